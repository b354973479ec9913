// The device layer's command checks: non-finite wrenches become zero (and are
// counted), peaks clamp keeping direction, force-only end-effectors lose
// their torque; limits are validated.
#include "operator/device/haptic_device.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hemm::device {
namespace {

using Eigen::Vector3d;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

EndEffectorLimits arm_limits() {
  EndEffectorLimits l = phantom_omni_limits().ee[0];
  l.peak_force = 30.0;
  l.max_continuous_force = 20.0;
  l.renders_torque = true;
  l.peak_torque = 2.0;
  l.max_rotational_stiffness = 50.0;
  l.peak_grip_force = 4.0;
  return l;
}

TEST(DeviceCommand, NonFiniteWrenchOfOneEndEffectorBecomesZeroAndIsCounted) {
  DeviceCommand c;
  c.ee[0].force_H = Vector3d(1, 2, 3);
  c.ee[0].torque_H = Vector3d(0.1, 0, 0);
  c.ee[0].grip_force = 0.5;
  c.ee[1].force_H = Vector3d(4, 5, 6);
  c.ee[1].torque_H = Vector3d(0, kNaN, 0);
  c.ee[1].grip_force = 0.7;
  EXPECT_TRUE(wrench_is_finite(c.ee[0]));
  EXPECT_FALSE(wrench_is_finite(c.ee[1]));
  EXPECT_EQ(zero_nonfinite_wrenches(c, 2), 1);
  EXPECT_EQ(c.ee[0].force_H, Vector3d(1, 2, 3));  // the good one is untouched
  EXPECT_EQ(c.ee[0].grip_force, 0.5);
  EXPECT_EQ(c.ee[1].force_H, Vector3d::Zero());
  EXPECT_EQ(c.ee[1].torque_H, Vector3d::Zero());
  EXPECT_EQ(c.ee[1].grip_force, 0.0);
  // Each entry alone makes the wrench non-finite.
  for (int i = 0; i < 7; ++i) {
    EndEffectorCommand e;
    if (i < 3) e.force_H[i] = kInf;
    else if (i < 6) e.torque_H[i - 3] = -kInf;
    else e.grip_force = kNaN;
    EXPECT_FALSE(wrench_is_finite(e)) << i;
  }
  // End-effectors beyond the count are not looked at.
  DeviceCommand d;
  d.ee[1].force_H.x() = kNaN;
  EXPECT_EQ(zero_nonfinite_wrenches(d, 1), 0);
  EXPECT_TRUE(std::isnan(d.ee[1].force_H.x()));
}

TEST(DeviceCommand, ClampToPeakKeepsDirectionAndDropsTorqueOfForceOnlyDevices) {
  const EndEffectorLimits arm = arm_limits();
  EndEffectorCommand c;
  c.force_H = Vector3d(30, 40, 0);  // |F| = 50 N
  c.torque_H = Vector3d(0, 0, -3);  // |T| = 3 N m
  c.grip_force = 9.0;
  clamp_to_peak(c, arm);
  EXPECT_NEAR(c.force_H.x(), 0.6 * 30.0, 1e-12);
  EXPECT_NEAR(c.force_H.y(), 0.8 * 30.0, 1e-12);
  EXPECT_EQ(c.force_H.z(), 0.0);
  EXPECT_NEAR(c.torque_H.z(), -2.0, 1e-12);
  EXPECT_EQ(c.grip_force, 4.0);
  // Below the peaks nothing changes; a negative grip force (pulling the
  // finger) is not something the interface can do.
  EndEffectorCommand small;
  small.force_H = Vector3d(1, -2, 3);
  small.torque_H = Vector3d(0.5, 0.5, 0.5);
  small.grip_force = -1.0;
  const EndEffectorCommand before = small;
  clamp_to_peak(small, arm);
  EXPECT_EQ(small.force_H, before.force_H);
  EXPECT_EQ(small.torque_H, before.torque_H);
  EXPECT_EQ(small.grip_force, 0.0);
  // The Omni renders no torque and no grip force.
  EndEffectorCommand omni = before;
  omni.grip_force = 2.0;
  clamp_to_peak(omni, phantom_omni_limits().ee[0]);
  EXPECT_EQ(omni.torque_H, Vector3d::Zero());
  EXPECT_EQ(omni.grip_force, 0.0);
  EXPECT_NEAR(omni.force_H.norm(), 3.3, 1e-12);  // sqrt(14) N > 3.3 N peak
}

TEST(DeviceLimitsCheck, AcceptsTheOmniAndRejectsNonsense) {
  EXPECT_EQ(check_limits(phantom_omni_limits()), nullptr);
  DeviceLimits two;
  two.end_effectors = 2;
  two.ee = {arm_limits(), arm_limits()};
  EXPECT_EQ(check_limits(two), nullptr);

  DeviceLimits d = two;
  d.end_effectors = 0;
  EXPECT_NE(check_limits(d), nullptr);
  d.end_effectors = kMaxEndEffectors + 1;
  EXPECT_NE(check_limits(d), nullptr);
  d = two;
  d.ee[1].workspace_min_H.x() = d.ee[1].workspace_max_H.x();  // empty box on the second arm
  EXPECT_NE(check_limits(d), nullptr);
  EXPECT_EQ(check_limits(d.ee[0]), nullptr);
  d.end_effectors = 1;  // the second is not part of the device any more
  EXPECT_EQ(check_limits(d), nullptr);

  auto bad = [](auto mutate) {
    EndEffectorLimits l = arm_limits();
    mutate(l);
    return check_limits(l) != nullptr;
  };
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.max_continuous_force = 31.0; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.peak_force = kNaN; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.max_stiffness = 0.0; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.peak_torque = 0.0; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.max_rotational_stiffness = -1.0; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.peak_grip_force = kInf; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.max_linear_speed = -0.1; }));
  EXPECT_TRUE(bad([](EndEffectorLimits& l) { l.workspace_max_H.z() = kInf; }));
  EXPECT_FALSE(bad([](EndEffectorLimits& l) {  // force only: torque limits may be 0
    l.renders_torque = false;
    l.peak_torque = 0.0;
    l.max_rotational_stiffness = 0.0;
  }));
}

TEST(HandleInputs, InputBitsNameWhatTheHandleHas) {
  HandleInputs h;
  EXPECT_EQ(handle_input_bits(h), 0u);
  h.has_grip = true;
  h.has_clutch = true;
  EXPECT_EQ(handle_input_bits(h), kHasGrip | kHasClutch);
  h.has_deadman = h.has_joystick = true;
  EXPECT_EQ(handle_input_bits(h), kAllHandleInputs);
  EXPECT_EQ(kAllHandleInputs, 15u);
}

TEST(DeviceCommand, ForceCommandPutsTheForceOnOneEndEffectorOnly) {
  const DeviceCommand c = force_command(Vector3d(1, 2, 3), 1);
  EXPECT_EQ(c.ee[0].force_H, Vector3d::Zero());
  EXPECT_EQ(c.ee[1].force_H, Vector3d(1, 2, 3));
  EXPECT_EQ(c.ee[1].torque_H, Vector3d::Zero());
  EXPECT_EQ(c.ee[1].grip_force, 0.0);
}

}  // namespace
}  // namespace hemm::device
