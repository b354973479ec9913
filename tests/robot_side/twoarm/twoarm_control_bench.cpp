// Per-tick compute of both arm controllers of the two-arm robot
// (twoarm_control: forward kinematics, avoidance, impedance, grippers, wrist
// wrenches), on the SIMULATED workbench with the arms moving: Google
// Benchmark's time per tick, and the median / p99 / max of single ticks
// (the station's control thread calls it once per 1 ms period). Machine
// load matters: state the condition with the numbers.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/realtime/timing_stats.h"
#include "robot_side/twoarm/twoarm_control.h"
#include "robot_side/twoarm/workbench_sim.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace ht = hemm::twoarm;

namespace {

using hemm::test::kWorkbenchScene;
void BM_TwoArmControlTick(benchmark::State& state) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  ht::TwoArmParams p;
  std::array<ht::ArmReading, ht::kArms> in{sim.reading(ht::Side::kRight), sim.reading(ht::Side::kLeft)};
  const ht::TwoArmTargets hold = ht::hold_targets(sim.model(), in, {10.0, 10.0});
  ht::TwoArmTargets t = hold;
  ht::TwoArmOutput out;
  hemm::rt::LogHistogram h;
  int64_t k = 0;
  for (auto _ : state) {
    // Circles of 5 cm radius for both grasp frames (the arms move, the
    // avoidance and limits see changing postures).
    const double s = 2.0 * std::numbers::pi * static_cast<double>(k) / 2000.0;
    t.T_A_G[0].translation() = hold.T_A_G[0].translation() + 0.05 * Eigen::Vector3d(std::cos(s) - 1.0, std::sin(s), 0.0);
    t.T_A_G[1].translation() = hold.T_A_G[1].translation() + 0.05 * Eigen::Vector3d(0.0, std::sin(s), 1.0 - std::cos(s));
    in = {sim.reading(ht::Side::kRight), sim.reading(ht::Side::kLeft)};
    const auto t0 = std::chrono::steady_clock::now();
    ht::twoarm_control(sim.model(), p, in, t, out);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(out);
    h.record(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
    state.PauseTiming();
    sim.set_command(ht::Side::kRight, out.command[0]);
    sim.set_command(ht::Side::kLeft, out.command[1]);
    sim.step();
    ++k;
    state.ResumeTiming();
  }
  state.counters["median_us"] = h.quantile_ns(0.5) / 1e3;
  state.counters["p99_us"] = h.quantile_ns(0.99) / 1e3;
  state.counters["max_us"] = static_cast<double>(h.max_ns()) / 1e3;
}
BENCHMARK(BM_TwoArmControlTick)->Iterations(20000)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
