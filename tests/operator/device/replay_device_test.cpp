#include "operator/device/replay_device.h"

#include <gtest/gtest.h>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

Trajectory two_segments() {
  Trajectory t;
  TrajectorySample a, b, c;
  a.t_s = 10.0;  // replay time is relative to the first sample
  a.ee[0].position_H = Vector3d(0, 0, 0);
  b.t_s = 10.004;
  b.ee[0].position_H = Vector3d(0.004, 0, 0);
  b.ee[0].orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Vector3d::UnitZ()));
  b.ee[0].handle.buttons = kButton1;
  c.t_s = 10.006;
  c.ee[0].position_H = Vector3d(0.004, 0.002, 0);
  c.ee[0].orientation_H = b.ee[0].orientation_H;
  t.samples = {a, b, c};
  t.has_orientation = true;
  return t;
}

TEST(ReplayDevice, InterpolatesAtServoRateAndRecordsForces) {
  ReplayDevice dev(two_segments(), phantom_omni_limits(), 0.001, 4);
  DeviceSample s;
  std::vector<DeviceSample> seen;
  for (int i = 0; i < 9; ++i) {
    dev.read(s);
    seen.push_back(s);
    dev.write(force_command(Vector3d(i, 0, 0)));
  }
  // t = 1 ms: a quarter along the first segment (1 m/s in x).
  EXPECT_NEAR(seen[1].ee[0].position_H.x(), 0.001, 1e-15);
  EXPECT_NEAR(seen[1].ee[0].velocity_H.x(), 1.0, 1e-9);
  EXPECT_NEAR(seen[2].ee[0].orientation_H.angularDistance(Eigen::Quaterniond::Identity()), 0.2, 1e-9);
  EXPECT_EQ(seen[3].ee[0].handle.buttons, 0u);
  EXPECT_EQ(seen[4].ee[0].handle.buttons, kButton1);  // at b
  EXPECT_NEAR(seen[5].ee[0].position_H.y(), 0.001, 1e-12);
  EXPECT_NEAR(seen[5].ee[0].velocity_H.y(), 1.0, 1e-9);
  EXPECT_EQ(seen[8].ee[0].position_H, Vector3d(0.004, 0.002, 0));  // held after the end
  EXPECT_EQ(seen[8].ee[0].velocity_H, Vector3d::Zero());
  EXPECT_EQ(seen[8].end_effectors, 1);
  EXPECT_TRUE(dev.finished());
  // Commands are recorded, not applied; beyond capacity they are counted.
  ASSERT_EQ(dev.commands_recorded(), 4u);
  EXPECT_EQ(dev.commands_dropped(), 5u);
  EXPECT_EQ(dev.command(2).command.ee[0].force_H, Vector3d(2, 0, 0));
  EXPECT_NEAR(dev.command(2).t_s, 0.002, 1e-15);
}

TEST(ReplayDevice, RejectsEmptyOrUnorderedTrajectories) {
  EXPECT_THROW(ReplayDevice(Trajectory{}, phantom_omni_limits()), std::invalid_argument);
  Trajectory t = two_segments();
  t.samples[2].t_s = t.samples[1].t_s;
  EXPECT_THROW(ReplayDevice(t, phantom_omni_limits()), std::invalid_argument);
  EXPECT_THROW(ReplayDevice(two_segments(), phantom_omni_limits(), 0.0), std::invalid_argument);
}

// A version 1 file (older recordings, no velocities) loads and replays as it
// always did: positions interpolated, velocity from the segment.
TEST(ReplayDevice, PlaysAVersion1FileAsBefore) {
  Trajectory t;
  const auto err = parse_trajectory_csv("t_s,x,y,z,qw,qx,qy,qz,buttons\n"
                                        "0,0,0,0,1,0,0,0,0\n"
                                        "0.002,0.004,0,0,1,0,0,0,2\n",
                                        "old.csv", phantom_omni_limits(), &t);
  ASSERT_FALSE(err) << err->to_string();
  ASSERT_FALSE(t.has_twist);
  ReplayDevice dev(t, phantom_omni_limits());
  DeviceSample s;
  dev.read(s);
  dev.write(DeviceCommand{});
  dev.read(s);
  EXPECT_NEAR(s.ee[0].position_H.x(), 0.002, 1e-15);
  EXPECT_NEAR(s.ee[0].velocity_H.x(), 2.0, 1e-12);  // 4 mm in 2 ms
  EXPECT_EQ(s.ee[0].handle.buttons, 0u);
  dev.write(DeviceCommand{});
  dev.read(s);
  EXPECT_EQ(s.ee[0].handle.buttons, kButton2);
}

// Two end-effectors with recorded twists: velocities are interpolated like
// positions (not differentiated), handles and enabled come from the sample at
// or before, and both wrenches are recorded.
TEST(ReplayDevice, ReplaysRecordedTwistsAndHandlesOfEveryEndEffector) {
  DeviceLimits lim;
  lim.end_effectors = 2;
  lim.ee = {phantom_omni_limits().ee[0], phantom_omni_limits().ee[0]};
  Trajectory t;
  t.end_effectors = 2;
  t.has_twist = true;
  TrajectorySample a, b;
  a.end_effectors = b.end_effectors = 2;
  a.t_s = 0.0;
  b.t_s = 0.004;
  a.ee[1].position_H = Vector3d(0.01, 0, 0);
  b.ee[1].position_H = Vector3d(0.01, 0.004, 0);  // the segment's mean speed is 1 m/s
  a.ee[1].velocity_H = Vector3d(0, 2.0, 0);       // the recorded ones differ from it
  b.ee[1].velocity_H = Vector3d(0, 0.0, 0);
  a.ee[0].angular_velocity_H = Vector3d(0, 0, 4.0);
  b.ee[0].angular_velocity_H = Vector3d(0, 0, -4.0);
  a.ee[1].handle.has_grip = true;
  a.ee[1].handle.grip_position = 0.01;
  b.ee[1].handle = a.ee[1].handle;
  b.ee[1].handle.grip_position = 0.02;
  b.ee[0].enabled = false;
  t.samples = {a, b};
  ReplayDevice dev(t, lim, 0.001, 16);
  DeviceSample s[6];
  for (int i = 0; i < 6; ++i) {
    dev.read(s[i]);
    DeviceCommand c = force_command(Vector3d(i, 0, 0), 0);
    c.ee[1].torque_H = Vector3d(0, 0, -i);
    dev.write(c);
  }
  EXPECT_EQ(s[1].end_effectors, 2);
  EXPECT_NEAR(s[1].ee[1].position_H.y(), 0.001, 1e-15);
  EXPECT_NEAR(s[1].ee[1].velocity_H.y(), 1.5, 1e-12);  // 2 + (0 - 2) / 4
  EXPECT_NEAR(s[3].ee[1].velocity_H.y(), 0.5, 1e-12);
  EXPECT_NEAR(s[2].ee[0].angular_velocity_H.z(), 0.0, 1e-12);
  EXPECT_EQ(s[3].ee[1].handle.grip_position, 0.01);  // from a until b
  EXPECT_TRUE(s[3].ee[0].enabled);
  EXPECT_EQ(s[4].ee[1].handle.grip_position, 0.02);
  EXPECT_FALSE(s[4].ee[0].enabled);
  EXPECT_EQ(s[5].ee[1].velocity_H, Vector3d::Zero());  // held after the end
  ASSERT_EQ(dev.commands_recorded(), 6u);
  EXPECT_EQ(dev.command(3).command.ee[0].force_H, Vector3d(3, 0, 0));
  EXPECT_EQ(dev.command(3).command.ee[1].torque_H, Vector3d(0, 0, -3));
}

TEST(ReplayDevice, RejectsATrajectoryForAnotherEndEffectorCount) {
  DeviceLimits two;
  two.end_effectors = 2;
  two.ee = {phantom_omni_limits().ee[0], phantom_omni_limits().ee[0]};
  EXPECT_THROW(ReplayDevice(two_segments(), two), std::invalid_argument);
  Trajectory t = two_segments();
  t.end_effectors = 2;
  EXPECT_THROW(ReplayDevice(t, two), std::invalid_argument);  // its samples have one
}

}  // namespace
}  // namespace hemm::device
