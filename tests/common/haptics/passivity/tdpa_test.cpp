// The TDPA's pieces against closed forms: the observer's energy of known
// signals, the peer energy's acceptance rules, the controller's scale, and
// the mode suggestion's thresholds.
#include "common/haptics/passivity/tdpa.h"

#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

namespace {

namespace td = hemm::haptics::tdpa;
using V1 = Eigen::Matrix<double, 1, 1>;
using V3 = Eigen::Matrix<double, 3, 1>;

// The observer (kObserveOnly) on a damper F = b v driven by v = A sin(w t),
// sampled N times a period over whole periods: the energy it takes is
// b A^2 T / 2 (the sampled sum of sin^2 over a period is exactly N/2 for
// N >= 3), and it never gives any back. The robot end's port: the damper's
// force on the gripper is -b v, so the channel puts b v^2 out.
TEST(TdpaObserver, DamperEnergyIsTheClosedForm) {
  const double b = 7.5, A = 0.3, f_hz = 2.0;
  for (int per_period : {4, 37, 1000}) {
    const double dt = 1.0 / (f_hz * per_period);
    const int periods = 5;
    td::Side<1> s;
    for (int k = 0; k < per_period * periods; ++k) {
      const double v = A * std::sin(2 * std::numbers::pi * f_hz * k * dt);
      EXPECT_EQ(td::robot_tick<1>(s, V1(v), V1(-b * v), dt, td::PcMode::kObserveOnly)[0], v);
    }
    const double T = periods / f_hz;
    EXPECT_NEAR(s.out_J[0], b * A * A * T / 2, 1e-12 * b * A * A * T) << per_period;
    EXPECT_EQ(s.in_J[0], 0.0);
    EXPECT_EQ(s.pc_active_ticks, 0u);
  }
}

// A spring with x = A sin(w t) at the operator's port (the device shows the
// hand F = -k x): the channel gives k A^2 / 2 out in each quarter period the
// spring relaxes and takes it back in the next, so over P whole periods
// E_in = E_out = P k A^2.
TEST(TdpaObserver, SpringEnergyIsTheClosedForm) {
  const double k = 5000.0, A = 0.01, f_hz = 3.0, dt = 1e-5;
  const int periods = 4;
  const int n = static_cast<int>(std::lround(periods / (f_hz * dt)));
  td::Side<1> s;
  for (int i = 0; i < n; ++i) {
    const double w = 2 * std::numbers::pi * f_hz;
    const double t = (i + 0.5) * dt;  // midpoint samples
    const double x = A * std::sin(w * t), v = A * w * std::cos(w * t);
    td::operator_tick<1>(s, V1(-k * x), V1(v), dt, td::PcMode::kObserveOnly);
  }
  const double expect = periods * k * A * A;
  EXPECT_NEAR(s.in_J[0], expect, 1e-6 * expect);
  EXPECT_NEAR(s.out_J[0], expect, 1e-6 * expect);
}

TEST(TdpaPeer, NewestBySequenceAndBadInputChangesNothing) {
  td::Side<3> s;
  EXPECT_EQ(td::receive_peer<3>(s, 5, V3(1, 2, 3)), td::Receive::kAccepted);
  EXPECT_EQ(s.peer_seq, 5u);
  // Older and duplicate: ignored (reordered or repeated datagrams).
  EXPECT_EQ(td::receive_peer<3>(s, 4, V3(0.5, 1, 1)), td::Receive::kOld);
  EXPECT_EQ(td::receive_peer<3>(s, 5, V3(9, 9, 9)), td::Receive::kOld);
  EXPECT_EQ(s.peer_in_J, V3(1, 2, 3));
  // A lost message loses nothing: the next one carries the sum.
  EXPECT_EQ(td::receive_peer<3>(s, 9, V3(4, 2, 3)), td::Receive::kAccepted);
  EXPECT_EQ(s.peer_in_J, V3(4, 2, 3));
  const td::Side<3> before = s;
  EXPECT_EQ(td::receive_peer<3>(s, 10, V3(std::numeric_limits<double>::quiet_NaN(), 2, 3)),
            td::Receive::kNonFinite);
  EXPECT_EQ(td::receive_peer<3>(s, 11, V3(5, -1e-9, 3)), td::Receive::kNegative);
  EXPECT_EQ(td::receive_peer<3>(s, 12, V3(5, 1.9, 3)), td::Receive::kDecreasing);
  EXPECT_EQ(s.peer_in_J, before.peer_in_J);
  EXPECT_EQ(s.peer_seq, before.peer_seq);
  EXPECT_EQ(s.peer_refused, 3u);
  EXPECT_EQ(s.peer_old, 2u);
  td::reset<3>(s);
  EXPECT_FALSE(s.peer_received);
  EXPECT_EQ(td::receive_peer<3>(s, 1, V3(0, 0, 0)), td::Receive::kAccepted);
}

// The robot end moves 0.2 m/s into a 10 N push: 2 W out of the channel, 2 mJ
// a 1 ms tick. With 0.5 mJ of budget the tracked velocity is a quarter; then,
// the budget spent, zero; moving away (energy in) is never changed.
TEST(TdpaController, RobotScalesVelocityToTheBudget) {
  td::Side<1> s;
  ASSERT_EQ(td::receive_peer<1>(s, 1, V1(0.5e-3)), td::Receive::kAccepted);
  const double dt = 1e-3;
  EXPECT_NEAR(td::robot_tick<1>(s, V1(0.2), V1(-10.0), dt)[0], 0.05, 1e-15);
  EXPECT_NEAR(s.out_J[0], 0.5e-3, 1e-18);
  EXPECT_NEAR(s.dissipated_J[0], 1.5e-3, 1e-15);
  EXPECT_EQ(td::robot_tick<1>(s, V1(0.2), V1(-10.0), dt)[0], 0.0);
  EXPECT_EQ(td::robot_tick<1>(s, V1(-0.2), V1(-10.0), dt)[0], -0.2);
  EXPECT_NEAR(s.in_J[0], 2e-3, 1e-15);
  EXPECT_EQ(s.pc_active_ticks, 2u);
  // Observe-only: counted, not changed.
  EXPECT_EQ(td::robot_tick<1>(s, V1(0.2), V1(-10.0), dt, td::PcMode::kObserveOnly)[0], 0.2);
  EXPECT_NEAR(s.out_J[0], 2.5e-3, 1e-15);
}

// The operator end: the device pushes the hand along its motion (output).
TEST(TdpaController, OperatorScalesForceToTheBudget) {
  td::Side<1> s;
  const double dt = 1e-3;
  // No budget received yet: nothing may leave.
  EXPECT_EQ(td::operator_tick<1>(s, V1(4.0), V1(0.1), dt)[0], 0.0);
  ASSERT_EQ(td::receive_peer<1>(s, 3, V1(1e-3)), td::Receive::kAccepted);
  EXPECT_NEAR(td::operator_tick<1>(s, V1(4.0), V1(0.5), dt)[0], 2.0, 1e-15);  // 2 mJ wanted, 1 allowed
  // Against the motion: the hand puts energy in, the force is shown whole.
  EXPECT_EQ(td::operator_tick<1>(s, V1(-4.0), V1(0.5), dt)[0], -4.0);
  EXPECT_NEAR(s.in_J[0], 2e-3, 1e-15);
  EXPECT_LE(s.out_J[0], s.peer_in_J[0]);
}

TEST(TdpaMode, ThresholdsAndHysteresis) {
  const td::ModeThresholds t;  // 100 ms, 10 %, 20 % hysteresis
  using M = td::FeedbackMode;
  EXPECT_EQ(td::suggest_mode(0.0, 0.0), M::kDirect);
  EXPECT_EQ(td::suggest_mode(0.079, 0.05), M::kDirect);
  EXPECT_EQ(td::suggest_mode(0.09, 0.0), M::kModelMediated);  // within the band: stay
  EXPECT_EQ(td::suggest_mode(0.09, 0.0, M::kDirect, t), M::kDirect);
  EXPECT_EQ(td::suggest_mode(0.101, 0.0, M::kDirect, t), M::kModelMediated);
  EXPECT_EQ(td::suggest_mode(0.3, 0.05), M::kModelMediated);
  EXPECT_EQ(td::suggest_mode(3.0, 0.05), M::kModelMediated);
  EXPECT_EQ(td::suggest_mode(0.02, 0.11, M::kDirect, t), M::kModelMediated);
  EXPECT_EQ(td::suggest_mode(std::numeric_limits<double>::quiet_NaN(), 0.0, M::kDirect, t), M::kModelMediated);
  EXPECT_EQ(td::suggest_mode(0.01, -0.1, M::kDirect, t), M::kModelMediated);
}

}  // namespace
