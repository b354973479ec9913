// A session recorded on loopback through hemm-relay at 300 ms round trip
// (5 % loss, jitter with reordering), SIMULATED robot and Omni, the
// probe-cylinder script (exploration: the probe meets the bin, so forces are
// rendered), then replayed by hemm-operator --replay: every tick's force
// equal to the recorded one (the servo CSV's, written independently of the
// recording), at least 10 times faster than real time when asked for full
// speed; and a cut copy refused with the record and byte where it broke,
// its readable part replayed and matching.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";
constexpr double kRunS = 8.0;

TEST(SessionReplayLoopback, RecordedAt300msRoundTripReplaysTheSameForcesFast) {
  const std::string dir = make_temp_dir();
  const int robot_tcp = free_port(), robot_udp = free_port(), relay_tcp = free_port(), relay_udp = free_port();
  ChildProcess robot({kBin + "hemm-robot", "--config", kConfigs + "robot.pbtxt", "--listen", "127.0.0.1",
                      "--session-port", std::to_string(robot_tcp), "--stream-port", std::to_string(robot_udp),
                      "--duration", std::to_string(kRunS + 20)},
                     dir + "/robot.out", dir + "/robot.err");
  auto logs = [&] {
    return "--- robot\n" + read_file(dir + "/robot.err") + "--- relay\n" + read_file(dir + "/relay.err") +
           "--- operator\n" + read_file(dir + "/op.err") + read_file(dir + "/op.out");
  };
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 15s)) << logs();
  ChildProcess relay({kBin + "hemm-relay", "--tcp-listen", "127.0.0.1:" + std::to_string(relay_tcp), "--tcp-forward",
                      "127.0.0.1:" + std::to_string(robot_tcp), "--udp-listen",
                      "127.0.0.1:" + std::to_string(relay_udp), "--udp-forward",
                      "127.0.0.1:" + std::to_string(robot_udp), "--seed", "5", "--duration",
                      std::to_string(kRunS + 20), "--delay-ms", "150", "--jitter-ms", "15", "--jitter-dist",
                      "uniform", "--jitter-reorder", "--loss", "0.05"},
                     dir + "/relay.out", dir + "/relay.err");
  ASSERT_TRUE(wait_for_text(dir + "/relay.out", "hemm-relay ready", 15s)) << logs();
  const std::string rec = dir + "/session.rec";
  ChildProcess op({kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot", "127.0.0.1",
                   "--session-port", std::to_string(relay_tcp), "--stream-port", std::to_string(relay_udp),
                   "--duration", std::to_string(kRunS), "--script", "probe-cylinder", "--log", dir + "/op.csv",
                   "--record", rec},
                  dir + "/op.out", dir + "/op.err");
  const auto rc = op.wait(std::chrono::milliseconds(static_cast<int>((kRunS + 40) * 1000)));
  robot.signal(SIGTERM);
  relay.signal(SIGTERM);
  robot.wait(20s);
  relay.wait(20s);
  ASSERT_TRUE(rc && *rc == 0) << logs();

  // The recorded forces, from the servo log (the servo loop's own record of
  // what it commanded, not the recording).
  const CsvColumns servo = read_csv_columns(dir + "/op.csv");
  ASSERT_TRUE(servo.ok) << servo.error;
  const std::size_t logged = servo["t_ns"].size();
  std::size_t forced = 0;
  for (std::size_t i = 0; i < logged; ++i)
    forced += std::hypot(servo["fx"][i], servo["fy"][i], servo["fz"][i]) > 0.1;
  ASSERT_GT(logged, static_cast<std::size_t>(0.8 * kRunS * 1000));
  EXPECT_GT(forced, 300u) << "the probe must touch the bin for the comparison to mean anything";

  // Full speed.
  ChildProcess replay({kBin + "hemm-operator", "--replay", rec, "--replay-speed", "0", "--replay-json",
                       dir + "/replay.json"},
                      dir + "/replay.out", dir + "/replay.err");
  const auto rrc = replay.wait(60s);
  ASSERT_TRUE(rrc && *rrc == 0) << read_file(dir + "/replay.err") << read_file(dir + "/replay.out");
  const std::string j = read_file(dir + "/replay.json");
  std::printf("%s", read_file(dir + "/replay.out").c_str());
  const double ticks = json_number(j, "ticks").value_or(-1);
  EXPECT_EQ(ticks, static_cast<double>(logged));  // every tick the log has (none dropped)
  EXPECT_EQ(json_number(j, "ticks_missing").value_or(-1), 0);
  EXPECT_EQ(json_number(j, "force_mismatches").value_or(-1), 0);
  EXPECT_LE(json_number(j, "max_force_error_N").value_or(1), 1e-9);
  EXPECT_EQ(json_number(j, "mode_mismatches").value_or(-1), 0);
  const double recorded_s = json_number(j, "recorded_s").value_or(0), wall_s = json_number(j, "wall_s").value_or(1e9);
  EXPECT_GT(recorded_s, 0.8 * kRunS);
  std::printf("replay: %.2f s recorded in %.3f s: %.1f times real time\n", recorded_s, wall_s, recorded_s / wall_s);
#ifndef HEMM_SANITIZE  // the instrumentation makes wall-clock bounds meaningless
  EXPECT_GT(recorded_s / wall_s, 10.0);
#endif

  // A copy cut in the middle: refused where it broke, the rest replays.
  std::string bytes = read_file(rec);
  const std::string cut = dir + "/cut.rec";
  {
    std::ofstream f(cut, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  ChildProcess part({kBin + "hemm-operator", "--replay", cut, "--replay-speed", "0", "--replay-json",
                     dir + "/part.json"},
                    dir + "/part.out", dir + "/part.err");
  const auto prc = part.wait(60s);
  ASSERT_TRUE(prc.has_value());
  EXPECT_EQ(*prc, 2);
  const std::string err = read_file(dir + "/part.err");
  EXPECT_NE(err.find("cut.rec: record "), std::string::npos) << err;
  EXPECT_NE(err.find(" at byte "), std::string::npos) << err;
  EXPECT_NE(err.find("truncated"), std::string::npos) << err;
  const std::string pj = read_file(dir + "/part.json");
  EXPECT_GT(json_number(pj, "ticks").value_or(0), 0.3 * ticks);
  EXPECT_EQ(json_number(pj, "force_mismatches").value_or(-1), 0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hemm::test
