#include <gtest/gtest.h>

#include <cstdio>
#include <chrono>
#include <fstream>
#include <thread>
#include <sstream>
#include <string>
#include <vector>

#include "operator/servo/servo_log.h"

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
  const std::string path = testing::TempDir() + "servo_log_test.csv";
  auto logger = make_servo_logger(1024);
  ASSERT_FALSE(logger.start(path));
  EXPECT_TRUE(logger.start(path).has_value());  // already running
  constexpr int kN = 3000;  // more than the ring: the writer must keep up
  std::uint64_t refused = 0;
  for (int i = 0; i < kN; ++i) {
    ServoLogRecord r;
    r.t_ns = 1'000'000LL * i;
    r.tick = static_cast<std::uint64_t>(i);
    r.force[2] = 0.001 * i;
    r.device_position[0] = -0.25 * i;
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
