#include "operator/device/replay_device.h"

#include <gtest/gtest.h>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

Trajectory two_segments() {
  Trajectory t;
  TrajectorySample a, b, c;
  a.t_s = 10.0;  // replay time is relative to the first sample
  a.position_H = Vector3d(0, 0, 0);
  b.t_s = 10.004;
  b.position_H = Vector3d(0.004, 0, 0);
  b.orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Vector3d::UnitZ()));
  b.buttons = kButton1;
  c.t_s = 10.006;
  c.position_H = Vector3d(0.004, 0.002, 0);
  c.orientation_H = b.orientation_H;
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
    dev.write(Vector3d(i, 0, 0));
  }
  // t = 1 ms: a quarter along the first segment (1 m/s in x).
  EXPECT_NEAR(seen[1].position_H.x(), 0.001, 1e-15);
  EXPECT_NEAR(seen[1].velocity_H.x(), 1.0, 1e-9);
  EXPECT_NEAR(seen[2].orientation_H.angularDistance(Eigen::Quaterniond::Identity()), 0.2, 1e-9);
  EXPECT_EQ(seen[3].buttons, 0u);
  EXPECT_EQ(seen[4].buttons, kButton1);  // at b
  EXPECT_NEAR(seen[5].position_H.y(), 0.001, 1e-12);
  EXPECT_NEAR(seen[5].velocity_H.y(), 1.0, 1e-9);
  EXPECT_EQ(seen[8].position_H, Vector3d(0.004, 0.002, 0));  // held after the end
  EXPECT_EQ(seen[8].velocity_H, Vector3d::Zero());
  EXPECT_TRUE(dev.finished());
  // Forces are recorded, not applied; beyond capacity they are counted.
  ASSERT_EQ(dev.forces_recorded(), 4u);
  EXPECT_EQ(dev.forces_dropped(), 5u);
  EXPECT_EQ(dev.force(2).force_H, Vector3d(2, 0, 0));
  EXPECT_NEAR(dev.force(2).t_s, 0.002, 1e-15);
}

TEST(ReplayDevice, RejectsEmptyOrUnorderedTrajectories) {
  EXPECT_THROW(ReplayDevice(Trajectory{}, phantom_omni_limits()), std::invalid_argument);
  Trajectory t = two_segments();
  t.samples[2].t_s = t.samples[1].t_s;
  EXPECT_THROW(ReplayDevice(t, phantom_omni_limits()), std::invalid_argument);
  EXPECT_THROW(ReplayDevice(two_segments(), phantom_omni_limits(), 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace hemm::device
