// The stations through the impairment relay (hemm-relay, built by the relay
// component): delay/jitter/loss and an outage. Skipped with a clear message
// when the relay binary is not in this build.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <thread>

#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";

bool relay_built() {
  struct stat st {};
  return ::stat((kBin + "hemm-relay").c_str(), &st) == 0 && (st.st_mode & S_IXUSR);
}

double num(const std::string& json, const std::string& key) {
  auto v = json_number(json, key);
  EXPECT_TRUE(v.has_value()) << "missing " << key << " in " << json;
  return v.value_or(-1);
}

struct RelayRig {
  std::string dir;
  int robot_tcp = free_port(), robot_udp = free_port(), relay_tcp = free_port(), relay_udp = free_port();
  std::unique_ptr<ChildProcess> robot, relay, op;

  void start(const std::vector<std::string>& impairments, double relay_s, double robot_s, double op_s) {
    dir = make_temp_dir();
    robot = std::make_unique<ChildProcess>(
        std::vector<std::string>{kBin + "hemm-robot", "--config", kConfigs + "robot.pbtxt", "--listen", "127.0.0.1",
                                 "--session-port", std::to_string(robot_tcp), "--stream-port",
                                 std::to_string(robot_udp), "--duration", std::to_string(robot_s), "--stats-json",
                                 dir + "/robot.json"},
        dir + "/robot.out", dir + "/robot.err");
    ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 10s)) << read_file(dir + "/robot.err");
    std::vector<std::string> rargv = {kBin + "hemm-relay",
                                      "--tcp-listen", "127.0.0.1:" + std::to_string(relay_tcp),
                                      "--tcp-forward", "127.0.0.1:" + std::to_string(robot_tcp),
                                      "--udp-listen", "127.0.0.1:" + std::to_string(relay_udp),
                                      "--udp-forward", "127.0.0.1:" + std::to_string(robot_udp),
                                      "--seed", "7",
                                      "--duration", std::to_string(relay_s),
                                      "--stats-json", dir + "/relay.json"};
    rargv.insert(rargv.end(), impairments.begin(), impairments.end());
    relay = std::make_unique<ChildProcess>(rargv, dir + "/relay.out", dir + "/relay.err");
    ASSERT_TRUE(wait_for_text(dir + "/relay.out", "hemm-relay ready", 10s)) << logs();
    op = std::make_unique<ChildProcess>(
        std::vector<std::string>{kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot",
                                 "127.0.0.1", "--session-port", std::to_string(relay_tcp), "--stream-port",
                                 std::to_string(relay_udp), "--duration", std::to_string(op_s), "--stats-json",
                                 dir + "/op.json"},
        dir + "/op.out", dir + "/op.err");
  }
  // The operator exits 0 by itself; then the robot and the relay are stopped.
  void finish() {
    const auto rc = op->wait(60s);
    ASSERT_TRUE(rc.has_value()) << logs();
    EXPECT_EQ(*rc, 0) << logs();
    robot->signal(SIGTERM);
    relay->signal(SIGTERM);
    ASSERT_TRUE(robot->wait(20s).has_value());
    relay->wait(20s);
  }
  std::string logs() const {
    return "--- robot\n" + read_file(dir + "/robot.err") + "--- relay\n" + read_file(dir + "/relay.err") +
           "--- operator\n" + read_file(dir + "/op.err");
  }
};

TEST(LinkRelayTest, SessionHoldsAndRttIsMeasuredAt200msDelay20msJitter10PercentLoss) {
  if (!relay_built()) GTEST_SKIP() << "hemm-relay is not built in " << kBin << " (add component 'relay')";
  RelayRig s;
  // --jitter-reorder: each datagram gets exactly 200 ms + N(0, 20 ms). Without
  // it the relay keeps FIFO order, so a datagram drawn early waits behind a
  // late one and the injected delay is no longer the configured one (it
  // biases the median RTT up by ~10 % at these rates).
  s.start({"--delay-ms", "200", "--jitter-ms", "20", "--jitter-dist", "normal", "--jitter-reorder", "--loss", "0.1"},
          40, 40, 20);
  ASSERT_NO_FATAL_FAILURE(s.finish());
  const std::string oj = read_file(s.dir + "/op.json");
  const std::string rj = read_file(s.dir + "/robot.json");
  // The session held: opened once, never lost.
  EXPECT_EQ(num(oj, "sessions_opened"), 1) << s.logs();
  EXPECT_EQ(num(rj, "sessions_opened"), 1) << s.logs();
  EXPECT_EQ(num(oj, "link_lost_events"), 0) << s.logs();
  EXPECT_EQ(num(rj, "link_lost_events"), 0) << s.logs();
  // RTT: two 200 ms one-way delays; median over the estimator window within 10 %.
  for (const std::string* j : {&oj, &rj}) {
    const double rtt = num(*j, "rtt_median_ms");
    std::printf("[ measured ] %s: rtt_median_ms=%.1f rtt_min_ms=%.1f clock_offset_ms=%.3f samples=%.0f\n",
                j == &oj ? "operator" : "robot", rtt, num(*j, "rtt_min_ms"), num(*j, "clock_offset_ms"),
                num(*j, "clock_samples"));
    EXPECT_NEAR(rtt, 400.0, 40.0) << *j;
    EXPECT_GT(num(*j, "clock_samples"), 100);
    // Same host clock: the offset estimate stays near zero (unbounded normal
    // jitter and a loaded machine make the per-direction minima noisy).
    EXPECT_LT(std::abs(num(*j, "clock_offset_ms")), 25.0) << *j;
  }
  // About 10 % of the datagrams were lost on the way in each direction.
  // "received" counts every authenticated arrival, also the ones that came
  // after a newer one of their kind (late, dropped by newest-wins), which
  // jitter-induced reordering makes common.
  const double lost = num(rj, "lost"), got = num(rj, "received");
  std::printf("[ measured ] robot: lost=%.0f received=%.0f (%.1f %%) late=%.0f reordered=%.0f\n", lost, got,
              100.0 * lost / (lost + got), num(rj, "late"), num(rj, "reordered"));
  EXPECT_GT(lost / (lost + got), 0.06);
  EXPECT_LT(lost / (lost + got), 0.14);
}

TEST(LinkRelayTest, OutageIsReportedAsLinkLostAndTheSessionRecoversWithoutRestart) {
  if (!relay_built()) GTEST_SKIP() << "hemm-relay is not built in " << kBin << " (add component 'relay')";
  RelayRig s;
  // Outage from t = 4 s for 3 s (relay clock); the operator runs 12 s.
  s.start({"--delay-ms", "20", "--jitter-ms", "2", "--loss", "0", "--outage", "4:3"}, 30, 30, 12);
  EXPECT_TRUE(wait_for_text(s.dir + "/robot.err", "event=link_lost", 15s)) << s.logs();
  EXPECT_TRUE(wait_for_text(s.dir + "/robot.err", "event=link_restored", 15s)) << s.logs();
  ASSERT_NO_FATAL_FAILURE(s.finish());
  const std::string oj = read_file(s.dir + "/op.json");
  const std::string rj = read_file(s.dir + "/robot.json");
  EXPECT_GE(num(rj, "link_lost_events"), 1) << s.logs();
  EXPECT_GE(num(rj, "link_restored_events"), 1) << s.logs();
  // Neither process restarted and the TCP session survived: one session each.
  EXPECT_EQ(num(rj, "sessions_opened"), 1) << s.logs();
  EXPECT_EQ(num(oj, "sessions_opened"), 1) << s.logs();
  // Heartbeats flowed again after the outage.
  EXPECT_GE(num(oj, "link_restored_events"), 1) << s.logs();
  EXPECT_NE(read_file(s.dir + "/robot.err").find("event=peer_bye"), std::string::npos) << s.logs();
}

// 2 s round trip (1 s each way) and 5 % datagram loss each way, with the
// shipped configs unchanged: the session opens (each handshake step waits
// handshake_timeout_ms = 3 s for a reply that takes 2 s), the robot validates
// the operator's path, and both measure the round trip.
TEST(LinkRelayTest, SessionOpensAt2sRoundTripAnd5PercentLossWithTheDefaultConfigs) {
  if (!relay_built()) GTEST_SKIP() << "hemm-relay is not built in " << kBin << " (add component 'relay')";
  RelayRig s;
  s.start({"--delay-ms", "1000", "--loss", "0.05"}, 40, 40, 14);
  ASSERT_NO_FATAL_FAILURE(s.finish());
  const std::string oj = read_file(s.dir + "/op.json");
  const std::string rj = read_file(s.dir + "/robot.json");
  EXPECT_EQ(num(oj, "sessions_opened"), 1) << s.logs();
  EXPECT_EQ(num(rj, "sessions_opened"), 1) << s.logs();
  EXPECT_EQ(num(rj, "paths_validated"), 1) << s.logs();
  EXPECT_EQ(num(oj, "clock_valid"), 1) << s.logs();
  std::printf("[ measured ] 2 s rtt: operator rtt_median_ms=%.1f delivered=%.0f; robot rtt_median_ms=%.1f "
              "delivered=%.0f path_challenges_sent=%.0f\n",
              num(oj, "rtt_median_ms"), num(oj, "delivered"), num(rj, "rtt_median_ms"), num(rj, "delivered"),
              num(rj, "path_challenges_sent"));
  EXPECT_NEAR(num(oj, "rtt_median_ms"), 2000.0, 150.0);
  EXPECT_GT(num(oj, "delivered"), 500);  // robot state and scans for several seconds
}

}  // namespace
}  // namespace hemm::test
