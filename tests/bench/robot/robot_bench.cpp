// Robot station speed: MuJoCo steps at 1 kHz with the controllers, with and
// without the laser (181 beams, 30 Hz) and sonar ring (16 x 5 rays, 10 Hz);
// the cost of one scan; FK/IK; and how well a paced loop holds 1 kHz here.
// Prints steps/s and the real-time factor (simulated s per wall-clock s).
#include <benchmark/benchmark.h>

#include <string>

#include "config_robot.pb.h"
#include "robot_side/sim/realtime.h"
#include "robot_side/sim/simulated_robot.h"

namespace hr = hemm::robot;
namespace hk = hemm::kinematics;

namespace {
const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

// The robot driving a slow circle in the living room under operator control.
void prepare(hr::SimulatedRobot& r, bool laser, bool sonar) {
  if (auto e = r.load(hemm::config::RobotConfig(), kScene)) {
    std::fprintf(stderr, "%s\n", e->c_str());
    std::abort();
  }
  r.set_base_pose_sim({0.5, -0.3, 0.0});
  r.enable_sensors(laser, sonar);
  r.set_operator_in_control(true);
  r.set_command(hr::BaseArmCommand{}, r.time_ns());  // neutral: the robot re-arms on the next command
}

void command(hr::SimulatedRobot& r) {
  hr::BaseArmCommand c;
  c.mode = hemm::wire::MODE_NAVIGATION;
  c.v = 0.2;
  c.omega = 0.4;
  c.deadman = true;
  r.set_command(c, r.time_ns());
}

void BM_SimStep(benchmark::State& state) {
  const bool sensors = state.range(0) != 0;
  hr::SimulatedRobot r;
  prepare(r, sensors, sensors);
  int64_t n = 0;
  for (auto _ : state) {
    if (n % 10 == 0) command(r);
    r.step(1);
    if (n % 100 == 0) benchmark::DoNotOptimize(r.take_scans());
    ++n;
  }
  const double dt = r.timestep_ns() * 1e-9;
  state.counters["steps_per_s"] = benchmark::Counter(static_cast<double>(n), benchmark::Counter::kIsRate);
  state.counters["real_time_factor"] = benchmark::Counter(static_cast<double>(n) * dt, benchmark::Counter::kIsRate);
  state.SetLabel(sensors ? "laser+sonar on" : "sensors off");
}
BENCHMARK(BM_SimStep)->Arg(0)->Arg(1)->MinTime(2.0)->UseRealTime();

void BM_Scan(benchmark::State& state) {
  hr::SimulatedRobot r;
  prepare(r, false, false);
  const hr::SimLaserParams lp = r.laser_params();
  const hr::SimSonarParams sp = r.sonar_params();
  // Cost of one scan = (step with that sensor due) - (plain step): measured
  // directly by stepping with only that sensor on at 1 kHz.
  hemm::config::RobotConfig cfg;
  if (state.range(0) == 0) {
    cfg.mutable_laser()->set_rate_hz(1000);
    cfg.mutable_sonar()->set_enabled(false);
  } else {
    cfg.mutable_sonar()->set_rate_hz(1000);
    cfg.mutable_laser()->set_enabled(false);
  }
  hr::SimulatedRobot s;
  if (s.load(cfg, kScene)) std::abort();
  for (auto _ : state) {
    s.step(1);
    benchmark::DoNotOptimize(s.take_scans());
  }
  state.SetLabel(state.range(0) == 0 ? "step + one laser scan (" + std::to_string(lp.beams) + " rays)"
                                     : "step + one sonar scan (" + std::to_string(sp.count * sp.rays_per_cone) +
                                           " rays)");
}
BENCHMARK(BM_Scan)->Arg(0)->Arg(1)->UseRealTime();

void BM_ForwardKinematics(benchmark::State& state) {
  const hk::Arm5Model m;
  hk::Arm5Vector q = (hk::Arm5Vector() << 0.1, 0.5, -1.0, 0.2, 0.3).finished();
  for (auto _ : state) {
    q(0) += 1e-9;
    benchmark::DoNotOptimize(hk::forward_kinematics(m, q));
  }
}
BENCHMARK(BM_ForwardKinematics);

void BM_InverseKinematics(benchmark::State& state) {
  const hk::Arm5Model m;
  const hk::Arm5Vector q = (hk::Arm5Vector() << 0.1, 0.5, -1.0, 0.2, 0.3).finished();
  const Eigen::Isometry3d T = hk::forward_kinematics(m, q);
  const hk::Arm5Target t{T.translation(), hk::tool_pitch(T), q(3)};
  for (auto _ : state) benchmark::DoNotOptimize(hk::inverse_kinematics(m, t, hk::Arm5Vector::Zero()));
}
BENCHMARK(BM_InverseKinematics);

// One paced second at 1 kHz with sensors: lateness of step starts.
void BM_RealtimePacing(benchmark::State& state) {
  hr::SimulatedRobot r;
  prepare(r, true, true);
  hr::PacingStats st;
  for (auto _ : state) st = hr::step_realtime(r, 1000);
  state.counters["max_lateness_us"] = static_cast<double>(st.max_lateness_ns) * 1e-3;
  state.counters["late_steps"] = st.late_steps;
}
BENCHMARK(BM_RealtimePacing)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
