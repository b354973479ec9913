// The dead-man with both stations in one process over loopback sockets
// (issue 23 item 2): the SIMULATED robot station (MuJoCo, real time) and the
// real operator station (SIMULATED Omni with a scripted hand, servo loop,
// command sender). The hand drives with the stylus's dead-man pressed and
// then lets go of it, the stylus still pushed: the robot stops, and the
// time from the hand letting go (the servo log's tick where the device first
// reports it released) to the base, or the arm, at rest in MuJoCo is
// measured. Bound: the command sender's period, the loopback link, the
// base's deceleration at its acceleration limit from the speed it had
// (the arm: its hold), with a margin for this shared VM.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/clock/steady_clock.h"
#include "config_robot.pb.h"
#include "operator/client/operator_client.h"
#include "operator/device/hand_script.h"
#include "operator/station/operator_station.h"
#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"
#include "tests/operator/client/loopback_client.h"
#include "tests/robot_side/station/robot_side.h"

namespace hemm::test {
namespace {

const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

net::Key test_key() {
  net::Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(41 * i + 9);
  return k;
}

// The robot's true state, polled every 2 ms on the test thread.
struct Sample {
  int64_t stamp_ns;
  double v_truth;
  double qd_max;  // rad/s, the fastest arm joint
};

struct ReleaseRun {
  std::vector<Sample> robot;
  int64_t release_ns = -1;  // the servo tick where the device first reported the dead-man released
  double v_at_release = 0.0, qd_at_release = 0.0;
  int64_t rest_ns = -1;     // the first state after it from which the base (or the arm) stays at rest
  op::OperatorStationSummary summary;
};

// Runs the stations for `seconds` with `hand` in `mode`; at_rest(sample)
// says what counts as at rest.
ReleaseRun run_release(std::shared_ptr<const device::HandScript> hand, math::Mode mode, double seconds,
        bool (*at_rest)(const Sample&)) {
  ReleaseRun out;
  config::RobotConfig cfg;
  cfg.mutable_net()->set_state_rate_hz(250);
  RobotSide robot(cfg, test_key(), kScene);
  robot.start();
  asio::io_context io;
  op::OperatorClient client(io, loopback_client_options("deadman-test", robot.server->session_port(), test_key()));
  op::OperatorStationOptions so = loopback_station_options("unused.csv");
  so.log_path = make_temp_dir() + "/servo.csv";
  so.hand = std::move(hand);
  so.task.initial_mode = mode;
  // The arm's box of the shipped manipulation demos (tests/integration/
  // manip3d): ahead of the base and above the laser head, clear of the
  // robot's keep-out.
  so.task.arm_base_R = {0.08, 0.0, 0.36};
  so.task.arm_workspace_centre_R = {0.42, 0.0, 0.56};
  so.task.arm_reach = 0.44;
  op::OperatorStation station(io, client, so);
  std::string err;
  EXPECT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  station.start();
  std::thread net([&] { io.run(); });
  const int64_t end = steady_now_ns() + static_cast<int64_t>(seconds * 1e9);
  while (steady_now_ns() < end) {
    const robot::RobotStateSim s = robot.station->latest_state();
    if (out.robot.empty() || s.stamp_ns != out.robot.back().stamp_ns)
      out.robot.push_back({s.stamp_ns, s.v_truth, s.qd.cwiseAbs().maxCoeff()});
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  station.stop();
  asio::post(io, [&] { client.stop("test over"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  io.stop();
  net.join();
  out.summary = station.summary();

  const CsvColumns log = read_csv_columns(so.log_path);
  EXPECT_TRUE(log.ok) << log.error;
  if (!log.ok) return out;
  const auto& t = log["t_ns"];
  const auto& dm = log["deadman"];
  for (std::size_t i = 1; i < t.size(); ++i) {
    if (dm[i - 1] == 1.0 && dm[i] == 0.0) {
      out.release_ns = static_cast<int64_t>(t[i]);
      break;
    }
  }
  if (out.release_ns < 0) return out;
  for (const Sample& s : out.robot) {
    if (s.stamp_ns <= out.release_ns) {
      out.v_at_release = s.v_truth;
      out.qd_at_release = s.qd_max;
    }
  }
  // At rest from the first sample after the release from which every later one is at rest.
  for (std::size_t i = out.robot.size(); i-- > 0;) {
    if (out.robot[i].stamp_ns < out.release_ns || !at_rest(out.robot[i])) break;
    out.rest_ns = out.robot[i].stamp_ns;
  }
  return out;
}

// Navigation: the stylus 25 mm forward from 1 s (the robot drives), the
// dead-man pressed from 0.5 s to 4.5 s, the stylus still forward after.
TEST(DeadMan, LettingGoStopsTheBaseWithinTheSenderPeriodAndItsDeceleration) {
  const Eigen::Vector3d fwd_H = op::R_B_H().transpose() * Eigen::Vector3d(0.025, 0.0, 0.0);
  auto motion = std::make_shared<device::WaypointScript>(std::vector<device::Waypoint>{
      {0.0, Eigen::Vector3d::Zero(), 0}, {1.0, Eigen::Vector3d::Zero(), 0}, {1.5, fwd_H, 0}});
  auto hand = std::make_shared<device::DeadmanScript>(motion, std::vector<device::DeadmanPress>{{0.5, 4.5}});
  const ReleaseRun r = run_release(hand, math::Mode::kNavigation, 7.0, [](const Sample& s) { return std::abs(s.v_truth) < 0.01; });
  ASSERT_GT(r.release_ns, 0) << "the servo log shows no release";
  ASSERT_GT(r.rest_ns, 0) << "the base never came to rest after the release";
  const config::RobotConfig defaults;
  const double decel_s = std::abs(r.v_at_release) / defaults.base().max_accel_mps2();
  const double stop_s = static_cast<double>(r.rest_ns - r.release_ns) * 1e-9;
  const double sender_s = 1.0 / 200.0;
  std::printf("navigation: dead-man let go at %.2f m/s -> base at rest (|v| < 0.01 m/s, MuJoCo) after %.3f s "
              "(deceleration at %.1f m/s^2: %.3f s; sender period %.3f s)\n",
              r.v_at_release, stop_s, defaults.base().max_accel_mps2(), decel_s, sender_s);
  std::printf("%s", op::to_string(r.summary).c_str());
  EXPECT_GT(r.v_at_release, 0.15) << "the robot was not driving when the hand let go";
  EXPECT_LT(stop_s, sender_s + decel_s + 0.15);
  EXPECT_GT(stop_s, decel_s - 0.1);  // the deceleration, not something faster
  EXPECT_GT(r.summary.commands.deadman_pressed, 100u);
}

// Manipulation: the stylus sweeps left and right (the arm follows), the
// dead-man pressed from 0.5 s to 4.0 s (in the middle of a sweep) while the
// stylus keeps sweeping.
TEST(DeadMan, LettingGoStopsTheArm) {
  std::vector<device::Waypoint> w;
  w.push_back({0.0, Eigen::Vector3d::Zero(), 0});
  w.push_back({1.0, Eigen::Vector3d::Zero(), 0});
  for (int k = 0; k < 6; ++k) {
    const double side = k % 2 == 0 ? 0.02 : -0.02;
    w.push_back({1.8 + 0.8 * k, op::R_B_H().transpose() * Eigen::Vector3d(0.0, side, 0.0), 0});
  }
  auto motion = std::make_shared<device::WaypointScript>(w);
  auto hand = std::make_shared<device::DeadmanScript>(motion, std::vector<device::DeadmanPress>{{0.5, 4.0}});
  const ReleaseRun r = run_release(hand, math::Mode::kManipulation, 6.5, [](const Sample& s) { return s.qd_max < 0.02; });
  ASSERT_GT(r.release_ns, 0) << "the servo log shows no release";
  ASSERT_GT(r.rest_ns, 0) << "the arm never came to rest after the release";
  const double stop_s = static_cast<double>(r.rest_ns - r.release_ns) * 1e-9;
  std::printf("manipulation: dead-man let go with the fastest joint at %.2f rad/s -> arm at rest "
              "(every joint < 0.02 rad/s, MuJoCo) after %.3f s\n",
              r.qd_at_release, stop_s);
  std::printf("%s", op::to_string(r.summary).c_str());
  EXPECT_GT(r.qd_at_release, 0.1) << "the arm was not moving when the hand let go";
  EXPECT_LT(stop_s, 0.5);
  EXPECT_EQ(r.summary.arm_refusals.refused, 0u);
}

}  // namespace
}  // namespace hemm::test
