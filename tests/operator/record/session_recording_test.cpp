// Session recordings (operator/record): what is written reads back equal;
// truncated, corrupt and foreign files are refused with the record and byte
// where they broke, keeping what came before (a foreign file changes
// nothing); and a session recorded from a model thread and a servo task
// replays to the same forces bit for bit, while a changed recorded force is
// caught.
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <google/protobuf/util/delimited_message_util.h>
#include <gtest/gtest.h>
#include <numbers>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "operator/record/session_mcap.h"
#include "operator/record/session_recording.h"
#include "operator/record/session_replay.h"

namespace ho = hemm::op;
namespace hw = hemm::wire;
namespace hr = hemm::rec;

namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("hemm_rec_" + std::to_string(::getpid()) + "_" + name)).string();
}
std::string read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}
void write_bytes(const std::string& p, const std::string& b) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
}
// Where each record starts, found with protobuf's own delimited reader (not
// the loader under test).
std::vector<std::size_t> record_starts(const std::string& bytes) {
  google::protobuf::io::ArrayInputStream in(bytes.data(), static_cast<int>(bytes.size()));
  std::vector<std::size_t> starts;
  hr::Record r;
  bool clean = false;
  while (true) {
    const auto at = static_cast<std::size_t>(in.ByteCount());
    if (at == bytes.size()) break;
    if (!google::protobuf::util::ParseDelimitedFromZeroCopyStream(&r, &in, &clean)) break;
    starts.push_back(at);
  }
  return starts;
}

hr::Header header() {
  hr::Header h;
  h.set_start_ns(123);
  h.set_servo_period_ns(1'000'000);
  h.set_initial_mode(static_cast<std::uint32_t>(hemm::math::Mode::kExploration));
  h.set_script("test");
  h.set_end_effectors(1);
  return h;
}

// A laser at the robot's origin facing +x before a wall `d` metres ahead,
// 91 beams over +-45 deg.
hw::RangeScan wall_ahead(double d, double robot_x, std::int64_t stamp, std::uint32_t id) {
  hw::RangeScan m;
  m.set_stamp_ns(stamp);
  m.set_scan_id(id);
  m.set_sensor(hw::RANGE_SENSOR_LASER);
  m.set_sensor_name("laser");
  m.mutable_t_w_r()->set_x(robot_x);
  m.mutable_t_r_s()->mutable_orientation()->set_w(1.0);
  const double a0 = -std::numbers::pi / 4, step = std::numbers::pi / 180;
  m.set_angle_min(a0);
  m.set_angle_step(step);
  m.set_beam_count(91);
  m.set_range_min(0.05);
  m.set_range_max(8.0);
  for (int i = 0; i < 91; ++i) {
    m.add_ranges(static_cast<float>(d / std::cos(a0 + i * step)));
    m.add_valid(true);
  }
  return m;
}

ho::ServoTickRecord tick_record(std::uint64_t k) {
  ho::ServoTickRecord t;
  t.tick = k;
  t.in.t_ns = 1'000'000'000 + static_cast<std::int64_t>(k) * 1'000'000;
  t.in.ee[0].position_H = Eigen::Vector3d(0.01 * k, -0.02, 1.0 / 3.0);
  t.in.ee[0].orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ()));
  t.in.ee[0].velocity_H = Eigen::Vector3d(0.1, 0.2, -0.3);
  t.in.ee[0].handle.buttons = k % 2 == 0 ? hemm::device::kButton1 : 0u;
  t.in.ee[0].handle.has_grip = true;
  t.in.ee[0].handle.grip_position = 0.004;
  t.model_version = k / 2;
  t.command.ee[0].force_H = Eigen::Vector3d(1.0 / 7.0, -2.5, 1e-300);
  t.view_presses = k == 3 ? hemm::device::kButton1 : 0u;
  t.mode = 4;
  return t;
}

TEST(SessionRecording, WhatIsWrittenReadsBackEqual) {
  const std::string path = temp_path("roundtrip.rec");
  std::vector<hr::ModelStep> steps_written;
  {
    ho::SessionRecorder r(path, header(), 64);
    r.start();
    for (std::uint64_t k = 0; k < 10; ++k) r.ticks().push(tick_record(k));
    ho::ModelThread::StepInputs in;
    in.now_ns = 42;
    in.offset_ns = -7;
    in.delay_ns = 150'000'000;
    in.commands = {{40, 0.2, -0.1}, {41, 0.25, 0.0}};
    hw::RobotState st;
    st.set_stamp_ns(39);
    st.mutable_t_w_r_odom()->set_x(0.5);
    in.state = st;
    in.scans = {std::make_shared<const hw::RangeScan>(wall_ahead(1.0, 0.5, 38, 1))};
    r.model_step(in, 1);
    steps_written.emplace_back();
    ho::to_proto(in, 1, &steps_written.back());
    in.state.reset();
    in.scans.clear();
    r.model_step(in, 2);
    steps_written.emplace_back();
    ho::to_proto(in, 2, &steps_written.back());
    hw::StreamMessage m;
    m.mutable_command()->set_v(0.3);
    r.stream(50, true, m);
    hw::SessionFrame f;
    f.mutable_estop()->set_engaged(true);
    r.session(51, true, f);
    r.stop();
    EXPECT_EQ(r.records(), 1u + 10 + 2 + 1 + 1);
    EXPECT_EQ(r.ticks_dropped(), 0u);
    EXPECT_FALSE(r.write_failed());
  }
  ho::Recording rec;
  ASSERT_EQ(ho::load_recording(path, &rec), std::nullopt);
  EXPECT_EQ(rec.records, 15u);
  EXPECT_EQ(rec.bytes, read_bytes(path).size());
  EXPECT_EQ(rec.header.magic(), ho::kRecordingMagic);
  EXPECT_EQ(rec.header.start_ns(), 123);
  ASSERT_EQ(rec.ticks.size(), 10u);
  for (std::uint64_t k = 0; k < 10; ++k) {
    ho::ServoTickRecord back;
    ASSERT_EQ(ho::from_proto(rec.ticks[k], 1, &back), std::nullopt);
    const ho::ServoTickRecord want = tick_record(k);
    EXPECT_EQ(back.tick, want.tick);
    EXPECT_EQ(back.in.t_ns, want.in.t_ns);
    EXPECT_EQ(back.in.ee[0].position_H, want.in.ee[0].position_H);  // exact: doubles travel bit for bit
    EXPECT_EQ(back.in.ee[0].orientation_H.coeffs(), want.in.ee[0].orientation_H.coeffs());
    EXPECT_EQ(back.in.ee[0].velocity_H, want.in.ee[0].velocity_H);
    EXPECT_EQ(back.in.ee[0].handle.buttons, want.in.ee[0].handle.buttons);
    EXPECT_TRUE(back.in.ee[0].handle.has_grip);
    EXPECT_FALSE(back.in.ee[0].handle.has_deadman);
    EXPECT_EQ(back.in.ee[0].handle.grip_position, 0.004);
    EXPECT_EQ(back.model_version, want.model_version);
    EXPECT_EQ(back.command.ee[0].force_H, want.command.ee[0].force_H);
    EXPECT_EQ(back.view_presses, want.view_presses);
    EXPECT_EQ(back.mode, want.mode);
  }
  ASSERT_EQ(rec.steps.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) EXPECT_EQ(rec.steps[i].SerializeAsString(), steps_written[i].SerializeAsString());
  EXPECT_TRUE(rec.steps[0].has_state());
  EXPECT_FALSE(rec.steps[1].has_state());
  ASSERT_EQ(rec.streams.size(), 1u);
  EXPECT_EQ(rec.streams[0].message().command().v(), 0.3);
  ASSERT_EQ(rec.sessions.size(), 1u);
  EXPECT_TRUE(rec.sessions[0].frame().estop().engaged());
  std::remove(path.c_str());
}

// A recording of 1 header + 30 ticks.
std::string small_recording() {
  const std::string path = temp_path("small.rec");
  {
    ho::SessionRecorder r(path, header(), 64);
    for (std::uint64_t k = 0; k < 30; ++k) r.ticks().push(tick_record(k));
    r.stop();
  }
  std::string b = read_bytes(path);
  std::remove(path.c_str());
  return b;
}

TEST(SessionRecording, TruncatedFileSaysWhereItBrokeAndKeepsTheRecordsBefore) {
  const std::string bytes = small_recording();
  const std::vector<std::size_t> starts = record_starts(bytes);
  ASSERT_EQ(starts.size(), 31u);
  const std::string path = temp_path("truncated.rec");
  // Cut inside record 20's body.
  write_bytes(path, bytes.substr(0, starts[20] + 5));
  ho::Recording rec;
  const auto e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 20 at byte " + std::to_string(starts[20]) + ": truncated"), std::string::npos) << *e;
  EXPECT_EQ(rec.records, 20u);
  EXPECT_EQ(rec.ticks.size(), 19u);
  EXPECT_EQ(rec.bytes, starts[20]);
  EXPECT_EQ(rec.ticks.back().tick(), 18u);
  // Cut inside a length prefix that needs a second byte: none here is that
  // long, so cut right after a record: that is a whole, shorter recording.
  write_bytes(path, bytes.substr(0, starts[10]));
  EXPECT_EQ(ho::load_recording(path, &rec), std::nullopt);
  EXPECT_EQ(rec.ticks.size(), 9u);
  std::remove(path.c_str());
}

TEST(SessionRecording, CorruptRecordIsRefusedWhereItIs) {
  const std::string bytes = small_recording();
  const std::vector<std::size_t> starts = record_starts(bytes);
  const std::string path = temp_path("corrupt.rec");
  ho::Recording rec;
  // A body byte set to an invalid tag (field 0).
  std::string b = bytes;
  b[starts[7] + 1] = '\0';
  write_bytes(path, b);
  auto e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 7 at byte " + std::to_string(starts[7])), std::string::npos) << *e;
  EXPECT_EQ(rec.ticks.size(), 6u);
  // A length prefix claiming 2^40 bytes.
  b = bytes.substr(0, starts[12]) + std::string("\x80\x80\x80\x80\x80\x20", 6) + bytes.substr(starts[12]);
  write_bytes(path, b);
  e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 12 at byte " + std::to_string(starts[12]) + ": length"), std::string::npos) << *e;
  EXPECT_EQ(rec.ticks.size(), 11u);
  // A tick out of order (record 5 repeated after record 9).
  b = bytes.substr(0, starts[10]) + bytes.substr(starts[5], starts[6] - starts[5]) + bytes.substr(starts[10]);
  write_bytes(path, b);
  e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 10 at byte " + std::to_string(starts[10]) + ": tick 4 does not follow tick 8"),
            std::string::npos)
      << *e;
  std::remove(path.c_str());
}

// The check value of the CRC-32C catalogue (Castagnoli, reflected, init and
// final xor all ones): "123456789" -> 0xe3069283.
TEST(SessionRecording, ChecksumIsCrc32c) {
  EXPECT_EQ(ho::record_checksum("123456789", 9), 0xe3069283u);
  EXPECT_EQ(ho::record_checksum("", 0), 0u);
}

// A single flipped bit inside a number parses as another number; the
// record's checksum catches it, before the record is used.
TEST(SessionRecording, FlippedBitInsideANumberIsCaughtByTheChecksum) {
  const std::string bytes = small_recording();
  const std::vector<std::size_t> starts = record_starts(bytes);
  ASSERT_EQ(starts.size(), 31u);
  // Every record, read by protobuf itself, carries its checksum.
  {
    google::protobuf::io::ArrayInputStream in(bytes.data(), static_cast<int>(bytes.size()));
    hr::Record r;
    bool clean = false;
    for (std::size_t i = 0; i < starts.size(); ++i) {
      ASSERT_TRUE(google::protobuf::util::ParseDelimitedFromZeroCopyStream(&r, &in, &clean));
      EXPECT_TRUE(r.has_crc32c()) << "record " << i;
    }
  }
  const std::string path = temp_path("flipped.rec");
  // In record 7 (a tick), the first bit from its middle on whose flip
  // protobuf still parses: a number changed, nothing malformed.
  std::string b;
  const std::size_t body = starts[7] + (bytes[starts[7]] & 0x80 ? 2 : 1);  // after the length prefix
  const std::size_t end = starts[8] - 5;                                  // before the checksum field
  for (std::size_t at = (body + end) / 2; at < end && b.empty(); ++at) {
    std::string t = bytes;
    t[at] = static_cast<char>(t[at] ^ 0x04);
    hr::Record still_parses;
    if (still_parses.ParseFromArray(t.data() + body, static_cast<int>(starts[8] - body)) && still_parses.has_tick())
      b = t;
  }
  ASSERT_FALSE(b.empty());
  write_bytes(path, b);
  ho::Recording rec;
  const auto e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 7 at byte " + std::to_string(starts[7]) + ": checksum mismatch"), std::string::npos)
      << *e;
  EXPECT_EQ(rec.ticks.size(), 6u);
  std::remove(path.c_str());
}

// Recordings of format 1 (no checksums) still load; an unknown version does not.
TEST(SessionRecording, FormatOneWithoutChecksumsStillReads) {
  auto without_checksums = [](std::uint32_t version) {
    std::string b;
    google::protobuf::io::StringOutputStream out(&b);
    hr::Record r;
    *r.mutable_header() = header();
    r.mutable_header()->set_magic(ho::kRecordingMagic);
    r.mutable_header()->set_format_version(version);
    EXPECT_TRUE(google::protobuf::util::SerializeDelimitedToZeroCopyStream(r, &out));
    for (std::uint64_t k = 0; k < 3; ++k) {
      ho::to_proto(tick_record(k), r.mutable_tick());
      EXPECT_TRUE(google::protobuf::util::SerializeDelimitedToZeroCopyStream(r, &out));
    }
    return b;
  };
  const std::string path = temp_path("v1.rec");
  write_bytes(path, without_checksums(1));
  ho::Recording rec;
  EXPECT_EQ(ho::load_recording(path, &rec), std::nullopt);
  EXPECT_EQ(rec.header.format_version(), 1u);
  EXPECT_EQ(rec.ticks.size(), 3u);
  // Format 2 without its checksums is corrupt.
  write_bytes(path, without_checksums(2));
  auto e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("record 0 at byte 0: no checksum"), std::string::npos) << *e;
  write_bytes(path, without_checksums(9));
  e = ho::load_recording(path, &rec);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->find("format version 9"), std::string::npos) << *e;
  EXPECT_EQ(rec.header.format_version(), 1u);  // unchanged by the refused files
  std::remove(path.c_str());
}

TEST(SessionRecording, ForeignFilesChangeNothing) {
  ho::Recording rec;
  rec.header.set_script("untouched");
  rec.records = 99;
  const std::string path = temp_path("foreign.csv");
  const std::vector<std::string> foreign = {
      "t,x,y,z\n0,0,0,0\n",                                      // a trajectory CSV
      "",                                                         // empty
      small_recording().substr(0, 3),                              // a header cut short
      std::string("\x05\x0a\x03" "abc", 6),                        // a record, but no header
  };
  for (const std::string& f : foreign) {
    write_bytes(path, f);
    const auto e = ho::load_recording(path, &rec);
    EXPECT_TRUE(e.has_value());
    EXPECT_EQ(rec.records, 99u);
    EXPECT_EQ(rec.header.script(), "untouched");
  }
  EXPECT_FALSE(ho::looks_like_recording(path));
  EXPECT_TRUE(ho::load_recording(temp_path("does_not_exist"), &rec).has_value());
  std::remove(path.c_str());
}

// A SIMULATED session without a network: a model thread (stepped here) fed
// with a robot driving toward a wall, a servo task whose hand sweeps into
// it, both recorded through the station's taps; then replayed.
TEST(SessionReplay, ReproducesTheRecordedForcesBitForBitAndCatchesAChange) {
  const std::string path = temp_path("session.rec");
  std::uint64_t forced_ticks = 0;
  {
    ho::SessionRecorder recorder(path, header(), 8192);
    recorder.start();
    hemm::servo::ModelChannel channel;
    ho::ModelThread model(channel, ho::ModelThreadParams{});
    model.set_step_tap([&](const ho::ModelThread::StepInputs& in, const ho::OperatorModelSnapshot& s) {
      recorder.model_step(in, s.version);
    });
    ho::OperatorTaskParams tp;
    tp.proxy.period = 1e-3;
    tp.initial_mode = hemm::math::Mode::kExploration;
    ho::OperatorServoTask task(tp);
    task.set_tick_tap(&recorder.ticks());
    task.on_servo_start();
    const hemm::servo::ModelSnapshot empty;
    hemm::servo::TickOutput out;
    const std::int64_t t0 = 5'000'000'000;
    for (std::uint64_t k = 0; k < 3000; ++k) {
      const std::int64_t t = t0 + static_cast<std::int64_t>(k) * 1'000'000;
      if (k % 20 == 0) {  // 50 Hz model steps, a scan and a state every 40 ms
        const double x = 0.05 * static_cast<double>(k) * 1e-3;  // robot creeping at 5 cm/s
        if (k % 40 == 0) {
          hw::RobotState st;
          st.set_stamp_ns(t - 3'000'000);
          st.mutable_t_w_r_odom()->set_x(x);
          st.set_v(0.05);
          model.submit_state(st);
          model.submit_scan(std::make_shared<const hw::RangeScan>(wall_ahead(1.5 - x, x, t - 3'000'000, k)));
        }
        model.record_command(ho::SentCommand{t, 0.05, 0.0});
        model.set_command_delay(150'000'000 + static_cast<std::int64_t>(k) * 1000);
        model.set_clock_offset(-12345);
        model.step(t);
      }
      hemm::device::DeviceSample s;
      s.t_ns = t;
      const double ph = static_cast<double>(k) * 1e-3;
      // Forward in W is -z of the device (R_B_H); the hand pushes 8 cm
      // forward over the 3 s, sliding sideways.
      s.ee[0].position_H = Eigen::Vector3d(0.02 * std::sin(1.3 * ph), 0.0, -0.08 * ph / 3.0);
      s.ee[0].velocity_H = Eigen::Vector3d(0.026 * std::cos(1.3 * ph), 0.0, -0.08 / 3.0);
      s.ee[0].handle.buttons = 0;
      const hemm::servo::ModelSnapshot* snap = channel.acquire();
      hemm::servo::prepare_tick_output(s, k, out);
      task.tick(s, snap != nullptr ? *snap : empty, out);
      if (out.command.ee[0].force_H.norm() > 0.05) ++forced_ticks;
    }
    recorder.stop();
    EXPECT_EQ(recorder.ticks_dropped(), 0u);
  }
  // The hand must reach the wall for the comparison to mean anything.
  EXPECT_GT(forced_ticks, 200u);

  ho::Recording rec;
  ASSERT_EQ(ho::load_recording(path, &rec), std::nullopt);
  ASSERT_EQ(rec.ticks.size(), 3000u);
  ASSERT_EQ(rec.steps.size(), 150u);
  ho::SessionReplayOptions o;
  o.speed = 0.0;
  std::uint64_t snapshots = 0;
  o.on_snapshot = [&](const ho::OperatorModelSnapshot&) { ++snapshots; };
  const ho::SessionReplayResult r = ho::replay_session(rec, o);
  EXPECT_TRUE(r.stopped.empty()) << r.stopped;
  EXPECT_EQ(r.ticks, 3000u);
  EXPECT_EQ(r.steps, 150u);
  EXPECT_EQ(snapshots, 150u);
  EXPECT_EQ(r.ticks_missing, 0u);
  EXPECT_EQ(r.max_force_error_N, 0.0);
  EXPECT_EQ(r.force_mismatches, 0u);
  EXPECT_EQ(r.mode_mismatches, 0u);
  EXPECT_NEAR(r.recorded_s, 2.999, 1e-9);
  EXPECT_TRUE(r.warning.empty()) << r.warning;

  // The same session through its MCAP export (session_mcap.h): read back
  // record for record, replayed to the same forces tick for tick.
  {
    const std::string mcap = temp_path("session.mcap");
    const ho::McapExport x = ho::export_mcap(rec, mcap);
    EXPECT_EQ(x.topics.at("/operator/servo"), 3000u);
    EXPECT_EQ(x.topics.at("/operator/device"), 3000u);
    EXPECT_EQ(x.topics.at("/operator/model_step"), 150u);
    ho::Recording back;
    ASSERT_EQ(ho::load_recording(mcap, &back), std::nullopt);
    EXPECT_EQ(back.header.SerializeAsString(), rec.header.SerializeAsString());
    ASSERT_EQ(back.ticks.size(), rec.ticks.size());
    for (std::size_t i = 0; i < rec.ticks.size(); ++i)
      ASSERT_EQ(back.ticks[i].SerializeAsString(), rec.ticks[i].SerializeAsString()) << i;
    ASSERT_EQ(back.steps.size(), rec.steps.size());
    for (std::size_t i = 0; i < rec.steps.size(); ++i)
      ASSERT_EQ(back.steps[i].SerializeAsString(), rec.steps[i].SerializeAsString()) << i;
    std::vector<Eigen::Vector3d> fa, fb;
    ho::SessionReplayOptions oa = o, ob = o;
    oa.on_tick = [&](std::uint64_t, const hemm::servo::TickOutput& t) { fa.push_back(t.command.ee[0].force_H); };
    ob.on_tick = [&](std::uint64_t, const hemm::servo::TickOutput& t) { fb.push_back(t.command.ee[0].force_H); };
    ho::replay_session(rec, oa);
    const ho::SessionReplayResult rb = ho::replay_session(back, ob);
    EXPECT_EQ(rb.force_mismatches, 0u);
    ASSERT_EQ(fa.size(), 3000u);
    ASSERT_EQ(fa.size(), fb.size());
    for (std::size_t i = 0; i < fa.size(); ++i) ASSERT_EQ(fa[i], fb[i]) << "tick " << i;
    std::remove(mcap.c_str());
  }

  // A 3D session's replay says what it does not rebuild.
  ho::Recording three_d = rec;
  three_d.header.set_config_text("probe_3d { enabled: true }");
  EXPECT_NE(ho::replay_session(three_d, o).warning.find("3D session"), std::string::npos);

  // A recorded force changed by 1 uN on one tick is found on that tick.
  ho::Recording changed = rec;
  changed.ticks[2500].mutable_command(0)->set_force(1, changed.ticks[2500].command(0).force(1) + 1e-6);
  const ho::SessionReplayResult c = ho::replay_session(changed, o);
  EXPECT_EQ(c.force_mismatches, 1u);
  EXPECT_NEAR(c.max_force_error_N, 1e-6, 1e-12);
  EXPECT_EQ(c.max_error_tick, 2500u);

  // The readable part of a truncated copy replays, matching. The cut is
  // inside a record (a cut that lands on a record's boundary leaves a file a
  // reader cannot tell from a complete one: the format has no end record; the
  // run's sizes vary, and 1 run in 8 cut on a boundary when this took 2/3).
  const std::string bytes = read_bytes(path);
  std::size_t cut = bytes.size() * 2 / 3;
  const std::vector<std::size_t> starts = record_starts(bytes);
  if (std::find(starts.begin(), starts.end(), cut) != starts.end()) ++cut;
  write_bytes(path, bytes.substr(0, cut));
  ho::Recording part;
  ASSERT_TRUE(ho::load_recording(path, &part).has_value());
  const ho::SessionReplayResult p = ho::replay_session(part, o);
  EXPECT_GT(p.ticks, 1000u);
  EXPECT_EQ(p.max_force_error_N, 0.0);
  std::remove(path.c_str());
}

}  // namespace
