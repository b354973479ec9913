// The base and arm controllers as pure functions, against closed forms (the
// safety pieces: watchdog_test, collision_guard_test, arm_keep_out_test,
// seen_voxels_test).
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/arm_control.h"
#include "robot_side/control/base_control.h"

namespace hr = hemm::robot;

TEST(BaseSlew, RampsAtTheAccelerationLimitAndClampsSpeed) {
  const hr::BaseLimits l{0.7, 2.0, 1.0, 4.0};
  hr::BaseSetpoint s;
  int steps = 0;
  while (s.v < 0.7 && steps < 10000) {
    s = hr::slew_setpoint(l, s, 5.0, 0.0, 0.001);  // asks for more than the limit
    ++steps;
  }
  EXPECT_NEAR(steps, 700, 1);  // 0.7 m/s at 1 m/s^2
  EXPECT_DOUBLE_EQ(s.v, 0.7);
  s = hr::slew_setpoint(l, s, std::nan(""), 1e9, 0.001);  // NaN counts as 0
  EXPECT_NEAR(s.v, 0.699, 1e-12);
  EXPECT_NEAR(s.omega, 0.004, 1e-12);
}

TEST(SkidSteer, WheelSpeedsAndBodyMotionAreInverses) {
  const hr::SkidSteerGeometry g;
  const hr::BaseSetpoint b{0.3, -0.8};
  const hr::WheelSpeeds w = hr::wheel_speeds(g, b);
  EXPECT_NEAR(w.right - w.left, b.omega * g.track_width * g.slip_factor, 1e-12);
  const hr::BaseSetpoint b2 = hr::body_motion(g, w);
  EXPECT_NEAR(b2.v, b.v, 1e-12);
  EXPECT_NEAR(b2.omega, b.omega, 1e-12);
}

TEST(Odometry, ConstantWheelSpeedsTraceTheClosedFormArc) {
  const hr::SkidSteerGeometry g;
  const hr::BaseSetpoint b{0.4, 0.5};
  const hr::WheelSpeeds w = hr::wheel_speeds(g, b);
  hr::Odometry o;
  const double T = 2.0;
  for (int k = 0; k < 2000; ++k) hr::integrate_odometry(g, w, 0.001, o);
  // Arc of radius v/omega (the chord update is exact for constant speeds).
  const double R = b.v / b.omega, th = b.omega * T;
  EXPECT_NEAR(o.x, R * std::sin(th), 1e-9);
  EXPECT_NEAR(o.y, R * (1 - std::cos(th)), 1e-9);
  EXPECT_NEAR(o.theta, th, 1e-12);
  EXPECT_NEAR(hemm::math::wrap_angle(3 * std::numbers::pi), std::numbers::pi, 1e-12);
}

TEST(ArmControl, ReferenceIsRateLimitedAndTorqueClamped) {
  const hemm::kinematics::Arm5Model m;
  hr::ArmControlParams p;
  hr::ArmControlState s;
  hr::reset_arm(s, hr::Arm5Vector::Zero());
  EXPECT_TRUE(hr::set_arm_goal(m, s, hr::Arm5Vector::Constant(5.0)));  // beyond the limits: clamped
  EXPECT_TRUE(hemm::kinematics::within_limits(m, s.q_goal));
  bool sat = false;
  const hr::Arm5Vector tau =
      hr::arm_control_step(p, s, hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), 0.001, &sat);
  EXPECT_NEAR(s.q_ref(0), p.max_joint_speed * 0.001, 1e-15);
  EXPECT_LE(tau.cwiseAbs().maxCoeff(), p.max_joint_torque);
  // Gravity bias alone passes through (no error, no motion).
  hr::reset_arm(s, hr::Arm5Vector::Zero());
  const hr::Arm5Vector bias = (hr::Arm5Vector() << 0, 1.0, -0.5, 0, 0.1).finished();
  const hr::Arm5Vector t2 = hr::arm_control_step(p, s, hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), bias, 0.001, &sat);
  EXPECT_LT((t2 - bias).norm(), 1e-12);
  EXPECT_FALSE(sat);
}
