// Trajectory CSV parsing: good files in both layouts; every kind of bad row is
// rejected with file:line and leaves the output untouched.
#include "operator/device/trajectory_csv.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

Trajectory sentinel() {
  Trajectory t;
  TrajectorySample s;
  s.t_s = 42.0;
  s.buttons = 7;
  t.samples.push_back(s);
  t.has_orientation = true;
  return t;
}

void expect_untouched(const Trajectory& t) {
  ASSERT_EQ(t.samples.size(), 1u);
  EXPECT_EQ(t.samples[0].t_s, 42.0);
  EXPECT_EQ(t.samples[0].buttons, 7u);
  EXPECT_TRUE(t.has_orientation);
}

TEST(TrajectoryCsv, ParsesPositionOnlyWithHeaderCommentsAndCrlf) {
  const std::string text =
      "t_s,x,y,z,buttons\r\n"
      "# a comment\n"
      "\n"
      "0.0,0.01,-0.02,0.003,0\r\n"
      "0.5, 0.02 ,-0.01,0,3\n"
      "1e0,+0.001,0,0,1";
  Trajectory t;
  ASSERT_FALSE(parse_trajectory_csv(text, "a.csv", phantom_omni_limits(), &t));
  ASSERT_EQ(t.samples.size(), 3u);
  EXPECT_FALSE(t.has_orientation);
  EXPECT_EQ(t.samples[0].position_H, Vector3d(0.01, -0.02, 0.003));
  EXPECT_EQ(t.samples[1].t_s, 0.5);
  EXPECT_EQ(t.samples[1].buttons, 3u);
  EXPECT_EQ(t.samples[2].t_s, 1.0);
  EXPECT_EQ(t.samples[2].position_H.x(), 0.001);
}

TEST(TrajectoryCsv, ParsesOrientationAndNormalises) {
  Trajectory t;
  ASSERT_FALSE(parse_trajectory_csv("0,0,0,0,1,0,0,0,0\n0.001,0,0,0,0.7071,0.7071,0,0,1\n", "b.csv",
                                    phantom_omni_limits(), &t));
  ASSERT_EQ(t.samples.size(), 2u);
  EXPECT_TRUE(t.has_orientation);
  EXPECT_NEAR(t.samples[1].orientation_H.norm(), 1.0, 1e-15);
  EXPECT_NEAR(t.samples[1].orientation_H.x(), std::sqrt(0.5), 1e-12);
}

struct BadCase {
  const char* text;
  int line;
  const char* what;  // a piece of the message
};

TEST(TrajectoryCsv, RejectsBadRowsWithFileAndLine) {
  const BadCase cases[] = {
      {"0,0,0,0,0\n0.1,0,0,0\n", 2, "expected 5 fields"},
      {"0,0,0,0,0\n0.1,0,0,0,0,1,0,0,0,0,0\n", 2, "too many fields"},
      {"t_s,x,y,z,buttons\n0,0,0,0,0\n0.1,0,0,0,1,0,0,0,0\n", 3, "like the rows before"},
      {"0,0,abc,0,0\n", 1, "field y: not a finite number"},
      {"0,0,nan,0,0\n", 1, "field y: not a finite number"},
      {"0,inf,0,0,0\n", 1, "field x: not a finite number"},
      {"0,0,0,,0\n", 1, "field z"},
      {"0,0,0,0,0\n0.2,0,0,0,0\n0.2,0,0,0,0\n", 3, "not strictly increasing"},
      {"0,0,0,0,0\n-1,0,0,0,0\n", 2, "not strictly increasing"},
      {"# c\n0,0.5,0,0,0\n", 2, "outside the device workspace"},
      {"0,0,0,0.05,0\n", 1, "outside the device workspace"},
      {"0,0,0,0,1,1,0,0,0\n", 1, "not a unit quaternion"},
      {"0,0,0,0,-1\n", 1, "buttons"},
      {"0,0,0,0,1.5\n", 1, "buttons"},
      {"0,0,0,0,4294967296\n", 1, "buttons"},
      {"", 0, "no samples"},
      {"t_s,x,y,z,buttons\n# only a header\n", 2, "no samples"},
  };
  for (const BadCase& c : cases) {
    Trajectory t = sentinel();
    const auto err = parse_trajectory_csv(c.text, "bad.csv", phantom_omni_limits(), &t);
    ASSERT_TRUE(err.has_value()) << c.text;
    EXPECT_EQ(err->file, "bad.csv");
    EXPECT_EQ(err->line, c.line) << c.text << " -> " << err->to_string();
    EXPECT_NE(err->message.find(c.what), std::string::npos) << err->to_string();
    EXPECT_EQ(err->to_string().rfind("bad.csv:" + std::to_string(c.line) + ": ", 0), 0u);
    expect_untouched(t);
  }
}

TEST(TrajectoryCsv, LoadReportsMissingFileAndReadsRealFiles) {
  Trajectory t = sentinel();
  auto err = load_trajectory_csv("/nonexistent/dir/x.csv", phantom_omni_limits(), &t);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->line, 0);
  expect_untouched(t);

  const std::string path = testing::TempDir() + "traj_load_test.csv";
  {
    std::ofstream f(path);
    f << "t_s,x,y,z,buttons\n0,0,0,0,0\n0.1,0.01,0,0,1\n0.2,0.02,0,0.1,0\n";
  }
  err = load_trajectory_csv(path, phantom_omni_limits(), &t);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->to_string(), path + ":4: position outside the device workspace");
  expect_untouched(t);
  std::remove(path.c_str());
}

TEST(TrajectoryCsv, FormattedRowsParseBackToTheSameDoubles) {
  TrajectorySample s;
  s.t_s = 0.1 + 0.2;  // not exactly representable in short decimal
  s.position_H = Vector3d(1.0 / 30.0, -0.0123456789012345, 2e-17);
  s.orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized()));
  s.buttons = 3;
  char buf[256];
  for (bool with_q : {false, true}) {
    const std::size_t n = format_trajectory_row(s, with_q, buf, sizeof buf);
    ASSERT_GT(n, 0u);
    EXPECT_EQ(buf[n - 1], '\n');
    Trajectory t;
    const std::string text = std::string(trajectory_csv_header(with_q)) + "\n" + std::string(buf, n);
    ASSERT_FALSE(parse_trajectory_csv(text, "rt.csv", phantom_omni_limits(), &t));
    ASSERT_EQ(t.samples.size(), 1u);
    EXPECT_EQ(t.samples[0].t_s, s.t_s);
    EXPECT_EQ(t.samples[0].position_H, s.position_H);
    EXPECT_EQ(t.samples[0].buttons, 3u);
    if (with_q) {
      EXPECT_LT(t.samples[0].orientation_H.angularDistance(s.orientation_H), 1e-15);
    }
  }
  EXPECT_EQ(format_trajectory_row(s, true, buf, 20), 0u);  // too small: refused
}

}  // namespace
}  // namespace hemm::device
