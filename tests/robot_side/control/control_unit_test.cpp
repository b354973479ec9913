// Controllers and safety as pure functions, against closed forms.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/arm_control.h"
#include "robot_side/control/base_control.h"
#include "robot_side/control/safety.h"

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
  EXPECT_NEAR(hr::wrap_angle(3 * M_PI), M_PI, 1e-12);
}

TEST(Watchdog, ExpiresAfterTheTimeout) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  EXPECT_TRUE(hr::watchdog_expired(w, 0));  // nothing received yet
  hr::watchdog_feed(w, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'250'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'250'000'001));
}

TEST(Watchdog, CountsFromTheCommandsSendTimeAndNeverFromTheFuture) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  // Arrived at t = 1 s but sent (as the fastest command would have been) 150 ms earlier: 100 ms left.
  hr::watchdog_feed(w, 850'000'000, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'100'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'100'000'001));
  // Held longer than the timeout: expired on arrival.
  hr::watchdog_feed(w, 600'000'000, 1'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 1'000'000'000));
  // A send time after now (a clock estimate off) counts as now, not later.
  hr::watchdog_feed(w, 5'000'000'000, 2'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 2'250'000'001));
}

TEST(CollisionGuard, StoppingDistanceFitsTheFreeRange) {
  const double a = 1.0, tr = 0.05;
  for (double d : {0.01, 0.1, 0.5, 2.0}) {
    const double v = hr::stoppable_speed(d, a, tr);
    EXPECT_NEAR(v * tr + v * v / (2 * a), d, 1e-12);
  }
  EXPECT_EQ(hr::stoppable_speed(-0.1, a, tr), 0.0);
  hr::CollisionGuardParams p;
  p.margin = 0.15;
  const std::vector<Eigen::Vector2d> pts = {
      {1.0, 0.1},   // ahead in the corridor
      {0.6, 0.4},   // ahead but outside the corridor: ignored
      {0.0, 0.2},   // beside the robot: ignored
      {-0.9, -0.2}  // behind
  };
  const hr::GuardLimit g = hr::collision_guard(p, pts);
  EXPECT_NEAR(g.free_ahead, 1.0 - p.front_x, 1e-12);
  EXPECT_NEAR(g.free_behind, 0.9 + p.rear_x, 1e-12);
  EXPECT_NEAR(g.max_forward, hr::stoppable_speed(1.0 - p.front_x - p.margin, p.max_decel, p.reaction_time), 1e-12);
  const hr::GuardLimit none = hr::collision_guard(p, {});
  EXPECT_TRUE(std::isinf(none.max_forward));
  // An obstacle inside the margin: no forward motion at all.
  const std::vector<Eigen::Vector2d> close = {{p.front_x + 0.1, 0.0}};
  EXPECT_EQ(hr::collision_guard(p, close).max_forward, 0.0);
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
