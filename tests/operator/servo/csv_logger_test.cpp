#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <stdexcept>
#include <chrono>
#include <fstream>
#include <thread>
#include <sstream>
#include <string>
#include <vector>

#include "operator/servo/servo_log.h"
#include "tests/temp_dir.h"

namespace hemm::servo {
namespace {

std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(f, l);) lines.push_back(l);
  return lines;
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string f; std::getline(ss, f, ',');) out.push_back(f);
  return out;
}

TEST(ServoLog, WriterThreadWritesHeaderAndEveryRecord) {
  const std::string path = hemm::test::make_temp_dir() + "/servo_log_test.csv";
  auto logger = make_servo_logger(1024);
  ASSERT_FALSE(logger.start(path));
  EXPECT_TRUE(logger.start(path).has_value());  // already running
  constexpr int kN = 3000;  // more than the ring: the writer must keep up
  std::uint64_t refused = 0;
  for (int i = 0; i < kN; ++i) {
    ServoLogRecord r;
    r.t_ns = 1'000'000LL * i;
    r.tick = static_cast<std::uint64_t>(i);
    r.ee[0].force[2] = 0.001 * i;
    r.ee[0].position[0] = -0.25 * i;
    r.model_age_ns = i % 7;
    r.link_rtt_ns = 123;
    while (!logger.push(r)) {  // a refused push is counted as dropped; retry
      ++refused;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  logger.stop();
  const auto lines = read_lines(path);
  ASSERT_EQ(lines.size(), static_cast<std::size_t>(kN + 1));
  EXPECT_EQ(lines[0], servo_log_header());
  const auto header = split(lines[0]);
  for (int i = 1; i <= kN; i += 997) {
    const auto f = split(lines[i]);
    ASSERT_EQ(f.size(), header.size());
    EXPECT_EQ(std::stoll(f[0]), 1'000'000LL * (i - 1));
    EXPECT_EQ(std::stoull(f[1]), static_cast<unsigned long long>(i - 1));
    EXPECT_EQ(std::stod(f[4]), -0.25 * (i - 1));   // dev_x
    EXPECT_EQ(std::stod(f[18]), 0.001 * (i - 1));  // fz
    EXPECT_EQ(std::stoll(f[21]), (i - 1) % 7);     // model_age_ns
    EXPECT_EQ(std::stoll(f[23]), 123);             // link_rtt_ns
  }
  EXPECT_EQ(logger.written(), static_cast<std::uint64_t>(kN));
  EXPECT_EQ(logger.dropped(), refused);
  EXPECT_FALSE(logger.write_failed());
  std::remove(path.c_str());
}

// The columns of the one-end-effector log before the device API grew to
// several 6-DoF end-effectors, spelled out: readers (deploy/plots/plot_run.py,
// the latency suite) find them by these names.
constexpr const char* kOriginalHeader =
    "t_ns,tick,wake_latency_ns,compute_ns,"
    "dev_x,dev_y,dev_z,dev_vx,dev_vy,dev_vz,"
    "proxy_x,proxy_y,proxy_z,ip_x,ip_y,ip_z,fx,fy,fz,"
    "buttons,mode,model_age_ns,model_version,link_rtt_ns,link_offset_ns";

TEST(ServoLog, OriginalColumnsKeepTheirNamesAndPlaces) {
  const auto original = split(kOriginalHeader);
  for (int n = 1; n <= device::kMaxEndEffectors; ++n) {
    const auto h = split(servo_log_header(n));
    ASSERT_GT(h.size(), original.size());
    for (std::size_t i = 0; i < original.size(); ++i) EXPECT_EQ(h[i], original[i]) << n;
    // Every name once.
    for (std::size_t i = 0; i < h.size(); ++i)
      for (std::size_t j = i + 1; j < h.size(); ++j) EXPECT_NE(h[i], h[j]);
  }
  EXPECT_THROW(servo_log_header(0), std::invalid_argument);
  EXPECT_THROW(servo_log_header(device::kMaxEndEffectors + 1), std::invalid_argument);
}

// Each end-effector's pose, twist, wrench and handle inputs land under its
// own names; values chosen distinct so a column mix-up shows.
TEST(ServoLog, EveryEndEffectorIsLoggedUnderItsNames) {
  ServoLogRecord r;
  r.end_effectors = 2;
  r.mode = 2;
  for (int k = 0; k < 2; ++k) {
    ServoLogEndEffector& e = r.ee[k];
    const double b = 100.0 * (k + 1);
    for (int i = 0; i < 3; ++i) {
      e.position[i] = b + 1 + i;
      e.velocity[i] = b + 4 + i;
      e.proxy_position[i] = b + 7 + i;
      e.interaction_point[i] = b + 10 + i;
      e.force[i] = b + 13 + i;
      e.angular_velocity[i] = b + 20 + i;
      e.torque[i] = b + 23 + i;
    }
    for (int i = 0; i < 4; ++i) e.orientation[i] = b + 16 + i;
    e.grip_force = b + 26;
    e.buttons = 3u + static_cast<std::uint32_t>(k);
    e.inputs = k == 0 ? 5u : 10u;
    e.enabled = k;
    e.deadman = 1 - k;
    e.grip_position = b + 27;
    e.grip_velocity = b + 28;
    e.joystick[0] = b + 29;
    e.joystick[1] = b + 30;
    e.switch_on = 1 - k;
    e.attached = k;
  }
  char buf[CsvLogger<ServoLogRecord>::kLineMax];
  const std::size_t n = format_servo_log_record(r, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  const auto h = split(servo_log_header(2));
  const auto f = split(std::string(buf, n - 1));
  ASSERT_EQ(f.size(), h.size());
  auto col = [&](const std::string& name) {
    for (std::size_t i = 0; i < h.size(); ++i)
      if (h[i] == name) return std::stod(f[i]);
    ADD_FAILURE() << "no column " << name;
    return -1.0;
  };
  for (int k = 0; k < 2; ++k) {
    const std::string p = k == 0 ? "" : "ee1_";
    const double b = 100.0 * (k + 1);
    EXPECT_EQ(col(p + "dev_x"), b + 1);
    EXPECT_EQ(col(p + "dev_vz"), b + 6);
    EXPECT_EQ(col(p + "proxy_y"), b + 8);
    EXPECT_EQ(col(p + "ip_z"), b + 12);
    EXPECT_EQ(col(p + "fx"), b + 13);
    EXPECT_EQ(col(p + "fz"), b + 15);
    EXPECT_EQ(col(p + "dev_qw"), b + 16);
    EXPECT_EQ(col(p + "dev_qz"), b + 19);
    EXPECT_EQ(col(p + "dev_wx"), b + 20);
    EXPECT_EQ(col(p + "tx"), b + 23);
    EXPECT_EQ(col(p + "tz"), b + 25);
    EXPECT_EQ(col(p + "grip_force"), b + 26);
    EXPECT_EQ(col(p + "buttons"), 3 + k);
    EXPECT_EQ(col(p + "inputs"), k == 0 ? 5 : 10);
    EXPECT_EQ(col(p + "enabled"), k);
    EXPECT_EQ(col(p + "deadman"), 1 - k);
    EXPECT_EQ(col(p + "grip"), b + 27);
    EXPECT_EQ(col(p + "grip_v"), b + 28);
    EXPECT_EQ(col(p + "joy_x"), b + 29);
    EXPECT_EQ(col(p + "joy_y"), b + 30);
    EXPECT_EQ(col(p + "switch"), 1 - k);
    EXPECT_EQ(col(p + "attached"), k);
  }
  EXPECT_EQ(col("mode"), 2);
  // One end-effector: its own header's column count, nothing of ee1.
  r.end_effectors = 1;
  const std::size_t n1 = format_servo_log_record(r, buf, sizeof buf);
  ASSERT_GT(n1, 0u);
  EXPECT_EQ(split(std::string(buf, n1 - 1)).size(), split(servo_log_header(1)).size());
  r.end_effectors = 0;
  EXPECT_EQ(format_servo_log_record(r, buf, sizeof buf), 0u);
}

// The longest numbers still fit the logger's line buffer with the most end-effectors.
TEST(ServoLog, WidestRecordFitsTheLineBuffer) {
  ServoLogRecord r;
  r.end_effectors = device::kMaxEndEffectors;
  r.t_ns = r.wake_latency_ns = r.compute_ns = r.model_age_ns = r.link_rtt_ns = r.link_offset_ns =
      std::numeric_limits<std::int64_t>::min();
  r.tick = r.model_version = std::numeric_limits<std::uint64_t>::max();
  r.mode = std::numeric_limits<std::uint32_t>::max();
  const double w = -2.2250738585072014e-308;  // 24 characters
  for (auto& e : r.ee) {
    for (double* a : {e.position, e.velocity, e.angular_velocity, e.proxy_position, e.interaction_point, e.force,
                      e.torque})
      for (int i = 0; i < 3; ++i) a[i] = w;
    for (double& q : e.orientation) q = w;
    e.grip_force = e.grip_position = e.grip_velocity = e.joystick[0] = e.joystick[1] = w;
    e.buttons = e.inputs = std::numeric_limits<std::uint32_t>::max();
    e.enabled = e.deadman = e.switch_on = e.attached = std::numeric_limits<int>::min();
  }
  char buf[CsvLogger<ServoLogRecord>::kLineMax];
  EXPECT_GT(format_servo_log_record(r, buf, sizeof buf), 0u);
}

TEST(ServoLog, FullRingDropsAndCountsWithoutBlocking) {
  auto logger = make_servo_logger(8);  // not started: nothing drains
  ServoLogRecord r;
  int ok = 0;
  for (int i = 0; i < 20; ++i) ok += logger.push(r);
  EXPECT_EQ(ok, 8);
  EXPECT_EQ(logger.dropped(), 12u);
}

TEST(ServoLog, UnwritablePathIsAnError) {
  auto logger = make_servo_logger(8);
  const auto err = logger.start("/nonexistent/dir/log.csv");
  ASSERT_TRUE(err.has_value());
  EXPECT_NE(err->find("/nonexistent/dir/log.csv"), std::string::npos);
}

}  // namespace
}  // namespace hemm::servo
