// SimulatedOmni against closed forms: spring-damper step response, static
// displacement F/k_hand, the peak clamp, the thermal (continuous) limiter,
// and the end stops.
#include "operator/device/simulated_omni.h"

#include <gtest/gtest.h>
#include <numbers>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

HandTarget target_at(const Vector3d& p) {
  HandTarget t;
  t.position_H = p;
  return t;
}

TEST(SimulatedOmni, FreeHandFollowsStepTargetLikeTheClosedFormSpringDamper) {
  const SimulatedOmniModel m;
  SimulatedOmniData d;  // at rest at the origin
  const double A = 0.02;
  const double k = m.hand_stiffness, mass = m.total_mass(), b = m.hand_damping + m.device_damping;
  const double wn = std::sqrt(k / mass), zeta = b / (2.0 * std::sqrt(k * mass));
  ASSERT_LT(zeta, 1.0);  // the default hand is underdamped
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  double max_err = 0.0, overshoot = 0.0;
  for (int i = 1; i <= 2000; ++i) {
    simulated_omni_step(m, d, target_at(Vector3d(A, 0, 0)), Vector3d::Zero());
    const double t = i * m.dt_s;
    const double x = A * (1.0 - std::exp(-zeta * wn * t) *
                                    (std::cos(wd * t) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(wd * t)));
    max_err = std::max(max_err, std::abs(d.position_H.x() - x));
    overshoot = std::max(overshoot, d.position_H.x() - A);
    EXPECT_EQ(d.position_H.y(), 0.0);
    EXPECT_EQ(d.position_H.z(), 0.0);
  }
  // Semi-implicit Euler with 8 sub-steps: O(h) error (0.11 % of A measured).
  EXPECT_LT(max_err, 0.003 * A);
  // Overshoot of an underdamped second-order system: exp(-pi zeta / sqrt(1 - zeta^2)).
  EXPECT_NEAR(overshoot / A, std::exp(-std::numbers::pi * zeta / std::sqrt(1 - zeta * zeta)), 0.002);
  EXPECT_NEAR(d.position_H.x(), A, 1e-6 * A);
  EXPECT_NEAR(d.t_s, 2.0, 1e-9);
}

TEST(SimulatedOmni, ConstantForceDisplacesHandByForceOverHandStiffness) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<HoldScript>(Vector3d(0.01, -0.02, 0.005));
  SimulatedOmni omni(m, script);
  const Vector3d f(0.3, -0.2, 0.4);  // |f| = 0.54 N: under the continuous limit
  ASSERT_LT(f.norm(), m.limits.max_continuous_force);
  for (int i = 0; i < 5000; ++i) omni.write(force_command(f));
  const Vector3d expected = Vector3d(0.01, -0.02, 0.005) + f / m.hand_stiffness;
  EXPECT_LT((omni.data().position_H - expected).norm(), 1e-7);
  EXPECT_LT(omni.data().velocity_H.norm(), 1e-6);
  EXPECT_EQ(omni.data().applied_force_H, f);
  DeviceSample s;
  omni.read(s);
  EXPECT_EQ(s.ee[0].position_H, omni.data().position_H);
  EXPECT_EQ(s.ee[0].velocity_H, omni.data().velocity_H);
}

TEST(SimulatedOmni, ForceIsClampedToPeakKeepingItsDirection) {
  const SimulatedOmniModel m;
  SimulatedOmniData d;
  const Vector3d f = limit_force(m, d, Vector3d(6.0, 8.0, 0.0));
  EXPECT_NEAR(f.norm(), m.limits.peak_force, 1e-12);
  EXPECT_NEAR(f.x(), 0.6 * m.limits.peak_force, 1e-12);
  EXPECT_NEAR(f.y(), 0.8 * m.limits.peak_force, 1e-12);
  EXPECT_EQ(f.z(), 0.0);
}

TEST(SimulatedOmni, ContinuousLimiterCutsSustainedForceToContinuousRating) {
  const SimulatedOmniModel m;
  SimulatedOmniData d;
  const double fp = m.limits.peak_force, fc = m.limits.max_continuous_force;
  const double a = std::exp(-m.dt_s / m.thermal_time_constant_s);
  // Full-peak steps allowed from cold: largest n with Fp^2 (1 - a^n) <= Fc^2.
  const int n_full = static_cast<int>(std::floor(std::log(1.0 - fc * fc / (fp * fp)) / std::log(a)));
  const Vector3d demand(0, 0, fp);
  int full = 0;
  bool first_cut_seen = false;
  for (int i = 0; i < 3000; ++i) {
    const Vector3d f = limit_force(m, d, demand);
    if (std::abs(f.norm() - fp) < 1e-12) {
      EXPECT_FALSE(first_cut_seen) << "full force again at step " << i;
      ++full;
    } else {
      first_cut_seen = true;
    }
  }
  EXPECT_NEAR(full, n_full, 1);
  // Sustained: exactly the continuous rating, same direction.
  for (int i = 0; i < 2000; ++i) {
    const Vector3d f = limit_force(m, d, demand);
    EXPECT_NEAR(f.z(), fc, 1e-9);
    EXPECT_EQ(f.x(), 0.0);
  }
  // A demand below the rating passes untouched even when warm.
  EXPECT_EQ(limit_force(m, d, Vector3d(0.5, 0, 0)), Vector3d(0.5, 0, 0));
  // After a long rest the peak is available again.
  for (int i = 0; i < 60000; ++i) limit_force(m, d, Vector3d::Zero());
  EXPECT_NEAR(limit_force(m, d, demand).norm(), fp, 1e-12);
}

TEST(SimulatedOmni, EndStopsHoldTheHandAtTheWorkspaceBoundary) {
  const SimulatedOmniModel m;
  // The hand pulls towards a point far outside +x and -y; the stops push back.
  const Vector3d target(0.20, -0.30, 0.0);
  auto script = std::make_shared<LineScript>(Vector3d::Zero(), target, 0.5);
  SimulatedOmni omni(m, script);
  double max_x = -1, min_y = 1;
  for (int i = 0; i < 4000; ++i) {
    omni.write(DeviceCommand{});
    max_x = std::max(max_x, omni.data().position_H.x());
    min_y = std::min(min_y, omni.data().position_H.y());
  }
  const double ks = m.end_stop_stiffness, kh = m.hand_stiffness;
  const Vector3d& hi = m.limits.workspace_max_H;
  const Vector3d& lo = m.limits.workspace_min_H;
  // Static balance of hand spring and stop spring.
  EXPECT_NEAR(omni.data().position_H.x(), (kh * target.x() + ks * hi.x()) / (kh + ks), 1e-7);
  EXPECT_NEAR(omni.data().position_H.y(), (kh * target.y() + ks * lo.y()) / (kh + ks), 1e-7);
  EXPECT_NEAR(omni.data().position_H.z(), 0.0, 1e-12);
  // While moving in, the stops gave by at most a few millimetres.
  EXPECT_LT(max_x, hi.x() + 0.004);
  EXPECT_GT(min_y, lo.y() - 0.004);
}

TEST(SimulatedOmni, RenderedForcePushesAgainstEndStopOnlyFromInside) {
  const SimulatedOmniModel m;
  // Hand at the centre, device pushed out along -z by 0.8 N: F/k = 4 mm, inside.
  auto script = std::make_shared<HoldScript>(Vector3d::Zero());
  SimulatedOmni omni(m, script);
  for (int i = 0; i < 3000; ++i) omni.write(force_command(Vector3d(0, 0, -0.8)));
  EXPECT_NEAR(omni.data().position_H.z(), -0.8 / m.hand_stiffness, 1e-7);
}

TEST(SimulatedOmni, NonFiniteForceIsTreatedAsZeroAndCounted) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<HoldScript>(Vector3d(0.01, 0, 0));
  SimulatedOmni omni(m, script);
  omni.write(force_command(Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0)));
  omni.write(force_command(Vector3d(0, std::numeric_limits<double>::infinity(), 0)));
  EXPECT_EQ(omni.data().nonfinite_commands, 2u);
  EXPECT_EQ(omni.data().applied_force_H, Vector3d::Zero());
  EXPECT_TRUE(omni.data().position_H.allFinite());
  EXPECT_TRUE(std::isfinite(omni.data().mean_square_force));
}

TEST(SimulatedOmni, IsOneForceOnlyEndEffectorWithButtonsAndADeadMan) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<HoldScript>(Vector3d(0.01, 0.02, -0.01), kButton2);
  SimulatedOmni omni(m, script);
  ASSERT_EQ(omni.limits().end_effectors, 1);
  EXPECT_FALSE(omni.limits().ee[0].renders_torque);
  EXPECT_EQ(omni.limits().ee[0].peak_force, phantom_omni_limits().ee[0].peak_force);
  EXPECT_EQ(omni.limits().ee[0].workspace_max_H, phantom_omni_limits().ee[0].workspace_max_H);
  EXPECT_EQ(check_limits(omni.limits()), nullptr);
  // Whatever the sample held before, read() reports one end-effector whose
  // handle has buttons and the stylus's dead-man (released: the script does
  // not press it), nothing else.
  DeviceSample s;
  s.end_effectors = 2;
  s.ee[0].handle.has_grip = true;
  s.ee[0].handle.grip_position = 0.01;
  s.ee[0].angular_velocity_H = Vector3d(1, 2, 3);
  s.ee[0].enabled = false;
  omni.read(s);
  EXPECT_EQ(s.end_effectors, 1);
  EXPECT_EQ(s.ee[0].position_H, Vector3d(0.01, 0.02, -0.01));
  EXPECT_EQ(s.ee[0].angular_velocity_H, Vector3d::Zero());
  EXPECT_TRUE(s.ee[0].enabled);
  EXPECT_EQ(s.ee[0].handle.buttons, kButton2);
  EXPECT_EQ(handle_input_bits(s.ee[0].handle), kHasDeadman);
  EXPECT_FALSE(s.ee[0].handle.deadman);
  EXPECT_EQ(s.ee[0].handle.grip_position, 0.0);
}

TEST(SimulatedOmni, TorqueIsIgnoredAndGripForceIgnoredAndCounted) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<LineScript>(Vector3d::Zero(), Vector3d(0.02, -0.01, 0.01), 0.05);
  SimulatedOmni plain(m, script), with_extras(m, script);
  DeviceCommand extras = force_command(Vector3d(0.2, 0.1, -0.3));
  extras.ee[0].torque_H = Vector3d(0.05, -0.02, 0.01);
  extras.ee[0].grip_force = 1.5;
  extras.ee[1].force_H = Vector3d(9, 9, 9);  // no second end-effector: ignored
  for (int i = 0; i < 500; ++i) {
    plain.write(force_command(extras.ee[0].force_H));
    with_extras.write(extras);
  }
  // Bit for bit the same motion: only the force acts.
  EXPECT_EQ(with_extras.data().position_H, plain.data().position_H);
  EXPECT_EQ(with_extras.data().applied_force_H, plain.data().applied_force_H);
  EXPECT_EQ(with_extras.data().ignored_grip_commands, 500u);
  EXPECT_EQ(plain.data().ignored_grip_commands, 0u);
  EXPECT_EQ(with_extras.data().nonfinite_commands, 0u);
}

TEST(SimulatedOmni, NonFiniteTorqueOrGripForceZeroesTheWholeWrench) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<HoldScript>(Vector3d::Zero());
  SimulatedOmni omni(m, script);
  DeviceCommand c = force_command(Vector3d(0.5, 0, 0));
  c.ee[0].torque_H.z() = std::numeric_limits<double>::quiet_NaN();
  omni.write(c);
  EXPECT_EQ(omni.data().applied_force_H, Vector3d::Zero());
  c = force_command(Vector3d(0.5, 0, 0));
  c.ee[0].grip_force = -std::numeric_limits<double>::infinity();
  omni.write(c);
  EXPECT_EQ(omni.data().applied_force_H, Vector3d::Zero());
  EXPECT_EQ(omni.data().nonfinite_commands, 2u);
  EXPECT_EQ(omni.data().ignored_grip_commands, 0u);
  omni.write(force_command(Vector3d(0.5, 0, 0)));  // a good command acts again
  EXPECT_EQ(omni.data().applied_force_H, Vector3d(0.5, 0, 0));
}

TEST(SimulatedOmni, ButtonsAndOrientationFollowTheScript) {
  auto motion = std::make_shared<HoldScript>(Vector3d::Zero());
  auto script = std::make_shared<ButtonEventsScript>(
      motion, std::vector<ButtonEvent>{{0.0105, kButton1}, {0.0205, kButton1 | kButton2}, {0.0305, 0}});
  SimulatedOmni omni(SimulatedOmniModel{}, script);
  EXPECT_NE(omni.name().find("simulated"), std::string_view::npos);
  DeviceSample s;
  std::uint32_t seen[40];
  for (int i = 0; i < 40; ++i) {
    omni.read(s);
    seen[i] = s.ee[0].handle.buttons;
    omni.write(DeviceCommand{});
  }
  // read i reports the state after i steps, i.e. the script at t = i ms.
  EXPECT_EQ(seen[10], 0u);
  EXPECT_EQ(seen[11], kButton1);
  EXPECT_EQ(seen[20], kButton1);
  EXPECT_EQ(seen[21], kButton1 | kButton2);
  EXPECT_EQ(seen[31], 0u);
}

TEST(SimulatedOmni, RejectsBadModelsAndNullScript) {
  auto script = std::make_shared<HoldScript>(Vector3d::Zero());
  SimulatedOmniModel m;
  m.device_mass = 0.0;
  EXPECT_THROW(SimulatedOmni(m, script), std::invalid_argument);
  m = SimulatedOmniModel{};
  m.hand_damping = -1.0;
  EXPECT_THROW(SimulatedOmni(m, script), std::invalid_argument);
  m = SimulatedOmniModel{};
  m.limits.max_continuous_force = 5.0;  // above peak
  EXPECT_THROW(SimulatedOmni(m, script), std::invalid_argument);
  m = SimulatedOmniModel{};
  m.dt_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(SimulatedOmni(m, script), std::invalid_argument);
  EXPECT_THROW(SimulatedOmni(SimulatedOmniModel{}, nullptr), std::invalid_argument);
  EXPECT_EQ(check_model(SimulatedOmniModel{}), nullptr);
}

// Issue 23 item 2: the stylus's dead-man is the hand's: pressed while the
// script presses it, released as soon as it lets go.
TEST(SimulatedOmni, TheStylusDeadManFollowsTheHandsScriptedPress) {
  auto hold = std::make_shared<HoldScript>(Vector3d::Zero());
  auto script = std::make_shared<DeadmanScript>(hold, std::vector<DeadmanPress>{{0.0105, 0.0205}});
  SimulatedOmni omni(SimulatedOmniModel{}, script);
  DeviceSample s;
  std::vector<int> pressed;
  for (int i = 0; i < 30; ++i) {
    omni.read(s);
    ASSERT_TRUE(s.ee[0].handle.has_deadman);
    pressed.push_back(s.ee[0].handle.deadman ? 1 : 0);
    omni.write(DeviceCommand{});
  }
  // read() i reports the hand after i periods of 1 ms: pressed for 11..20.
  for (int i = 0; i < 30; ++i) EXPECT_EQ(pressed[static_cast<size_t>(i)], i >= 11 && i <= 20 ? 1 : 0) << i;
}

}  // namespace
}  // namespace hemm::device
