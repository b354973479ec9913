// Loopback latency injection (issue 4): the real hemm-robot (SIMULATED robot,
// MuJoCo, real time) and hemm-operator (SIMULATED Omni and hand) as child
// processes, the link through hemm-relay with a round trip of 0, 100, 300 and
// 1000 ms, uniform jitter of +-10 % of the one-way delay (at least 1 ms; each
// datagram delayed on its own) and 5 % loss in each direction.
//
// For every round trip a closed-loop SIMULATED operator (--script nav-to-goal)
// drives the robot to a goal just in front of a wall, watching the pose the
// station predicts. Checked: the servo loop computed a finite force on every
// tick it ran (the 1 kHz log has one row per tick), its median period is
// 1 ms within 5 %, deadline misses are counted and printed, the force stayed
// close to the exact scene's (RMS error), the robot reached the goal, and it
// never touched anything (MuJoCo contacts counted by the robot station). At 0 and 300 ms
// the operator also probes the bin in exploration mode. For every run
// hemm-truth (SIMULATION ONLY) replays the proxy path against the scene's
// exact geometry: the force error of the local model. One table at the end.
//
// Also HEMM Fig. 8 as a test: driving at a wall, the robot stops short of it
// while the scripted hand keeps pushing, and the force holds the hand back.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "common/haptics/proxy/passivity.h"
#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";
const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

// The rendered force against the force the same proxy gives on the exact
// scene (hemm-truth), RMS over all ticks: about 0.17 N in these runs (scan
// noise, occlusion); a wrong frame, a stale pose or a lost surface gives
// errors of the order of the forces themselves (0.5 to 3 N).
constexpr double kForceErrorRms = 0.3;  // N
// The nav-to-goal script's default goal (operator/station/demo_scripts.h).
constexpr double kGoalX = 2.45, kGoalY = -1.6;
// The SIMULATED operator steers by the pose the station predicts (odometry
// corrected by scan registration) and stops within 0.10 m of the goal by that
// pose; the route turns 90 deg on the way. Judged against the simulation's
// truth, the base must truly be within 0.10 m of the goal: odometry alone
// (skid steer slips) ended 0.10-0.14 m off.
constexpr double kGoalTolerance = 0.10;       // m, predicted base centre to goal (nav_goal_test)
constexpr double kTrueGoalTolerance = 0.10;   // m, true base centre to goal

bool built(const std::string& name) {
  struct stat st {};
  return ::stat((kBin + name).c_str(), &st) == 0 && (st.st_mode & S_IXUSR);
}

// The four binaries are build dependencies of this test (CMakeLists.txt):
// one missing is a broken build, a failure, not a reason to skip.
void expect_built() {
  for (const char* b : {"hemm-robot", "hemm-operator", "hemm-relay", "hemm-truth"})
    EXPECT_TRUE(built(b)) << b << " is not built in " << kBin;
}

// Until `text` shows in `file`, or the process is gone (never started, or
// exited): a station that does not come up is found at once, not after the
// whole timeout.
bool came_up(ChildProcess& p, const std::string& file, const std::string& text, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (wait_for_text(file, text, 100ms)) return true;
    if (!p.running()) return wait_for_text(file, text, 0ms);
  }
  return false;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

double num(const std::string& json, const std::string& key) {
  const auto v = json_number(json, key);
  EXPECT_TRUE(v.has_value()) << "missing \"" << key << "\" in " << json.substr(0, 400);
  return v.value_or(NAN);
}

// "key" inside the object that follows "section" (the station JSON nests:
// {"timing": {"compute_us": {"p99": ...}}}).
double num_in(const std::string& json, const std::string& section, const std::string& key) {
  const std::size_t at = json.find("\"" + section + "\"");
  EXPECT_NE(at, std::string::npos) << "missing \"" << section << "\"";
  return at == std::string::npos ? NAN : num(json.substr(at), key);
}

struct RunResult {
  std::string name;
  double rtt_target_ms = 0;
  bool ok = false;  // all processes ran and the files are there
  // link
  double rtt_measured_ms = NAN, loss_up = NAN;
  // servo loop (from the 1 kHz log and the station's summary)
  double ticks = 0, log_rows = 0, log_dropped = 0, period_median_ms = NAN, period_p99_ms = NAN;
  double wake_p99_us = NAN, compute_p99_us = NAN, misses = NAN;
  std::size_t nan_forces = 0;
  double max_force = 0;
  // passivity observer on the logged device force and position
  double energy_generated_mJ = NAN, worst_episode_mJ = NAN;
  // robot (truth, from the robot station and the world log)
  double contact_steps = NAN, guard_states = NAN;
  double final_x = NAN, final_y = NAN, final_goal_dist = NAN, time_to_goal_s = NAN;
  double arrived = NAN, predicted_goal_dist = NAN;
  // force error against the exact scene (hemm-truth)
  double err_rms = NAN, err_max = NAN, contact_rms = NAN, contact_max = NAN, contact_ticks = NAN;
  double mean_force = NAN, pose_err_max = NAN;
  std::string logs;
  std::string dir;  // the run's files (logs, JSON)
};

// One run: robot, relay, operator with a script; then hemm-truth on its log.
// Every way it can end without its numbers (a process that does not start
// or fails, a missing or short log) is a test failure here, and ok stays
// false. `robot_bin` is replaceable so that this can be tested.
RunResult run(const std::string& name, double rtt_ms, const std::string& script, double op_s,
              const std::string& robot_bin = kBin + "hemm-robot") {
  RunResult r;
  r.name = name;
  r.rtt_target_ms = rtt_ms;
  const std::string dir = make_temp_dir();
  r.dir = dir;
  const int robot_tcp = free_port(), robot_udp = free_port(), relay_tcp = free_port(), relay_udp = free_port();
  const double one_way = rtt_ms / 2.0;
  const double jitter = std::max(1.0, 0.1 * one_way);
  ChildProcess robot({robot_bin, "--config", kConfigs + "robot.pbtxt", "--listen", "127.0.0.1",
                      "--session-port", std::to_string(robot_tcp), "--stream-port", std::to_string(robot_udp),
                      "--duration", std::to_string(op_s + 20), "--stats-json", dir + "/robot.json"},
                     dir + "/robot.out", dir + "/robot.err");
  auto logs = [&] {
    return "--- robot\n" + read_file(dir + "/robot.err") + "--- relay\n" + read_file(dir + "/relay.err") +
           "--- operator\n" + read_file(dir + "/op.err") + read_file(dir + "/op.out") + "--- truth\n" +
           read_file(dir + "/truth.err");
  };
  if (!came_up(robot, dir + "/robot.err", "event=listening", 15s)) {
    r.logs = logs();
    ADD_FAILURE() << name << ": hemm-robot did not start (" << robot_bin << ")\n" << r.logs;
    return r;
  }
  ChildProcess relay({kBin + "hemm-relay", "--tcp-listen", "127.0.0.1:" + std::to_string(relay_tcp), "--tcp-forward",
                      "127.0.0.1:" + std::to_string(robot_tcp), "--udp-listen",
                      "127.0.0.1:" + std::to_string(relay_udp), "--udp-forward",
                      "127.0.0.1:" + std::to_string(robot_udp), "--seed", "11", "--duration",
                      std::to_string(op_s + 20), "--delay-ms", std::to_string(one_way), "--jitter-ms",
                      std::to_string(jitter), "--jitter-dist", "uniform", "--jitter-reorder", "--loss", "0.05",
                      "--stats-json", dir + "/relay.json"},
                     dir + "/relay.out", dir + "/relay.err");
  if (!came_up(relay, dir + "/relay.out", "hemm-relay ready", 15s)) {
    r.logs = logs();
    ADD_FAILURE() << name << ": hemm-relay did not start\n" << r.logs;
    return r;
  }
  ChildProcess op({kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot", "127.0.0.1",
                   "--session-port", std::to_string(relay_tcp), "--stream-port", std::to_string(relay_udp),
                   "--duration", std::to_string(op_s), "--script", script, "--log", dir + "/op.csv",
                   "--stats-json", dir + "/op.json", "--station-json", dir + "/station.json"},
                  dir + "/op.out", dir + "/op.err");
  const auto rc = op.wait(std::chrono::milliseconds(static_cast<int>((op_s + 40) * 1000)));
  robot.signal(SIGTERM);
  relay.signal(SIGTERM);
  robot.wait(20s);
  relay.wait(20s);
  r.logs = logs();
  if (!rc || *rc != 0) {
    ADD_FAILURE() << name << ": hemm-operator exit " << (rc ? std::to_string(*rc) : "timeout") << "\n" << r.logs;
    return r;
  }
  ChildProcess truth({kBin + "hemm-truth", "--scene", kScene, "--log", dir + "/op.csv.world.csv", "--json",
                      dir + "/truth.json"},
                     dir + "/truth.out", dir + "/truth.err");
  const auto trc = truth.wait(120s);
  if (!trc || *trc != 0) {
    ADD_FAILURE() << name << ": hemm-truth failed\n" << read_file(dir + "/truth.err");
    return r;
  }

  const std::string oj = read_file(dir + "/op.json"), sj = read_file(dir + "/station.json"),
                    rj = read_file(dir + "/robot.json"), tj = read_file(dir + "/truth.json");
  r.rtt_measured_ms = num(oj, "rtt_median_ms");
  r.ticks = num(sj, "ticks");
  r.misses = num(sj, "misses");
  r.log_dropped = num(sj, "servo_dropped");
  r.wake_p99_us = num_in(sj, "wake_latency_us", "p99");
  r.compute_p99_us = num_in(sj, "compute_us", "p99");
  if (script == "nav-to-goal") {
    r.arrived = num_in(sj, "nav_goal", "arrived");
    r.predicted_goal_dist = num_in(sj, "nav_goal", "goal_distance_m");
    r.time_to_goal_s = num_in(sj, "nav_goal", "first_arrival_s");
  }
  r.contact_steps = num(rj, "contact_steps");
  r.guard_states = num(rj, "guard_states");
  r.err_rms = num(tj, "rms_n");
  r.err_max = num(tj, "max_n");
  r.contact_rms = num(tj, "contact_rms_n");
  r.contact_max = num(tj, "contact_max_n");
  r.contact_ticks = num(tj, "contact_ticks");
  r.mean_force = num(tj, "mean_force_truth_n");
  r.pose_err_max = num(tj, "pose_error_max_m");

  const CsvColumns servo = read_csv_columns(dir + "/op.csv");
  const CsvColumns world = read_csv_columns(dir + "/op.csv.world.csv");
  if (!servo.ok || !world.ok || servo.rows < 100 || world.rows < 100) {
    ADD_FAILURE() << name << ": logs: " << servo.error << " " << world.error;
    return r;
  }
  r.log_rows = static_cast<double>(servo.rows);
  const auto& t = servo["t_ns"];
  std::vector<double> period;
  period.reserve(t.size());
  for (std::size_t i = 1; i < t.size(); ++i) period.push_back((t[i] - t[i - 1]) * 1e-6);
  r.period_median_ms = percentile(period, 0.5);
  r.period_p99_ms = percentile(period, 0.99);
  const auto &fx = servo["fx"], &fy = servo["fy"], &fz = servo["fz"];
  for (std::size_t i = 0; i < servo.rows; ++i) {
    const double f = std::sqrt(fx[i] * fx[i] + fy[i] * fy[i] + fz[i] * fz[i]);
    if (!std::isfinite(f)) {
      ++r.nan_forces;
    } else {
      r.max_force = std::max(r.max_force, f);
    }
  }
  {
    std::vector<Eigen::Vector3d> force, position;
    force.reserve(servo.rows);
    position.reserve(servo.rows);
    const auto &dx = servo["dev_x"], &dy = servo["dev_y"], &dz = servo["dev_z"];
    for (std::size_t i = 0; i < servo.rows; ++i) {
      force.emplace_back(fx[i], fy[i], fz[i]);
      position.emplace_back(dx[i], dy[i], dz[i]);
    }
    const haptics::PassivityReport pr = haptics::passivity_observer(force, position, 0.0);
    r.energy_generated_mJ = 1e3 * pr.generated;
    r.worst_episode_mJ = 1e3 * std::min(0.0, pr.worst_episode_energy);
  }
  const auto &tx = world["truth_x"], &ty = world["truth_y"], &has = world["has_truth"];
  for (std::size_t i = 0; i < world.rows; ++i) {
    if (has[i] == 0) continue;
    const double d = std::hypot(tx[i] - kGoalX, ty[i] - kGoalY);
    r.final_x = tx[i];
    r.final_y = ty[i];
    r.final_goal_dist = d;
  }
  r.ok = true;
  return r;
}

void print_table(const std::vector<RunResult>& runs) {
  std::printf(
      "\n[ latency ] round trip through hemm-relay (jitter +-10 %% of one-way, >= 1 ms; 5 %% loss each way)\n"
      "%-22s %7s %7s | %7s %6s %6s %6s %6s %6s | %6s %6s %6s | %6s %7s %6s %7s %5s | %7s %7s %7s %7s %6s\n",
      "run", "rtt", "rtt_meas", "ticks", "per50", "per99", "wake99", "comp99", "misses", "|F|max", "E_gen", "E_ep",
      "goal_p", "goal_t", "t_goal", "contact", "guard", "dF_rms", "dF_max", "cF_rms", "cF_max", "pose_e");
  std::printf(
      "%-22s %7s %7s | %7s %6s %6s %6s %6s %6s | %6s %6s %6s | %6s %7s %6s %7s %5s | %7s %7s %7s %7s %6s\n", "",
      "ms", "ms", "", "ms", "ms", "us", "us", "", "N", "mJ", "mJ", "m", "m", "s", "steps", "st", "N", "N", "N", "N",
      "m");
  // A number, or "-" where it does not apply (goal columns of a probe run).
  auto col = [](double v, int width, int prec) {
    char b[32];
    if (std::isnan(v)) {
      std::snprintf(b, sizeof b, "%*s", width, "-");
    } else {
      std::snprintf(b, sizeof b, "%*.*f", width, prec, v);
    }
    return std::string(b);
  };
  for (const RunResult& r : runs) {
    const bool nav = r.name == "nav-to-goal";
    std::printf(
        "%-22s %7.0f %7.1f | %7.0f %6.3f %6.3f %6.0f %6.0f %6.0f | %6.3f %6.3f %6.3f | %s %s %s %7.0f %5.0f | "
        "%7.3f %7.3f %7.3f %7.3f %6.3f\n",
        r.name.c_str(), r.rtt_target_ms, r.rtt_measured_ms, r.ticks, r.period_median_ms, r.period_p99_ms,
        r.wake_p99_us, r.compute_p99_us, r.misses, r.max_force, r.energy_generated_mJ, r.worst_episode_mJ,
        col(r.predicted_goal_dist, 6, 3).c_str(),
        col(nav ? r.final_goal_dist : NAN, 7, 3).c_str(), col(r.time_to_goal_s, 6, 1).c_str(), r.contact_steps,
        r.guard_states, r.err_rms, r.err_max, r.contact_rms, r.contact_max, r.pose_err_max);
  }
  std::printf(
      "per50/per99: servo period median/p99 from the 1 kHz log; misses: deadline misses (station summary);\n"
      "E_gen: energy the rendering gave the hand beyond what it took (passivity observer on the logged force and\n"
      "device position; E_ep: worst contact episode), millijoules;\n"
      "goal_p/goal_t: predicted / true base centre to goal at the end; t_goal: first arrival (script s);\n"
      "contact: sim steps with the robot touching the scene;\n"
      "guard: robot states with the robot's own collision guard limiting it; dF: |F_local_model - F_true_scene|\n"
      "over all ticks (cF: ticks in contact), from hemm-truth; pose_e: max |predicted - true| robot position.\n");
  std::fflush(stdout);
}

void check_servo(const RunResult& r) {
  SCOPED_TRACE(r.name);
  // A force on every tick: one log row per tick, none lost, all finite.
  EXPECT_EQ(r.log_dropped, 0);
  EXPECT_NEAR(r.log_rows, r.ticks, 1.0);
  EXPECT_EQ(r.nan_forces, 0u);
  EXPECT_NEAR(r.period_median_ms, 1.0, 0.05);
  // Misses are reported; a shared 2-core VM stalls, so the bound is wide.
  EXPECT_LT(r.misses, 0.05 * r.ticks);
  // The force follows the true scene. (Not |F| <= the device's peak: the
  // proxy clamps to that very bound, so such a check could never fail.)
  EXPECT_LT(r.err_rms, kForceErrorRms);
  // No unstable contact: an active rendering loop gives back joules. What is
  // measured here (tenths of a millijoule to a few) is scan noise and the
  // robot's own motion moving surfaces into the resting proxy.
  EXPECT_LT(r.energy_generated_mJ, 10.0);
}

TEST(LatencySuite, NavigationToAGoalAndProbingThroughTheRelayAt0To1000msRoundTrip) {
  expect_built();
  std::vector<RunResult> runs;
#ifdef HEMM_SANITIZE
  // Under the sanitizers the suite looks for memory errors, not latency
  // figures: the extremes of the round trip exercise every code path.
  const std::vector<double> nav_rtts{0.0, 1000.0}, probe_rtts{300.0};
#else
  const std::vector<double> nav_rtts{0.0, 100.0, 300.0, 1000.0}, probe_rtts{0.0, 300.0};
#endif
  for (double rtt : nav_rtts) {
    RunResult r = run("nav-to-goal", rtt, "nav-to-goal", 25.0);
    EXPECT_TRUE(r.ok) << "nav-to-goal at " << rtt << " ms did not run to the end";
    if (r.ok) {
      SCOPED_TRACE("nav-to-goal rtt " + std::to_string(rtt));
      check_servo(r);
      EXPECT_EQ(r.arrived, 1) << "did not reach the goal\n" << r.logs;
      EXPECT_LT(r.predicted_goal_dist, kGoalTolerance + 0.02);
      EXPECT_LT(r.final_goal_dist, kTrueGoalTolerance);
      EXPECT_EQ(r.contact_steps, 0) << "the robot touched the scene";
    }
    runs.push_back(std::move(r));
  }
  for (double rtt : probe_rtts) {
    RunResult r = run("probe-cylinder", rtt, "probe-cylinder", 18.0);
    EXPECT_TRUE(r.ok) << "probe-cylinder at " << rtt << " ms did not run to the end";
    if (r.ok) {
      SCOPED_TRACE("probe-cylinder rtt " + std::to_string(rtt));
      check_servo(r);
      EXPECT_GT(r.contact_ticks, 1000) << "the probe never touched the bin";
      EXPECT_EQ(r.contact_steps, 0);
    }
    runs.push_back(std::move(r));
  }
  print_table(runs);
}

// HEMM Fig. 8: navigation mode; the SIMULATED hand steers for a point behind
// the wall wall_mid_n (west face x = 2.95) and keeps pushing the stylus
// forward. The navigation point meets the wall, the proxy holds it, the
// command falls into the dead band: the robot stops short of the wall while
// the hand still pushes and the force holds it back.
TEST(LatencySuite, Figure8RobotStopsShortOfTheWallWhileTheHandKeepsPushing) {
  expect_built();
  const RunResult r = run("nav-to-wall", 0.0, "nav-to-wall", 14.0);
  ASSERT_TRUE(r.ok) << r.logs;
  check_servo(r);
  const CsvColumns servo = read_csv_columns(r.dir + "/op.csv");
  const CsvColumns world = read_csv_columns(r.dir + "/op.csv.world.csv");
  ASSERT_GT(world.rows, 10000u);
  // The chassis (0.50 x 0.49 m, robot.xml) against the wall's face, from the
  // true pose.
  auto gap_to_wall = [&](std::size_t i) {
    const double x = world["truth_x"][i], th = world["truth_theta"][i];
    double front = -1e9;
    for (double a : {0.25, -0.25})
      for (double b : {0.245, -0.245}) front = std::max(front, x + std::cos(th) * a - std::sin(th) * b);
    return 2.95 - front;
  };
  // The last 2 s of the run.
  const auto& t = world["t_ns"];
  std::size_t from = world.rows - 1;
  while (from > 0 && t.back() - t[from] < 2e9) --from;
  const auto &tx = world["truth_x"], &ty = world["truth_y"], &v = world["v"];
  double moved = 0.0, v_max = 0.0, gap_min = 1e9;
  std::vector<double> v_end;
  for (std::size_t i = 0; i < world.rows; ++i) gap_min = std::min(gap_min, gap_to_wall(i));
  for (std::size_t i = from; i < world.rows; ++i) {
    moved = std::max(moved, std::hypot(tx[i] - tx[from], ty[i] - ty[from]));
    v_max = std::max(v_max, std::abs(v[i]));
    v_end.push_back(std::abs(v[i]));
  }
  const double v_median = percentile(v_end, 0.5);
  const double gap = gap_to_wall(world.rows - 1);
  // The hand: stylus pressed forward (-z in H) past the dead band (8 mm),
  // the force pushing it back (+z).
  const auto &dz = servo["dev_z"], &fz = servo["fz"], &fx = servo["fx"], &fy = servo["fy"];
  const std::size_t last = servo.rows - 1;
  const double f = std::sqrt(fx[last] * fx[last] + fy[last] * fy[last] + fz[last] * fz[last]);
  std::printf("[ fig. 8 ] chassis stopped %.3f m from the wall (closest %.3f m), moved %.4f m in the last 2 s, "
              "command |v| median %.3f max %.3f m/s; stylus z = %.1f mm, force %.2f N (fz %.2f); contact steps %.0f, "
              "guard states %.0f\n",
              gap, gap_min, moved, v_median, v_max, 1e3 * dz[last], f, fz[last], r.contact_steps, r.guard_states);
  EXPECT_GT(gap_min, 0.0);   // short of the wall
  EXPECT_LT(gap, 0.45);      // but it did drive up to it
  EXPECT_LT(moved, 0.02);    // stopped
  // By the operator's command: in the dead band (a noisy scan of the wall
  // nudges the proxy, so the command flickers just past it now and then).
  EXPECT_LT(v_median, 0.005);
  EXPECT_LT(v_max, 0.06);
  EXPECT_LT(dz[last], -0.008);  // the hand still pushes forward
  EXPECT_GT(fz[last], 0.3);     // and the force holds it back
  EXPECT_EQ(r.contact_steps, 0);
}

// The suite's own harness: a robot station that never starts (a wrong
// binary path) fails the run at once instead of passing it whole.
RunResult g_missing;  // EXPECT_NONFATAL_FAILURE's statement cannot use locals
TEST(LatencySuite, AStationThatDoesNotStartFailsTheRun) {
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NONFATAL_FAILURE(g_missing = run("no-robot", 0.0, "nav-to-goal", 5.0, kBin + "hemm-robot-not-there"),
                          "hemm-robot did not start");
  EXPECT_FALSE(g_missing.ok);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 10s);  // found at once, not after the 15 s start timeout
}

}  // namespace
}  // namespace hemm::test
