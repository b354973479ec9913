// The MCAP export of a session (operator/record/session_mcap.h), checked by a
// reader that is not the writer's code: deploy/mcap_reader.py, written from
// the MCAP specification in Python (magic, record layout, every CRC, the
// summary and its statistics, each schema decoded as a FileDescriptorSet,
// every message decoded and re-encoded to its very bytes). A short session
// on loopback (SIMULATED robot and Omni, the probe-cylinder script, so the
// probe meets the bin and forces are rendered) is recorded, exported with
// `hemm-operator --export-mcap`, read by that reader (its channel counts and
// the ticks' forces against the recording's), read back by the replay's
// loader, and replayed from both files: the same forces tick for tick. A
// corrupted copy is refused by both readers.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "operator/record/session_recording.h"
#include "operator/record/session_replay.h"
#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";
const std::string kReader = std::string(HEMM_SOURCE_DIR) + "/deploy/mcap_reader.py";
constexpr double kRunS = 7.0;

// The topic each recorded stream event is exported on (session_mcap.h).
std::string topic_of(const rec::StreamEvent& e) {
  switch (e.message().body_case()) {
    case wire::StreamMessage::kRobotState: return e.outgoing() ? "/link/stream" : "/robot/state";
    case wire::StreamMessage::kRangeScan: return e.outgoing() ? "/link/stream" : "/robot/scan";
    case wire::StreamMessage::kDepthChunk: return e.outgoing() ? "/link/stream" : "/robot/depth";
    case wire::StreamMessage::kCommand: return e.outgoing() ? "/operator/command" : "/link/stream";
    default: return "/link/stream";
  }
}

// "  /topic ... schema ... N" lines of the reader's channel list.
std::map<std::string, double> reader_counts(const std::string& out) {
  std::map<std::string, double> counts;
  std::istringstream s(out);
  for (std::string line; std::getline(s, line);) {
    std::istringstream l(line);
    std::string id, topic, schema;
    double n = -1;
    if ((l >> id >> topic >> schema >> n) && topic.rfind('/', 0) == 0) counts[topic] = n;
  }
  return counts;
}

struct Replayed {
  op::SessionReplayResult result;
  std::vector<std::pair<std::uint64_t, Eigen::Vector3d>> forces;
};
Replayed replay(const op::Recording& rec) {
  Replayed r;
  op::SessionReplayOptions o;
  o.speed = 0.0;
  o.on_tick = [&](std::uint64_t tick, const servo::TickOutput& out) {
    r.forces.emplace_back(tick, out.command.ee[0].force_H);
  };
  r.result = op::replay_session(rec, o);
  return r;
}

// A session of `seconds` on loopback recorded to dir/session.rec: the
// robot with `robot_config`, the operator with `operator_config` and `extra`.
void record_session(const std::string& dir, const std::string& robot_config, const std::string& operator_config,
                    double seconds, const std::vector<std::string>& extra) {
  const int tcp = free_port(), udp = free_port();
  ChildProcess robot({kBin + "hemm-robot", "--config", kConfigs + robot_config, "--listen", "127.0.0.1",
                      "--session-port", std::to_string(tcp), "--stream-port", std::to_string(udp), "--duration",
                      std::to_string(seconds + 20)},
                     dir + "/robot.out", dir + "/robot.err");
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 15s)) << read_file(dir + "/robot.err");
  std::vector<std::string> argv = {kBin + "hemm-operator", "--config", kConfigs + operator_config, "--robot",
                                   "127.0.0.1", "--session-port", std::to_string(tcp), "--duration",
                                   std::to_string(seconds), "--record", dir + "/session.rec"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  ChildProcess op(argv, dir + "/op.out", dir + "/op.err");
  const auto rc = op.wait(std::chrono::milliseconds(static_cast<int>((seconds + 40) * 1000)));
  robot.signal(SIGTERM);
  robot.wait(20s);
  ASSERT_TRUE(rc && *rc == 0) << read_file(dir + "/op.err");
}

// dir/session.rec exported to dir/session.mcap with the one command; the
// channels and counts it must have, from the recording.
std::map<std::string, double> export_session(const std::string& dir, op::Recording* native) {
  const ProcessResult ex = run_to_completion(
      {kBin + "hemm-operator", "--export-mcap", dir + "/session.rec", dir + "/session.mcap"}, dir, 60s);
  EXPECT_EQ(ex.rc, 0) << ex.err << ex.out;
  std::printf("%s", ex.out.c_str());
  EXPECT_FALSE(op::load_recording(dir + "/session.rec", native));
  std::map<std::string, double> expected{{"/hemm/recording", 1},
                                         {"/operator/servo", static_cast<double>(native->ticks.size())},
                                         {"/operator/device", static_cast<double>(native->ticks.size())},
                                         {"/operator/model_step", static_cast<double>(native->steps.size())}};
  for (const rec::StreamEvent& e : native->streams) ++expected[topic_of(e)];
  if (!native->sessions.empty()) expected["/link/session"] = static_cast<double>(native->sessions.size());
  return expected;
}

TEST(McapExport, IndependentReaderOpensItAndReplayGivesTheSameForces) {
  const std::string dir = make_temp_dir();
  record_session(dir, "robot.pbtxt", "operator.pbtxt", kRunS, {"--script", "probe-cylinder"});
  if (HasFatalFailure()) return;
  const std::string rec_path = dir + "/session.rec", mcap_path = dir + "/session.mcap";
  op::Recording native;
  std::map<std::string, double> expected = export_session(dir, &native);
  ASSERT_GT(native.ticks.size(), static_cast<std::size_t>(0.8 * kRunS * 1000));
  EXPECT_GT(expected["/robot/state"], 100);
  EXPECT_GT(expected["/robot/scan"], 10);
  EXPECT_GT(expected["/operator/command"], 100);

  // The independent reader: valid, the same channels and counts, the same ticks and forces.
  const std::string ticks_csv = dir + "/ticks.csv";
  const ProcessResult py = run_to_completion({"/usr/bin/python3", kReader, mcap_path, "--ticks", ticks_csv}, dir, 120s);
  ASSERT_EQ(py.rc, 0) << py.err << py.out;
  std::printf("%s", py.out.c_str());
  EXPECT_NE(py.out.find("valid MCAP"), std::string::npos) << py.out;
  EXPECT_EQ(reader_counts(py.out), expected) << py.out;
  const CsvColumns ticks = read_csv_columns(ticks_csv);
  ASSERT_TRUE(ticks.ok) << ticks.error;
  ASSERT_EQ(ticks.rows, native.ticks.size());
  std::size_t forced = 0;
  for (std::size_t i = 0; i < ticks.rows; ++i) {
    const rec::ServoTick& t = native.ticks[i];
    ASSERT_EQ(ticks["tick"][i], static_cast<double>(t.tick())) << i;
    ASSERT_EQ(ticks["t_ns"][i], static_cast<double>(t.t_ns())) << i;
    ASSERT_EQ(ticks["fx"][i], t.command(0).force(0)) << "tick " << t.tick();
    ASSERT_EQ(ticks["fy"][i], t.command(0).force(1)) << "tick " << t.tick();
    ASSERT_EQ(ticks["fz"][i], t.command(0).force(2)) << "tick " << t.tick();
    forced += std::hypot(t.command(0).force(0), t.command(0).force(1), t.command(0).force(2)) > 0.1;
  }
  EXPECT_GT(forced, 300u) << "the probe must touch the bin for the comparison to mean anything";

  // The replay's loader reads the export back into the same recording.
  op::Recording exported;
  const auto err = op::load_recording(mcap_path, &exported);
  ASSERT_FALSE(err) << *err;
  EXPECT_EQ(exported.header.SerializeAsString(), native.header.SerializeAsString());
  ASSERT_EQ(exported.ticks.size(), native.ticks.size());
  for (std::size_t i = 0; i < native.ticks.size(); ++i)
    ASSERT_EQ(exported.ticks[i].SerializeAsString(), native.ticks[i].SerializeAsString()) << "tick " << i;
  ASSERT_EQ(exported.steps.size(), native.steps.size());
  for (std::size_t i = 0; i < native.steps.size(); ++i)
    ASSERT_EQ(exported.steps[i].SerializeAsString(), native.steps[i].SerializeAsString()) << "step " << i;
  ASSERT_EQ(exported.streams.size(), native.streams.size());
  for (std::size_t i = 0; i < native.streams.size(); ++i)
    ASSERT_EQ(exported.streams[i].SerializeAsString(), native.streams[i].SerializeAsString()) << "stream " << i;
  ASSERT_EQ(exported.sessions.size(), native.sessions.size());

  // Replay from both: the same forces, tick for tick, each equal to the recorded one.
  const Replayed a = replay(native), b = replay(exported);
  EXPECT_TRUE(a.result.stopped.empty()) << a.result.stopped;
  EXPECT_TRUE(a.result.warning.empty()) << a.result.warning;
  EXPECT_EQ(a.result.ticks, native.ticks.size());
  EXPECT_EQ(a.result.force_mismatches, 0u);
  EXPECT_EQ(b.result.force_mismatches, 0u);
  ASSERT_EQ(a.forces.size(), b.forces.size());
  for (std::size_t i = 0; i < a.forces.size(); ++i) {
    ASSERT_EQ(a.forces[i].first, b.forces[i].first);
    ASSERT_EQ(a.forces[i].second, b.forces[i].second) << "tick " << a.forces[i].first;
  }
  // And the binary replays the export as it replays the recording.
  const ProcessResult rp =
      run_to_completion({kBin + "hemm-operator", "--replay", mcap_path, "--replay-speed", "0"}, dir, 120s);
  EXPECT_EQ(rp.rc, 0) << rp.err;
  EXPECT_NE(rp.out.find("force_mismatches=0 "), std::string::npos) << rp.out;

  // A flipped byte in the middle: both readers refuse the file.
  std::string bytes = read_file(mcap_path);
  bytes[bytes.size() / 2] ^= 0x01;
  const std::string bad = dir + "/bad.mcap";
  {
    std::ofstream f(bad, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  const ProcessResult pybad = run_to_completion({"/usr/bin/python3", kReader, bad}, dir, 120s);
  EXPECT_EQ(pybad.rc, 1) << pybad.out << pybad.err;
  EXPECT_NE(pybad.err.find("INVALID"), std::string::npos) << pybad.err;
  op::Recording partial;
  EXPECT_TRUE(op::load_recording(bad, &partial).has_value());
  std::filesystem::remove_all(dir);
}

// A 3D session (robot with the SIMULATED depth camera, operator with the
// live voxmap and the 3D probe): its depth chunks are in the recording and on
// /robot/depth, read by the independent reader; the replay says it does not
// rebuild the voxmap.
TEST(McapExport, ThreeDSessionRecordsItsDepthChunks) {
  const std::string dir = make_temp_dir();
  record_session(dir, "robot_depth.pbtxt", "operator_probe3d.pbtxt", 4.0, {});
  if (HasFatalFailure()) return;
  op::Recording native;
  const std::map<std::string, double> expected = export_session(dir, &native);
  ASSERT_TRUE(expected.count("/robot/depth")) << "no depth chunk recorded";
  EXPECT_GT(expected.at("/robot/depth"), 50);  // ~130 chunks a second
  const ProcessResult py = run_to_completion({"/usr/bin/python3", kReader, dir + "/session.mcap"}, dir, 120s);
  ASSERT_EQ(py.rc, 0) << py.err << py.out;
  std::printf("%s", py.out.c_str());
  EXPECT_EQ(reader_counts(py.out), expected) << py.out;
  op::Recording exported;
  ASSERT_FALSE(op::load_recording(dir + "/session.mcap", &exported));
  ASSERT_EQ(exported.streams.size(), native.streams.size());
  for (std::size_t i = 0; i < native.streams.size(); ++i)
    ASSERT_EQ(exported.streams[i].SerializeAsString(), native.streams[i].SerializeAsString()) << "stream " << i;
  const ProcessResult rp =
      run_to_completion({kBin + "hemm-operator", "--replay", dir + "/session.mcap", "--replay-speed", "0"}, dir, 120s);
  EXPECT_EQ(rp.rc, 0) << rp.err;
  EXPECT_NE(rp.err.find("does not rebuild the live voxmap"), std::string::npos) << rp.err;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hemm::test
