// Issue 9 item 8 with the real binaries on loopback: hemm-robot is killed
// (SIGKILL) while the closed-loop SIMULATED operator drives a two-goal route
// (via A = (1.2, 0) to B = (1.0, -0.7)) and is restarted 2 s later: a new
// SIMULATED robot at the start pose, a new odometry frame. Before the fix the
// operator kept its task: its predicted pose ran on while the robot was dead,
// its route marked A as passed, and it drove the new robot straight at B.
// Now: while the model is stale the route does not advance and the robot is
// held; the restarted robot is recognised (its frame epoch), the model and
// the route are resynchronised from its state, and it drives via A to B,
// touching nothing.
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";
constexpr double kAx = 1.2, kAy = 0.0, kBx = 1.0, kBy = -0.7;

// The true x of the robot in the newest complete row of the world log (NaN: none yet).
double newest_truth_x(const std::string& path) {
  const std::string text = read_file(path);
  const auto end = text.rfind('\n');
  if (end == std::string::npos || end == 0) return NAN;
  const auto start = text.rfind('\n', end - 1);
  if (start == std::string::npos) return NAN;
  const std::string line = text.substr(start + 1, end - start - 1);
  // truth_x is column 26 (station_log_header in operator/station/operator_task.cpp).
  std::size_t pos = 0;
  for (int i = 0; i < 25 && pos != std::string::npos; ++i) pos = line.find(',', pos + 1);
  return pos == std::string::npos ? NAN : std::strtod(line.c_str() + pos + 1, nullptr);
}

std::unique_ptr<ChildProcess> start_robot(const std::string& dir, const std::string& name, int tcp, int udp) {
  auto p = std::make_unique<ChildProcess>(
      std::vector<std::string>{kBin + "hemm-robot", "--config", kConfigs + "robot.pbtxt", "--listen", "127.0.0.1",
                               "--session-port", std::to_string(tcp), "--stream-port", std::to_string(udp),
                               "--duration", "60", "--stats-json", dir + "/" + name + ".json"},
      dir + "/" + name + ".out", dir + "/" + name + ".err");
  EXPECT_TRUE(wait_for_text(dir + "/" + name + ".err", "event=listening", 15s)) << read_file(dir + "/" + name + ".err");
  return p;
}

TEST(RobotRestart, DuringNavToGoalTheOperatorResynchronisesPoseAndRouteFromTheNewRobot) {
  const std::string dir = make_temp_dir();
  const int tcp = free_port(), udp = free_port();
  auto robot = start_robot(dir, "robot1", tcp, udp);
  ChildProcess op({kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot", "127.0.0.1",
                   "--session-port", std::to_string(tcp), "--duration", "40", "--script", "nav-to-goal", "--goal",
                   "1.2,0", "--goal", "1.0,-0.7", "--log", dir + "/op.csv", "--station-json", dir + "/station.json"},
                  dir + "/op.out", dir + "/op.err");
  auto logs = [&] {
    return "--- robot1\n" + read_file(dir + "/robot1.err") + "--- robot2\n" + read_file(dir + "/robot2.err") +
           "--- operator\n" + read_file(dir + "/op.err") + read_file(dir + "/op.out");
  };
  // Killed on the way to A, close enough that the pose the operator
  // predicts while it is dead runs past A.
  const std::string world = dir + "/op.csv.world.csv";
  bool there = false;
  for (int i = 0; i < 400 && !there; ++i) {
    there = newest_truth_x(world) >= 0.7;
    if (!there) std::this_thread::sleep_for(50ms);
  }
  ASSERT_TRUE(there) << logs();
  robot->signal(SIGKILL);
  robot->wait(5s);
  std::this_thread::sleep_for(2s);
  robot = start_robot(dir, "robot2", tcp, udp);
  const auto rc = op.wait(70s);
  robot->signal(SIGTERM);
  robot->wait(20s);
  ASSERT_TRUE(rc.has_value()) << logs();
  ASSERT_EQ(*rc, 0) << logs();

  const CsvColumns w = read_csv_columns(world);
  ASSERT_TRUE(w.ok) << w.error;
  const auto &tx = w["truth_x"], &ty = w["truth_y"], &has = w["has_truth"], &rx = w["robot_x"], &ry = w["robot_y"];
  const auto &v = w["v"], &t = w["t_ns"];
  // The restart: the first row with the new robot's truth, back at the start.
  std::size_t restart = 0;
  double x_before = 0.0, predicted_at_kill = 0.0;
  for (std::size_t i = 1; i < w.rows && restart == 0; ++i) {
    if (has[i] && tx[i] < 0.2 && x_before > 0.6) restart = i;
    if (has[i]) x_before = tx[i];
    predicted_at_kill = std::max(predicted_at_kill, rx[i]);
  }
  ASSERT_GT(restart, 0u) << "no restart seen in the world log";
  // After the restart: the new robot drove via A (within the pass radius
  // and a margin) to B, the predicted pose agreeing with the truth.
  double min_to_a = 1e9, max_pose_err = 0.0;
  for (std::size_t i = restart; i < w.rows; ++i) {
    min_to_a = std::min(min_to_a, std::hypot(tx[i] - kAx, ty[i] - kAy));
    if (t[i] - t[restart] > 1.5e9) max_pose_err = std::max(max_pose_err, std::hypot(rx[i] - tx[i], ry[i] - ty[i]));
  }
  const double final_to_b = std::hypot(tx[w.rows - 1] - kBx, ty[w.rows - 1] - kBy);
  // Held: once the model had gone stale (the old robot's last state, plus
  // the one-way delay and fresh_s, plus the fade) no command moved the robot
  // until the new robot's data had taken over (the first row with its truth).
  const auto& stamp = w["state_stamp_ns"];
  std::size_t last_old = 0;  // the row where the old robot's newest state first appeared
  for (std::size_t i = 1; i < restart; ++i)
    if (stamp[i] != stamp[i - 1]) last_old = i;
  double v_held = 0.0;
  for (std::size_t i = last_old; i < restart; ++i)
    if (t[i] - t[last_old] > 1.5e9) v_held = std::max(v_held, std::abs(v[i]));
  const double held_s = (t[restart] - t[last_old]) * 1e-9 - 1.5;
  const std::string station = read_file(dir + "/station.json"), robot2 = read_file(dir + "/robot2.json");
  std::printf("[ restart ] predicted x at most %.2f before the restart; held %.2f s with |v| at most %.3f m/s; "
              "new robot taken in %.2f s after its predecessor's last state, run ended %.2f s after that; after it: "
              "closest to A %.3f m, final to B %.3f m, |predicted - true| max %.3f m; robot2 guard states %.0f, "
              "contact steps %.0f\n",
              predicted_at_kill, held_s, v_held, (t[restart] - t[last_old]) * 1e-9, (t[w.rows - 1] - t[restart]) * 1e-9,
              min_to_a, final_to_b, max_pose_err,
              json_number(robot2, "guard_states").value_or(-1), json_number(robot2, "contact_steps").value_or(-1));
  EXPECT_LT(min_to_a, 0.40) << "the route was not restarted: the new robot did not go via A";
  EXPECT_LT(final_to_b, 0.25);
  EXPECT_EQ(json_number(station, "arrived").value_or(0), 1) << station;
  EXPECT_LT(max_pose_err, 0.15);
  EXPECT_GT(held_s, 1.0);  // the 2 s the robot was down, less the fade: not vacuous
  EXPECT_EQ(v_held, 0.0);
  EXPECT_EQ(json_number(station, "resyncs").value_or(0), 1) << station;
  EXPECT_EQ(json_number(robot2, "contact_steps").value_or(-1), 0);
  EXPECT_EQ(json_number(robot2, "guard_states").value_or(-1), 0);
}

}  // namespace
}  // namespace hemm::test
