// The SIMULATED bimanual interface's speed: both arms' controllers per servo
// tick (median and p99 over recorded states of a run in which the hands
// push the arms towards each other and the table, so collision avoidance is
// busy), the MuJoCo plant's real-time factor (simulated s per wall-clock s),
// a whole servo period (controllers + plant), and hemm-operator's servo tick
// with this device (read, environment task, write).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <memory>
#include <vector>

#include "operator/bimanual/bimanual_scripts.h"
#include "operator/bimanual/bimanual_task.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/device/bimanual/simulation.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

namespace {

// Hands crossing towards each other and down towards the table.
std::array<hb::HumanTarget, 2> scripted(const std::array<hb::HumanTarget, 2>& h0, double t) {
  auto h = h0;
  const double s = std::min(t / 2.0, 1.0);
  h[0].position_D += Eigen::Vector3d(0.0, 0.35 * s, -0.25 * s);
  h[1].position_D += Eigen::Vector3d(0.0, -0.35 * s, -0.25 * s);
  return h;
}

// Controller inputs recorded along a 3 s run.
std::vector<std::array<hb::ArmInput, 2>> record_inputs(hb::BimanualSimulation& s) {
  std::vector<std::array<hb::ArmInput, 2>> out;
  const auto h0 = s.resting_targets();
  for (int k = 0; k < 3000; ++k) {
    s.step(scripted(h0, s.time_s()));
    std::array<hb::ArmInput, 2> in;
    for (int a = 0; a < 2; ++a) {
      const hb::ArmReading& r = s.reading(static_cast<hb::ArmSide>(a));
      in[static_cast<size_t>(a)].q = r.q;
      in[static_cast<size_t>(a)].qd = r.qd;
      in[static_cast<size_t>(a)].ft_J7 = r.ft_J7;
    }
    out.push_back(in);
  }
  return out;
}

// Median, p99 and max of the per-call times; with period_s, also the
// real-time factor at the median (a shared machine's stalls inflate the mean).
void report_quantiles(benchmark::State& state, std::vector<double>& us, double period_s = 0.0) {
  if (us.empty()) return;
  std::sort(us.begin(), us.end());
  state.counters["median_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[us.size() * 99 / 100];
  state.counters["max_us"] = us.back();
  if (period_s > 0.0) state.counters["rtf_at_median"] = period_s * 1e6 / us[us.size() / 2];
}

void BM_ControllersPerTick(benchmark::State& state) {
  hb::SimulationConfig c;
  hb::BimanualSimulation sim(c);
  const auto inputs = record_inputs(sim);
  hb::BimanualController ctl(c.plant.rig, c.plant.handles, c.control, c.plant.control_period_s);
  std::array<hb::ArmOutput, 2> out;
  std::vector<double> us;
  us.reserve(1 << 20);
  std::size_t i = 0, active = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    ctl.update(inputs[i], out);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(out);
    if (us.size() < us.capacity()) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    active += ctl.collisions().count > 0;
    i = (i + 1) % inputs.size();
  }
  report_quantiles(state, us);
  state.counters["ticks_with_repulsion_pct"] = 100.0 * static_cast<double>(active) / static_cast<double>(state.iterations());
  state.SetLabel("both arms: FK, Jacobians, RNEA, CRBA, projector, feed-forward, 64+32 collision pairs");
}
BENCHMARK(BM_ControllersPerTick)->MinTime(2.0)->UseRealTime();

void BM_PlantStep(benchmark::State& state) {
  hb::SimulationConfig c;
  hb::BimanualSimulation sim(c);
  for (int k = 0; k < 500; ++k) sim.step(sim.resting_targets());
  std::array<hb::ArmActuation, 2> act;
  act[0].tau = sim.output(hb::ArmSide::kRight).tau;
  act[1].tau = sim.output(hb::ArmSide::kLeft).tau;
  const auto h = sim.resting_targets();
  std::vector<double> us;
  us.reserve(1 << 20);
  std::int64_t n = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    sim.plant().step(act, h);
    const auto t1 = std::chrono::steady_clock::now();
    if (us.size() < us.capacity()) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    ++n;
  }
  report_quantiles(state, us, c.plant.control_period_s);
  state.counters["real_time_factor"] =
      benchmark::Counter(static_cast<double>(n) * c.plant.control_period_s, benchmark::Counter::kIsRate);
  state.SetLabel("MuJoCo 2.2.2, 2 substeps of 0.5 ms per 1 ms period");
}
BENCHMARK(BM_PlantStep)->MinTime(2.0)->UseRealTime();

void BM_ServoPeriod(benchmark::State& state) {
  hb::SimulationConfig c;
  hb::BimanualSimulation sim(c);
  const auto h0 = sim.resting_targets();
  std::vector<double> us;
  us.reserve(1 << 20);
  std::int64_t n = 0;
  for (auto _ : state) {
    if (sim.time_s() > 3.0) {
      state.PauseTiming();
      sim.plant().reset({c.plant.rig.home(hb::ArmSide::kRight), c.plant.rig.home(hb::ArmSide::kLeft)});
      state.ResumeTiming();
    }
    const auto h = scripted(h0, std::fmod(sim.time_s(), 3.0));
    const auto t0 = std::chrono::steady_clock::now();
    sim.step(h);
    const auto t1 = std::chrono::steady_clock::now();
    if (us.size() < us.capacity()) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    ++n;
  }
  report_quantiles(state, us, c.plant.control_period_s);
  state.counters["real_time_factor"] =
      benchmark::Counter(static_cast<double>(n) * c.plant.control_period_s, benchmark::Counter::kIsRate);
  state.SetLabel("controllers + plant, hands pushing towards each other and the table");
}
BENCHMARK(BM_ServoPeriod)->MinTime(2.0)->UseRealTime();

// hemm-operator's whole servo tick with this device: read() both
// end-effectors, the station's environment task, write() (device-layer
// checks, both controllers, the plant), along the "features" hand script.
void BM_StationTick(benchmark::State& state) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kJoystick};
  const auto hands = hemm::op::make_bimanual_hands("features", c);
  auto device = std::make_unique<hb::SimulatedBimanualDevice>(c, hands.hands);
  hemm::op::HandEnvironment env;
  env.grip_object = true;
  hemm::op::BimanualTask task({env, env});
  const hemm::servo::ModelSnapshot model;
  hemm::device::DeviceSample s;
  std::vector<double> us;
  us.reserve(1 << 20);
  for (auto _ : state) {
    if (device->simulation().time_s() > hands.duration_s) {
      state.PauseTiming();
      device = std::make_unique<hb::SimulatedBimanualDevice>(c, hands.hands);
      state.ResumeTiming();
    }
    const auto t0 = std::chrono::steady_clock::now();
    device->read(s);
    hemm::servo::TickOutput out;
    task.tick(s, model, out);
    device->write(out.command);
    const auto t1 = std::chrono::steady_clock::now();
    if (us.size() < us.capacity()) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  report_quantiles(state, us, c.plant.control_period_s);
  state.SetLabel("read + environment task + write (controllers + plant), features script");
}
BENCHMARK(BM_StationTick)->MinTime(2.0)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
