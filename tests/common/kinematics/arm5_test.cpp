// The 5-DoF arm: corrected Eq. 3 against an independent product of elementary
// transforms and the DH table; Jacobian against finite differences; IK round
// trips, near-singular and out-of-reach targets. (The check against MuJoCo's
// own site pose is in tests/robot_side/sim.)
#include "common/kinematics/arm5.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace hk = hemm::kinematics;
using hk::Arm5Vector;

namespace {

Eigen::Isometry3d elementary_chain(const hk::Arm5Model& m, const Arm5Vector& q) {
  using Eigen::AngleAxisd;
  using Eigen::Translation3d;
  using Eigen::Vector3d;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T = T * AngleAxisd(q(0), Vector3d::UnitZ()) * Translation3d(m.A1, 0, 0);
  T = T * AngleAxisd(-q(1), Vector3d::UnitY()) * Translation3d(m.A2, 0, 0);
  T = T * AngleAxisd(-q(2), Vector3d::UnitY()) * Translation3d(m.A4, 0, 0);
  T = T * AngleAxisd(-q(3), Vector3d::UnitX()) * AngleAxisd(q(4), Vector3d::UnitY()) * Translation3d(m.A5, 0, 0);
  return T;
}

// Eq. 3 exactly as printed (second column with the paper's sign).
Eigen::Matrix3d printed_rotation(const Arm5Vector& q) {
  const double c1 = std::cos(q(0)), s1 = std::sin(q(0));
  const double c23 = std::cos(q(1) + q(2)), s23 = std::sin(q(1) + q(2));
  const double c4 = std::cos(q(3)), s4 = std::sin(q(3));
  const double c5 = std::cos(q(4)), s5 = std::sin(q(4));
  Eigen::Matrix3d R;
  R << c1 * s23 * c4 * s5 + c1 * c23 * c5 + s1 * s4 * s5, -c1 * s23 * s4 + s1 * c4,
      -c1 * s23 * c4 * c5 + c1 * c23 * s5 - s1 * s4 * c5,  //
      s1 * s23 * c4 * s5 + s1 * c23 * c5 - c1 * s4 * s5, -s1 * s23 * s4 - c1 * c4,
      -s1 * s23 * c4 * c5 + s1 * c23 * s5 + c1 * s4 * c5,  //
      -c23 * c4 * s5 + s23 * c5, c23 * s4, c23 * c4 * c5 + s23 * s5;
  return R;
}

Arm5Vector random_q(const hk::Arm5Model& m, std::mt19937_64& rng) {
  Arm5Vector q;
  for (int i = 0; i < hk::kArm5Dof; ++i) {
    q(i) = std::uniform_real_distribution<double>(m.q_min(i), m.q_max(i))(rng);
  }
  return q;
}

}  // namespace

TEST(Arm5Kinematics, ClosedFormMatchesElementaryChainAndDhTable) {
  const hk::Arm5Model m;
  std::mt19937_64 rng(7);
  for (int k = 0; k < 2000; ++k) {
    Arm5Vector q;
    for (int i = 0; i < 5; ++i) q(i) = std::uniform_real_distribution<double>(-std::numbers::pi, std::numbers::pi)(rng);
    const Eigen::Isometry3d T = hk::forward_kinematics(m, q);
    const Eigen::Isometry3d Te = elementary_chain(m, q);
    const Eigen::Isometry3d Td = hk::dh_forward_kinematics(m, q);
    ASSERT_LT((T.matrix() - Te.matrix()).cwiseAbs().maxCoeff(), 1e-12) << q.transpose();
    ASSERT_LT((T.matrix() - Td.matrix()).cwiseAbs().maxCoeff(), 1e-12) << q.transpose();
    ASSERT_NEAR(T.linear().determinant(), 1.0, 1e-12);
    ASSERT_LT((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  }
}

TEST(Arm5Kinematics, PrintedEquationIsAReflectionAndDiffersOnlyInColumnTwo) {
  const hk::Arm5Model m;
  std::mt19937_64 rng(8);
  for (int k = 0; k < 200; ++k) {
    const Arm5Vector q = random_q(m, rng);
    const Eigen::Matrix3d P = printed_rotation(q);
    const Eigen::Matrix3d R = hk::forward_kinematics(m, q).linear();
    EXPECT_NEAR(P.determinant(), -1.0, 1e-12);
    EXPECT_LT((P.col(0) - R.col(0)).norm(), 1e-12);
    EXPECT_LT((P.col(1) + R.col(1)).norm(), 1e-12);
    EXPECT_LT((P.col(2) - R.col(2)).norm(), 1e-12);
  }
}

TEST(Arm5Kinematics, ReachIsFiftyCentimetresWhenStretched) {
  const hk::Arm5Model m;
  const Eigen::Isometry3d T = hk::forward_kinematics(m, Arm5Vector::Zero());
  EXPECT_NEAR(T.translation().x(), 0.50, 1e-12);
  EXPECT_NEAR(m.reach(), 0.50, 1e-12);
  EXPECT_FALSE(hk::validate(m));
  hk::Arm5Model bad = m;
  bad.q_min(2) = 1.0;
  EXPECT_TRUE(hk::validate(bad));
}

TEST(Arm5Kinematics, JacobianMatchesFiniteDifferences) {
  const hk::Arm5Model m;
  std::mt19937_64 rng(9);
  const double h = 1e-6;
  for (int k = 0; k < 300; ++k) {
    const Arm5Vector q = random_q(m, rng);
    const hk::Arm5Jacobian J = hk::jacobian(m, q);
    for (int i = 0; i < 5; ++i) {
      Arm5Vector qp = q, qm = q;
      qp(i) += h;
      qm(i) -= h;
      const Eigen::Isometry3d Tp = hk::forward_kinematics(m, qp), Tm = hk::forward_kinematics(m, qm);
      const Eigen::Vector3d v = (Tp.translation() - Tm.translation()) / (2 * h);
      const Eigen::AngleAxisd aa(Tp.linear() * Tm.linear().transpose());
      const Eigen::Vector3d w = aa.axis() * aa.angle() / (2 * h);
      ASSERT_LT((J.block<3, 1>(0, i) - v).norm(), 1e-7) << "joint " << i;
      ASSERT_LT((J.block<3, 1>(3, i) - w).norm(), 1e-7) << "joint " << i;
    }
  }
}

TEST(Arm5InverseKinematics, RoundTripsRandomConfigurations) {
  const hk::Arm5Model m;
  std::mt19937_64 rng(10);
  int converged = 0;
  const int n = 1000;
  for (int k = 0; k < n; ++k) {
    const Arm5Vector q = random_q(m, rng);
    const Eigen::Isometry3d T = hk::forward_kinematics(m, q);
    const hk::Arm5Target t{T.translation(), hk::tool_pitch(T), q(3)};
    const hk::IkResult r = hk::inverse_kinematics(m, t, Arm5Vector::Zero());
    ASSERT_TRUE(r.q.allFinite());
    ASSERT_TRUE(hk::within_limits(m, r.q));
    if (r.status == hk::IkStatus::kConverged) {
      ++converged;
      const Eigen::Isometry3d Tr = hk::forward_kinematics(m, r.q);
      EXPECT_LT((Tr.translation() - t.p_A_E).norm(), 1e-5);
      EXPECT_NEAR(hk::tool_pitch(Tr), t.tool_pitch, 1e-4);
      EXPECT_NEAR(r.q(3), q(3), 1e-4);
    } else {
      // Not converged is allowed only as a local minimum that says so.
      EXPECT_EQ(r.status, hk::IkStatus::kUnreachable);
      EXPECT_GT(r.position_error_m + r.pitch_error_rad, 1e-6);
    }
  }
  // Every target is reachable by construction; DLS may stall at a joint limit
  // on a few (seeds and a posture grid are tried), but must not on more than 1%.
  EXPECT_GE(converged, n * 99 / 100) << converged;
  std::printf("IK round trips: %d of %d converged from a zero seed\n", converged, n);
}

TEST(Arm5InverseKinematics, OutOfReachGivesNearestPoseAndSaysSo) {
  const hk::Arm5Model m;
  const Eigen::Vector3d target(1.0, 0.3, 0.2);
  const double yaw = std::atan2(target.y(), target.x());
  const Eigen::Vector3d shoulder(m.A1 * std::cos(yaw), m.A1 * std::sin(yaw), 0.0);
  const Eigen::Vector3d d = target - shoulder;
  const double elevation = std::atan2(d.z(), std::hypot(d.x(), d.y()));
  const hk::IkResult r = hk::inverse_kinematics(m, {target, elevation, 0.0}, Arm5Vector::Zero());
  EXPECT_EQ(r.status, hk::IkStatus::kUnreachable);
  const double nearest = d.norm() - (m.A2 + m.A4 + m.A5);
  EXPECT_NEAR(r.position_error_m, nearest, 1e-4);
  const Eigen::Vector3d p = hk::forward_kinematics(m, r.q).translation();
  EXPECT_NEAR((p - shoulder).norm(), m.A2 + m.A4 + m.A5, 1e-4);
  EXPECT_TRUE(hk::within_limits(m, r.q));
}

TEST(Arm5InverseKinematics, NearSingularTargets) {
  const hk::Arm5Model m;
  // Fully stretched (elbow and wrist straight): exactly reachable...
  Arm5Vector q = Arm5Vector::Zero();
  q(1) = 0.3;
  const Eigen::Isometry3d T = hk::forward_kinematics(m, q);
  hk::IkResult r = hk::inverse_kinematics(m, {T.translation(), hk::tool_pitch(T), 0.0}, Arm5Vector::Zero());
  EXPECT_TRUE(r.q.allFinite());
  EXPECT_LT(r.position_error_m, 1e-4);
  // ... and 1 mm beyond the boundary: nearest pose, flagged.
  const Eigen::Vector3d shoulder(m.A1, 0, 0);
  const Eigen::Vector3d beyond = T.translation() + 1e-3 * (T.translation() - shoulder).normalized();
  r = hk::inverse_kinematics(m, {beyond, hk::tool_pitch(T), 0.0}, Arm5Vector::Zero());
  EXPECT_EQ(r.status, hk::IkStatus::kUnreachable);
  EXPECT_NEAR(r.position_error_m, 1e-3, 1e-4);
  EXPECT_TRUE(r.q.allFinite());
  // Tool tip on the yaw axis, where q1 does not move the tip (a position
  // singularity): the arm folded up and back, q5 found by bisection.
  auto tip_x = [&](double q5) {
    return hk::forward_kinematics(m, (Arm5Vector() << 0, 1.5, 0.3, 0, q5).finished()).translation().x();
  };
  double lo = -1.0, hi = 1.0;  // tip_x(lo) < 0 < tip_x(hi)
  ASSERT_LT(tip_x(lo) * tip_x(hi), 0.0);
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (tip_x(mid) < 0 ? lo : hi) = mid;
  }
  const Eigen::Isometry3d Ta = hk::forward_kinematics(m, (Arm5Vector() << 0, 1.5, 0.3, 0, lo).finished());
  ASSERT_LT(std::abs(Ta.translation().x()), 1e-12);
  r = hk::inverse_kinematics(m, {Ta.translation(), hk::tool_pitch(Ta), 0.0}, Arm5Vector::Zero());
  EXPECT_TRUE(r.q.allFinite());
  EXPECT_EQ(r.status, hk::IkStatus::kConverged) << r.position_error_m << " " << r.pitch_error_rad;
  EXPECT_LT(r.position_error_m, 1e-5);
}

TEST(Arm5InverseKinematics, HostileInputIsRejectedWithoutNaN) {
  const hk::Arm5Model m;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  hk::IkResult r = hk::inverse_kinematics(m, {Eigen::Vector3d(nan, 0, 0), 0, 0}, Arm5Vector::Zero());
  EXPECT_EQ(r.status, hk::IkStatus::kInvalidInput);
  EXPECT_TRUE(r.q.allFinite());
  Arm5Vector seed = Arm5Vector::Constant(nan);
  r = hk::inverse_kinematics(m, {Eigen::Vector3d(0.3, 0, 0.1), 0, 0}, seed);
  EXPECT_EQ(r.status, hk::IkStatus::kInvalidInput);
  EXPECT_TRUE(r.q.allFinite());
}

TEST(Arm5InverseKinematics, DampedRatesAreBoundedAtSingularities) {
  const hk::Arm5Model m;
  const double lambda = 0.02;
  const Eigen::Vector3d v(0.2, 0.0, 0.0);  // along the stretched arm: singular direction
  for (const Arm5Vector& q : {Arm5Vector::Zero().eval(), (Arm5Vector() << 0, std::numbers::pi / 2, 0, 0, 0).finished()}) {
    const Arm5Vector qd = hk::damped_rates(m, q, v, lambda);
    ASSERT_TRUE(qd.allFinite());
    EXPECT_LE(qd.norm(), v.norm() / (2 * lambda) + 1e-9);
  }
  // Away from singularities DLS tracks the velocity closely.
  const Arm5Vector q = (Arm5Vector() << 0.2, 0.5, -1.2, 0.1, 0.4).finished();
  const Eigen::Vector3d v2(0.01, -0.02, 0.01);
  const Arm5Vector qd = hk::damped_rates(m, q, v2, 1e-3);
  EXPECT_LT((hk::jacobian(m, q).topRows<3>() * qd - v2).norm(), 1e-4);
}
