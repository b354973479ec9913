// Trajectory CSV parsing: good files in both version 1 layouts (older files)
// and in version 2 (several end-effectors, 6-DoF pose, twist, handle inputs);
// every kind of bad row or header is rejected with file:line and leaves the
// output untouched; formatted rows parse back to the same values.
#include "operator/device/trajectory_csv.h"
#include "tests/temp_dir.h"

#include <gtest/gtest.h>
#include <numbers>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

Trajectory sentinel() {
  Trajectory t;
  TrajectorySample s;
  s.t_s = 42.0;
  s.ee[0].handle.buttons = 7;
  t.samples.push_back(s);
  t.has_orientation = true;
  return t;
}

void expect_untouched(const Trajectory& t) {
  ASSERT_EQ(t.samples.size(), 1u);
  EXPECT_EQ(t.samples[0].t_s, 42.0);
  EXPECT_EQ(t.samples[0].ee[0].handle.buttons, 7u);
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
  EXPECT_FALSE(t.has_twist);  // version 1: the replay differentiates positions
  EXPECT_EQ(t.end_effectors, 1);
  EXPECT_EQ(t.samples[0].ee[0].position_H, Vector3d(0.01, -0.02, 0.003));
  EXPECT_EQ(t.samples[1].t_s, 0.5);
  EXPECT_EQ(t.samples[1].ee[0].handle.buttons, 3u);
  EXPECT_EQ(t.samples[2].t_s, 1.0);
  EXPECT_EQ(t.samples[2].ee[0].position_H.x(), 0.001);
}

TEST(TrajectoryCsv, ParsesOrientationAndNormalises) {
  Trajectory t;
  ASSERT_FALSE(parse_trajectory_csv("0,0,0,0,1,0,0,0,0\n0.001,0,0,0,0.7071,0.7071,0,0,1\n", "b.csv",
                                    phantom_omni_limits(), &t));
  ASSERT_EQ(t.samples.size(), 2u);
  EXPECT_TRUE(t.has_orientation);
  EXPECT_FALSE(t.has_twist);
  EXPECT_NEAR(t.samples[1].ee[0].orientation_H.norm(), 1.0, 1e-15);
  EXPECT_NEAR(t.samples[1].ee[0].orientation_H.x(), std::sqrt(0.5), 1e-12);
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

  const std::string path = hemm::test::make_temp_dir() + "/traj_load_test.csv";
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

// ---- version 2 ----

// The version 2 header for one end-effector, spelled out as the format documents it.
constexpr const char* kHeaderOneEe =
    "t_s,ee0_x,ee0_y,ee0_z,ee0_qw,ee0_qx,ee0_qy,ee0_qz,ee0_vx,ee0_vy,ee0_vz,ee0_wx,ee0_wy,ee0_wz,"
    "ee0_enabled,ee0_buttons,ee0_inputs,ee0_deadman,ee0_grip,ee0_grip_v,ee0_joy_x,ee0_joy_y,ee0_switch,"
    "ee0_attached";

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t c = s.find(',', start);
    out.push_back(s.substr(start, c == std::string::npos ? c : c - start));
    if (c == std::string::npos) return out;
    start = c + 1;
  }
}
std::string join(const std::vector<std::string>& f) {
  std::string s;
  for (std::size_t i = 0; i < f.size(); ++i) s += (i ? "," : "") + f[i];
  return s;
}

TEST(TrajectoryCsv, Version2HeaderIsTheDocumentedOne) {
  EXPECT_EQ(trajectory_csv_header(1), kHeaderOneEe);
  std::vector<std::string> cols = split(kHeaderOneEe);
  const std::size_t one = cols.size();
  ASSERT_EQ(one, 1u + kTrajectoryColumnsPerEndEffector);
  for (std::size_t i = 1; i < one; ++i) cols.push_back("ee1_" + cols[i].substr(4));
  EXPECT_EQ(trajectory_csv_header(2), join(cols));
}

// Two arms whose boxes overlap only around x = 0, so a position good for one
// can be outside the other.
DeviceLimits two_arms() {
  DeviceLimits d;
  d.end_effectors = 2;
  for (int k = 0; k < 2; ++k) {
    EndEffectorLimits& l = d.ee[static_cast<std::size_t>(k)];
    l = phantom_omni_limits().ee[0];
    l.workspace_min_H = Vector3d(k == 0 ? -0.6 : -0.1, -0.4, -0.4);
    l.workspace_max_H = Vector3d(k == 0 ? 0.1 : 0.6, 0.4, 0.4);
  }
  return d;
}

// Left arm: turned 90 deg about z, moving, joystick handle with dead-man.
// Right arm: at rest, disabled, grip handle with clutch, detached.
std::vector<std::string> good_row(const std::string& t) {
  return {t,
          "-0.3", "0.1", "0", "0.7071067811865476", "0", "0", "0.7071067811865476", "0.1", "0", "-0.2", "0",
          "0", "1.5", "1", "3", "5", "1", "0", "0", "0.25", "-1", "1", "1",
          "0.3", "-0.1", "0.05", "1", "0", "0", "0", "0", "0", "0", "0", "0", "0", "0", "0", "10", "0",
          "0.012", "-0.05", "0", "0", "0", "0"};
}

TEST(TrajectoryCsv, ParsesVersion2WithTwoEndEffectorsAndTheirHandles) {
  const std::string text = trajectory_csv_header(2) + "\n# comment\n" + join(good_row("0")) + "\r\n" +
                           join(good_row("0.001")) + "\n";
  Trajectory t;
  const auto err = parse_trajectory_csv(text, "v2.csv", two_arms(), &t);
  ASSERT_FALSE(err) << err->to_string();
  ASSERT_EQ(t.samples.size(), 2u);
  EXPECT_EQ(t.end_effectors, 2);
  EXPECT_TRUE(t.has_orientation);
  EXPECT_TRUE(t.has_twist);
  const TrajectorySample& s = t.samples[1];
  EXPECT_EQ(s.t_s, 0.001);
  EXPECT_EQ(s.end_effectors, 2);
  const EndEffectorSample& l = s.ee[0];
  EXPECT_EQ(l.position_H, Vector3d(-0.3, 0.1, 0));
  EXPECT_NEAR(l.orientation_H.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Vector3d::UnitZ()))),
              0.0, 1e-12);
  EXPECT_EQ(l.velocity_H, Vector3d(0.1, 0, -0.2));
  EXPECT_EQ(l.angular_velocity_H, Vector3d(0, 0, 1.5));
  EXPECT_TRUE(l.enabled);
  EXPECT_EQ(l.handle.buttons, kButton1 | kButton2);
  EXPECT_TRUE(l.handle.has_deadman);
  EXPECT_TRUE(l.handle.deadman);
  EXPECT_TRUE(l.handle.has_joystick);
  EXPECT_EQ(l.handle.joystick, Eigen::Vector2d(0.25, -1));
  EXPECT_TRUE(l.handle.switch_on);
  EXPECT_FALSE(l.handle.has_grip);
  EXPECT_FALSE(l.handle.has_clutch);
  EXPECT_TRUE(l.handle.attached);
  const EndEffectorSample& r = s.ee[1];
  EXPECT_EQ(r.position_H, Vector3d(0.3, -0.1, 0.05));
  EXPECT_EQ(r.orientation_H.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_FALSE(r.enabled);
  EXPECT_EQ(handle_input_bits(r.handle), kHasGrip | kHasClutch);
  EXPECT_EQ(r.handle.grip_position, 0.012);
  EXPECT_EQ(r.handle.grip_velocity, -0.05);
  EXPECT_FALSE(r.handle.attached);
  EXPECT_FALSE(r.handle.deadman);
}

TEST(TrajectoryCsv, RejectsBadVersion2RowsWithFileAndLine) {
  const std::string header = trajectory_csv_header(2);
  const std::vector<std::string> cols = split(header);
  struct Bad {
    const char* column;
    const char* value;
    const char* what;
  };
  const Bad cases[] = {
      {"ee0_x", "0.3", "ee0: position outside the device workspace"},  // inside ee1's box, not ee0's
      {"ee1_x", "-0.3", "ee1: position outside the device workspace"},
      {"ee0_qw", "0.9", "ee0: orientation is not a unit quaternion"},
      {"ee0_vy", "nan", "field ee0_vy: not a finite number"},
      {"ee1_wz", "inf", "field ee1_wz: not a finite number"},
      {"ee1_z", "", "field ee1_z: not a finite number"},
      {"ee0_enabled", "2", "field ee0_enabled: not 0 or 1"},
      {"ee1_attached", "yes", "field ee1_attached: not 0 or 1"},
      {"ee0_buttons", "-1", "field ee0_buttons: not an unsigned 32-bit integer"},
      {"ee1_inputs", "16", "field ee1_inputs: not a set of input bits"},
      {"ee0_joy_x", "1.5", "field ee0_joy_x: joystick axis outside [-1, 1]"},
      {"ee0_grip", "0.01", "field ee0_grip: the handle has no grip"},
      {"ee1_deadman", "1", "field ee1_deadman: the handle has no dead-man"},
      {"ee1_switch", "1", "field ee1_switch: the handle has no joystick"},
      {"ee1_joy_y", "0.5", "field ee1_joy_y: the handle has no joystick"},
      {"ee0_attached", "0", "field ee0_attached: the handle has no clutch"},
      {"t_s", "0", "time not strictly increasing"},
      {"t_s", "x", "field t_s: not a finite number"},
  };
  for (const Bad& c : cases) {
    std::vector<std::string> row = good_row("0.001");
    const auto it = std::find(cols.begin(), cols.end(), c.column);
    ASSERT_NE(it, cols.end()) << c.column;
    row[static_cast<std::size_t>(it - cols.begin())] = c.value;
    const std::string text = header + "\n" + join(good_row("0")) + "\n" + join(row) + "\n";
    Trajectory t = sentinel();
    const auto err = parse_trajectory_csv(text, "bad2.csv", two_arms(), &t);
    ASSERT_TRUE(err.has_value()) << c.column;
    EXPECT_EQ(err->line, 3) << err->to_string();
    EXPECT_NE(err->message.find(c.what), std::string::npos) << err->to_string();
    EXPECT_EQ(err->to_string().rfind("bad2.csv:3: ", 0), 0u);
    expect_untouched(t);
  }
  // Field counts, and files that do not fit the device.
  const std::string one_row = join(good_row("0"));
  const std::string v1 = "t_s,x,y,z,buttons\n0,0,0,0,0\n";
  struct Whole {
    std::string text;
    DeviceLimits limits;
    int line;
    std::string what;
  };
  const Whole files[] = {
      {header + "\n" + one_row + ",0\n", two_arms(), 2, "too many fields (expected 47)"},
      {header + "\n" + one_row.substr(0, one_row.rfind(',')) + "\n", two_arms(), 2,
       "expected 47 fields as in the header, got 46"},
      {header + "\n" + one_row + "\n", phantom_omni_limits(), 1, "the file has 2 end-effector(s), the device 1"},
      {trajectory_csv_header(1) + "\n", two_arms(), 1, "the file has 1 end-effector(s), the device 2"},
      {"# c\nt_s,ee0_x,ee0_y\n" + one_row + "\n", two_arms(), 2, "not a trajectory header"},
      {header + "," + "ee2_x\n" + one_row + "\n", two_arms(), 1, "not a trajectory header"},
      {v1, two_arms(), 1, "a version 1 file has one end-effector, the device 2"},
      {header + "\n", two_arms(), 1, "no samples"},
  };
  for (const Whole& w : files) {
    Trajectory t = sentinel();
    const auto err = parse_trajectory_csv(w.text, "bad2.csv", w.limits, &t);
    ASSERT_TRUE(err.has_value()) << w.text;
    EXPECT_EQ(err->line, w.line) << err->to_string();
    EXPECT_NE(err->message.find(w.what), std::string::npos) << err->to_string();
    expect_untouched(t);
  }
}

TEST(TrajectoryCsv, FormattedRowsParseBackToTheSameDoubles) {
  TrajectorySample s;
  s.t_s = 0.1 + 0.2;  // not exactly representable in short decimal
  s.end_effectors = 2;
  EndEffectorSample& a = s.ee[0];
  a.position_H = Vector3d(1.0 / 30.0, -0.0123456789012345, 2e-17);
  a.orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized()));
  a.velocity_H = Vector3d(-1.0 / 7.0, 1e-300, 0.25);
  a.angular_velocity_H = Vector3d(3.0 / 11.0, -0.0, 5e-9);
  a.handle.buttons = 3;
  a.handle.has_joystick = true;
  a.handle.joystick = Eigen::Vector2d(-1.0 / 3.0, 1.0);
  a.handle.switch_on = true;
  a.handle.has_deadman = true;
  a.handle.deadman = true;
  EndEffectorSample& b = s.ee[1];
  b.position_H = Vector3d(0.2, 0.1 / 3.0, -0.3);
  b.orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(-2.0, Vector3d(0, 1, 1).normalized()));
  b.enabled = false;
  b.handle.has_grip = true;
  b.handle.grip_position = 0.0123 / 7.0;
  b.handle.grip_velocity = -0.5 / 3.0;
  b.handle.has_clutch = true;
  b.handle.attached = false;
  b.handle.joystick = Eigen::Vector2d(0.5, 0.5);  // no joystick: written as the default
  char buf[kTrajectoryRowMax];
  const std::size_t n = format_trajectory_row(s, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  EXPECT_EQ(buf[n - 1], '\n');
  Trajectory t;
  const std::string text = trajectory_csv_header(2) + "\n" + std::string(buf, n);
  const auto err = parse_trajectory_csv(text, "rt.csv", two_arms(), &t);
  ASSERT_FALSE(err) << err->to_string();
  ASSERT_EQ(t.samples.size(), 1u);
  const TrajectorySample& r = t.samples[0];
  EXPECT_EQ(r.t_s, s.t_s);
  for (std::size_t k = 0; k < 2; ++k) {
    const EndEffectorSample& e = r.ee[k];
    const EndEffectorSample& w = s.ee[k];
    EXPECT_EQ(e.position_H, w.position_H) << k;
    EXPECT_EQ(e.orientation_H.coeffs(), w.orientation_H.coeffs()) << k;  // bit for bit
    EXPECT_EQ(e.velocity_H, w.velocity_H) << k;
    EXPECT_EQ(e.angular_velocity_H, w.angular_velocity_H) << k;
    EXPECT_EQ(e.enabled, w.enabled) << k;
    EXPECT_EQ(e.handle.buttons, w.handle.buttons) << k;
    EXPECT_EQ(handle_input_bits(e.handle), handle_input_bits(w.handle)) << k;
    EXPECT_EQ(e.handle.deadman, w.handle.deadman) << k;
    EXPECT_EQ(e.handle.grip_position, w.handle.grip_position) << k;
    EXPECT_EQ(e.handle.grip_velocity, w.handle.grip_velocity) << k;
    EXPECT_EQ(e.handle.switch_on, w.handle.switch_on) << k;
    EXPECT_EQ(e.handle.attached, w.handle.attached) << k;
  }
  EXPECT_EQ(r.ee[0].handle.joystick, a.handle.joystick);
  EXPECT_EQ(r.ee[1].handle.joystick, Eigen::Vector2d::Zero());
  EXPECT_EQ(format_trajectory_row(s, buf, 20), 0u);  // too small: refused
  s.end_effectors = 0;
  EXPECT_EQ(format_trajectory_row(s, buf, sizeof buf), 0u);
}

}  // namespace
}  // namespace hemm::device
