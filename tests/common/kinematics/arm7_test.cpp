// The 7-DoF arm: forward kinematics, partial Jacobians and rigid-body
// dynamics against MuJoCo on the same model (body poses, mj_jac, mj_fullM,
// qfrc_bias, mj_inverse), against finite differences, and against closed
// forms of a point mass on a planar two-link chain.
#include "common/kinematics/arm7.h"

#include <cmath>
#include <cstring>
#include <numbers>
#include <random>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "tests/common/kinematics/mujoco_arm7.h"

namespace hk = hemm::kinematics;
using hk::Arm7Vector;

namespace {

Arm7Vector random_q(const hk::Arm7Model& m, std::mt19937_64& rng) {
  Arm7Vector q;
  for (int i = 0; i < hk::kArm7Dof; ++i) q(i) = std::uniform_real_distribution<double>(m.q_min(i), m.q_max(i))(rng);
  return q;
}

Arm7Vector random_vec(std::mt19937_64& rng, double s) {
  Arm7Vector v;
  for (int i = 0; i < hk::kArm7Dof; ++i) v(i) = std::uniform_real_distribution<double>(-s, s)(rng);
  return v;
}

Eigen::Isometry3d mj_pose(const mjData* d, int body) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << d->xpos[3 * body], d->xpos[3 * body + 1], d->xpos[3 * body + 2];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = d->xmat[9 * body + 3 * r + c];
  return T;
}

}  // namespace

TEST(Arm7Model, DefaultsAreTheLwrClassFacts) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  ASSERT_FALSE(hk::validate(m)) << *hk::validate(m);
  hk::Arm7Frames f;
  hk::forward_kinematics(m, Arm7Vector::Zero(), f);
  // Straight arm along z: shoulder ~0.31, upper arm 0.40, forearm 0.39, flange 0.078.
  EXPECT_NEAR(f.origin(2).z(), 0.3105, 1e-12);
  EXPECT_NEAR(f.origin(4).z() - f.origin(2).z(), 0.400, 1e-12);
  EXPECT_NEAR(f.origin(6).z() - f.origin(4).z(), 0.390, 1e-12);
  EXPECT_NEAR(f.origin(7).z() - f.origin(6).z(), 0.078, 1e-12);
  double mass = 0;
  for (const auto& l : m.link) mass += l.mass;
  EXPECT_NEAR(mass, 12.4, 0.01);  // + 1.2 kg fixed link 0 ~ the paper's 14 kg class
  EXPECT_NEAR(m.q_max(1), 120.0 * std::numbers::pi / 180, 1e-12);
  EXPECT_NEAR(m.q_max(2), 170.0 * std::numbers::pi / 180, 1e-12);
  EXPECT_EQ(m.tau_max(0), 176.0);
  EXPECT_EQ(m.tau_max(6), 38.0);
}

TEST(Arm7Model, ValidateRejectsNonsense) {
  auto bad = [](auto mutate) {
    hk::Arm7Model m = hk::lwr_arm_model();
    mutate(m);
    return hk::validate(m).has_value();
  };
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.axis[2] = Eigen::Vector3d(0, 0, 2); }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.offset[0].x() = NAN; }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.link[3].mass = -1; }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.link[3].inertia(0, 1) = 0.5; }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.link[3].inertia(2, 2) = 10.0; }));  // triangle inequality
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.q_min(4) = m.q_max(4); }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.tau_max(6) = 0; }));
  EXPECT_TRUE(bad([](hk::Arm7Model& m) { m.qd_max(0) = INFINITY; }));
  EXPECT_FALSE(bad([](hk::Arm7Model&) {}));
}

TEST(Arm7Kinematics, EveryJointFrameMatchesMujoco) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  // A horizontally mounted base, as on the column.
  auto mj = hemm::test::make_mj_arm7(m, "0.1 -0.2 1.3", "0.7071067811865476 0.7071067811865476 0 0");
  Eigen::Isometry3d T_W_A = Eigen::Isometry3d::Identity();
  T_W_A.translation() << 0.1, -0.2, 1.3;
  T_W_A.linear() = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::mt19937_64 rng(11);
  double worst = 0;
  for (int k = 0; k < 300; ++k) {
    const Arm7Vector q = random_q(m, rng);
    mj.set(q, Arm7Vector::Zero());
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    for (int i = 1; i <= hk::kArm7Dof; ++i) {
      const Eigen::Isometry3d T = T_W_A * f.joint(i);
      worst = std::max(worst, (T.matrix() - mj_pose(mj.d.get(), mj.link[i - 1]).matrix()).cwiseAbs().maxCoeff());
    }
    EXPECT_LT((hk::flange_pose(m, q).matrix() - f.joint(7).matrix()).cwiseAbs().maxCoeff(), 1e-15);
  }
  EXPECT_LT(worst, 1e-9);
}

// The S-R-S elbow: the wrist centre's distance from the shoulder depends on
// q4 alone, so elbow_bend recovers |q4| from the flange pose whatever the
// other joints; beyond the reach it gives minus the shortfall.
TEST(Arm7Kinematics, ElbowBendIsTheElbowJointWhateverTheOtherJoints) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  const hk::Arm7Elbow e = hk::arm7_elbow(m);
  EXPECT_NEAR(e.upper_arm_m, 0.40, 1e-12);
  EXPECT_NEAR(e.forearm_m, 0.39, 1e-12);
  std::mt19937_64 rng(11);
  double worst = 0.0;
  for (int i = 0; i < 200; ++i) {
    const Arm7Vector q = random_q(m, rng);
    const Eigen::Isometry3d T = hk::flange_pose(m, q);
    worst = std::max(worst, std::abs(hk::elbow_bend(e, T * e.wrist_J7) - std::abs(q(3))));
  }
  EXPECT_LT(worst, 1e-7);
  // Stretched along the shoulder's axis, then 5 cm further.
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, -0.5).normalized();
  EXPECT_NEAR(hk::elbow_bend(e, e.shoulder_A + 0.79 * dir), 0.0, 1e-6);
  EXPECT_NEAR(hk::elbow_bend(e, e.shoulder_A + 0.84 * dir), -0.05, 1e-12);
  // Not an S-R-S arm: refused.
  hk::Arm7Model bent = m;
  bent.offset[3] = Eigen::Vector3d(0.01, 0.0, 0.2085);
  EXPECT_THROW(hk::arm7_elbow(bent), std::invalid_argument);
}

TEST(Arm7Kinematics, PartialJacobiansMatchFiniteDifferencesAndMujoco) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  auto mj = hemm::test::make_mj_arm7(m);
  std::mt19937_64 rng(12);
  mjtNum jacp[3 * hk::kArm7Dof], jacr[3 * hk::kArm7Dof];
  for (int k = 0; k < 100; ++k) {
    const Arm7Vector q = random_q(m, rng);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    for (int link = 1; link <= hk::kArm7Dof; ++link) {
      // A point on the link, off the joint axis.
      const Eigen::Vector3d p_J(0.03, -0.02, 0.05);
      const Eigen::Vector3d p_A = f.joint(link) * p_J;
      const hk::Arm7Jacobian J = hk::partial_jacobian(m, f, link, p_A);
      // Finite differences of the point and of the link orientation.
      const double h = 1e-6;
      for (int i = 0; i < hk::kArm7Dof; ++i) {
        Arm7Vector qp = q, qm = q;
        qp(i) += h;
        qm(i) -= h;
        hk::Arm7Frames fp, fm;
        hk::forward_kinematics(m, qp, fp);
        hk::forward_kinematics(m, qm, fm);
        const Eigen::Vector3d v = (fp.joint(link) * p_J - fm.joint(link) * p_J) / (2 * h);
        const Eigen::AngleAxisd dR(fp.joint(link).linear() * fm.joint(link).linear().transpose());
        const Eigen::Vector3d w = dR.angle() * dR.axis() / (2 * h);
        ASSERT_LT((J.block<3, 1>(0, i) - v).norm(), 1e-7) << "link " << link << " col " << i;
        ASSERT_LT((J.block<3, 1>(3, i) - w).norm(), 1e-7) << "link " << link << " col " << i;
      }
      // MuJoCo's Jacobian of the same point on the same body.
      mj.set(q, Arm7Vector::Zero());
      const mjtNum pt[3] = {p_A.x(), p_A.y(), p_A.z()};
      mj_jac(mj.m.get(), mj.d.get(), jacp, jacr, pt, mj.link[link - 1]);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < hk::kArm7Dof; ++c) {
          ASSERT_NEAR(J(r, c), jacp[r * hk::kArm7Dof + c], 1e-9);
          ASSERT_NEAR(J(3 + r, c), jacr[r * hk::kArm7Dof + c], 1e-9);
        }
    }
    // The paper's two Jacobians.
    EXPECT_EQ(hk::elbow_jacobian(m, f), hk::partial_jacobian(m, f, 4, f.origin(4)));
    EXPECT_EQ(hk::flange_jacobian(m, f), hk::partial_jacobian(m, f, 7, f.origin(7)));
    EXPECT_TRUE(hk::elbow_jacobian(m, f).rightCols<3>().isZero(0.0));
  }
}

TEST(Arm7Kinematics, DriftAccelerationIsTheJacobianRateTimesTheJointRates) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  std::mt19937_64 rng(16);
  for (int k = 0; k < 100; ++k) {
    const Arm7Vector q = random_q(m, rng), qd = random_vec(rng, 2.0);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    const int link = 1 + k % 7;
    const Eigen::Vector3d p_J(0.02, 0.03, 0.07);
    const hk::Wrench6 a = hk::drift_acceleration(m, f, qd, link, f.joint(link) * p_J);
    // d/dt (J(q(t)) qd) along q(t) = q + t qd, the point moving with the link.
    const double h = 1e-6;
    hk::Arm7Frames fp, fm;
    hk::forward_kinematics(m, q + h * qd, fp);
    hk::forward_kinematics(m, q - h * qd, fm);
    const hk::Wrench6 vp = hk::partial_jacobian(m, fp, link, fp.joint(link) * p_J) * qd;
    const hk::Wrench6 vm = hk::partial_jacobian(m, fm, link, fm.joint(link) * p_J) * qd;
    ASSERT_LT((a - (vp - vm) / (2 * h)).norm(), 1e-6) << "link " << link;
  }
}

TEST(Arm7Dynamics, MassMatrixBiasAndInverseDynamicsMatchMujoco) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  // Horizontal mount: gravity has a component along the base axis.
  auto mj = hemm::test::make_mj_arm7(m, "0 0 1", "0.7071067811865476 0 0.7071067811865476 0");
  const Eigen::Matrix3d R_W_A = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d g_A = R_W_A.transpose() * Eigen::Vector3d(0, 0, -9.81);
  std::mt19937_64 rng(13);
  double worst_M = 0, worst_b = 0, worst_g = 0, worst_id = 0, max_M = 0, max_b = 0;
  std::vector<mjtNum> M(hk::kArm7Dof * hk::kArm7Dof);
  for (int k = 0; k < 200; ++k) {
    const Arm7Vector q = random_q(m, rng);
    const Arm7Vector qd = random_vec(rng, 2.0);
    const Arm7Vector qdd = random_vec(rng, 5.0);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    mj.set(q, qd);
    mj_fullM(mj.m.get(), M.data(), mj.d->qM);
    const hk::Arm7Matrix Mh = hk::mass_matrix(m, f);
    for (int r = 0; r < 7; ++r)
      for (int c = 0; c < 7; ++c) {
        worst_M = std::max(worst_M, std::abs(Mh(r, c) - M[static_cast<size_t>(r * 7 + c)]));
        max_M = std::max(max_M, std::abs(Mh(r, c)));
      }
    const Arm7Vector b = hk::bias_torque(m, f, qd, g_A);
    for (int i = 0; i < 7; ++i) {
      worst_b = std::max(worst_b, std::abs(b(i) - mj.d->qfrc_bias[i]));
      max_b = std::max(max_b, std::abs(b(i)));
    }
    // Gravity alone: MuJoCo's bias at rest.
    mj.set(q, Arm7Vector::Zero());
    const Arm7Vector g = hk::gravity_torque(m, f, g_A);
    for (int i = 0; i < 7; ++i) worst_g = std::max(worst_g, std::abs(g(i) - mj.d->qfrc_bias[i]));
    // Full inverse dynamics against mj_inverse.
    mj.set(q, qd);
    for (int i = 0; i < 7; ++i) mj.d->qacc[i] = qdd(i);
    mj_inverse(mj.m.get(), mj.d.get());
    const Arm7Vector tau = hk::inverse_dynamics(m, f, qd, qdd, g_A);
    for (int i = 0; i < 7; ++i) worst_id = std::max(worst_id, std::abs(tau(i) - mj.d->qfrc_inverse[i]));
    // And the identity tau = M qdd + b.
    ASSERT_LT((tau - (Mh * qdd + b)).cwiseAbs().maxCoeff(), 1e-10);
    // M symmetric positive definite.
    ASSERT_GT(Eigen::SelfAdjointEigenSolver<hk::Arm7Matrix>(Mh).eigenvalues().minCoeff(), 0.0);
  }
  std::printf("Arm7 vs MuJoCo, 200 random states: |dM|max %.2e (|M|max %.2f)  |dbias|max %.2e (|bias|max %.1f)  "
              "|dg|max %.2e  |dtau|max %.2e\n",
              worst_M, max_M, worst_b, max_b, worst_g, worst_id);
  EXPECT_LT(worst_M, 1e-9);
  EXPECT_LT(worst_b, 1e-8);
  EXPECT_LT(worst_g, 1e-8);
  EXPECT_LT(worst_id, 1e-8);
}

TEST(Arm7Dynamics, PayloadMatchesMujocoChildBody) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  hk::RigidBodyInertia payload;
  payload.mass = 0.8;
  payload.com = Eigen::Vector3d(0.02, -0.01, 0.09);
  payload.inertia = Eigen::Vector3d(0.004, 0.003, 0.002).asDiagonal();
  const hk::Arm7Model mp = hk::with_payload(m, payload);
  auto mj = hemm::test::make_mj_arm7(m, "0 0 0", "1 0 0 0",
                                     "<body name=\"payload\"><inertial pos=\"0.02 -0.01 0.09\" mass=\"0.8\" "
                                     "diaginertia=\"0.004 0.003 0.002\"/></body>\n");
  std::mt19937_64 rng(14);
  std::vector<mjtNum> M(49);
  for (int k = 0; k < 50; ++k) {
    const Arm7Vector q = random_q(m, rng);
    const Arm7Vector qd = random_vec(rng, 2.0);
    hk::Arm7Frames f;
    hk::forward_kinematics(mp, q, f);
    mj.set(q, qd);
    mj_fullM(mj.m.get(), M.data(), mj.d->qM);
    const hk::Arm7Matrix Mh = hk::mass_matrix(mp, f);
    const Arm7Vector b = hk::bias_torque(mp, f, qd, Eigen::Vector3d(0, 0, -9.81));
    for (int r = 0; r < 7; ++r) {
      ASSERT_NEAR(b(r), mj.d->qfrc_bias[r], 1e-8);
      for (int c = 0; c < 7; ++c) ASSERT_NEAR(Mh(r, c), M[static_cast<size_t>(r * 7 + c)], 1e-9);
    }
  }
}

TEST(Arm7Dynamics, PointMassOnPlanarTwoLinkChainHasTheTextbookForm) {
  // Only a point mass at the flange; joints 2 and 4 bend in the x-z plane
  // (axes -y and +y), the other joints at zero. With l1 = shoulder->elbow and
  // l2 = elbow->flange, about the shoulder: M22 = m (l1^2 + l2^2 + 2 l1 l2 cos q4),
  // M44 = m l2^2, M24 = -m (l2^2 + l1 l2 cos q4) (opposite axes), and the
  // gravity torque is the moment of m g about each axis.
  hk::Arm7Model m = hk::lwr_arm_model();
  for (auto& l : m.link) l = hk::RigidBodyInertia{};
  m.armature.setZero();
  const double mass = 3.0;
  m.link[6].mass = mass;  // at J7's origin, the flange
  const double l1 = 0.4, l2 = 0.39 + 0.078;
  std::mt19937_64 rng(15);
  for (int k = 0; k < 50; ++k) {
    Arm7Vector q = Arm7Vector::Zero();
    q(1) = std::uniform_real_distribution<double>(-2, 2)(rng);
    q(3) = std::uniform_real_distribution<double>(-2, 2)(rng);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    const hk::Arm7Matrix M = hk::mass_matrix(m, f);
    const double c4 = std::cos(q(3));
    EXPECT_NEAR(M(1, 1), mass * (l1 * l1 + l2 * l2 + 2 * l1 * l2 * c4), 1e-12);
    EXPECT_NEAR(M(3, 3), mass * l2 * l2, 1e-12);
    EXPECT_NEAR(M(1, 3), -mass * (l2 * l2 + l1 * l2 * c4), 1e-12);
    // Base vertical (g = -9.81 z in A): holding torque tau = J^T (m 9.81 z);
    // joint 2 (axis -y): (-y x r)_z = r_x; joint 4 (axis +y): (y x r)_z = -r_x.
    const Arm7Vector g = hk::gravity_torque(m, f, Eigen::Vector3d(0, 0, -9.81));
    const double x_e = f.origin(7).x() - f.origin(2).x();
    const double x_4 = f.origin(7).x() - f.origin(4).x();
    EXPECT_NEAR(g(1), mass * 9.81 * x_e, 1e-10);
    EXPECT_NEAR(g(3), -mass * 9.81 * x_4, 1e-10);
    // Rotations about -y by q2 then +y by q4: the planar forward kinematics.
    EXPECT_NEAR(x_e, -(l1 * std::sin(q(1)) + l2 * std::sin(q(1) - q(3))), 1e-12);
  }
}
