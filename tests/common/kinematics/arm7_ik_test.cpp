// The 7-DoF arm's IK and reachability index: round trips from forward
// kinematics of random postures, targets out of reach, the orientation
// sampling's uniformity, and the index against the reach sphere.
#include "common/kinematics/arm7_ik.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

namespace hk = hemm::kinematics;
using hk::Arm7Vector;

TEST(Arm7Ik, ReachesPosesOfRandomPosturesFromTheSeeds) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  const auto seeds = hk::ik_seed_postures(m);
  std::mt19937_64 rng(21);
  int reached = 0, trials = 200;
  for (int k = 0; k < trials; ++k) {
    Arm7Vector q;
    // Postures a bit inside the limits (at a limit the IK may stop short).
    for (int i = 0; i < 7; ++i) q(i) = 0.9 * std::uniform_real_distribution<double>(m.q_min(i), m.q_max(i))(rng);
    const Eigen::Isometry3d T = hk::flange_pose(m, q);
    bool ok = false;
    for (const Arm7Vector& s : seeds) {
      const hk::Arm7IkResult r = hk::inverse_kinematics(m, T, s);
      ASSERT_TRUE(hk::within_limits(m, r.q));
      if (r.converged) {
        // Independently: forward kinematics of the answer.
        const Eigen::Isometry3d Tr = hk::flange_pose(m, r.q);
        ASSERT_LT((Tr.translation() - T.translation()).norm(), 1e-4);
        ASSERT_LT(Eigen::AngleAxisd(Tr.linear() * T.linear().transpose()).angle(), 1e-3);
        ok = true;
        break;
      }
    }
    reached += ok;
  }
  std::printf("IK from 8 seed postures reached %d / %d poses of random postures\n", reached, trials);
  EXPECT_GE(reached, trials * 95 / 100);
}

TEST(Arm7Ik, OutOfReachAndNonFiniteTargetsDoNotConverge) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << 0.5, 0.6, 0.9;  // 1.03 m from the shoulder > 0.868 m reach
  const hk::Arm7IkResult r = hk::inverse_kinematics(m, T, hk::ik_seed_postures(m)[0]);
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(hk::within_limits(m, r.q));
  EXPECT_TRUE(r.q.allFinite());
  T.translation().x() = NAN;
  const hk::Arm7IkResult n = hk::inverse_kinematics(m, T, Arm7Vector::Constant(5.0));
  EXPECT_FALSE(n.converged);
  EXPECT_TRUE(hk::within_limits(m, n.q));
}

TEST(Arm7Reachability, OrientationSamplesAreNearUniform) {
  const auto R = hk::sample_orientations(500);
  ASSERT_EQ(R.size(), 500u);
  // Uniform on SO(3): the mean rotation matrix is zero.
  Eigen::Matrix3d mean = Eigen::Matrix3d::Zero();
  double min_angle = 10;
  for (size_t i = 0; i < R.size(); ++i) {
    ASSERT_NEAR(R[i].norm(), 1.0, 1e-12);
    mean += R[i].toRotationMatrix() / static_cast<double>(R.size());
    for (size_t j = 0; j < i; ++j) min_angle = std::min(min_angle, R[i].angularDistance(R[j]));
  }
  EXPECT_LT(mean.cwiseAbs().maxCoeff(), 0.02);
  // 500 points on SO(3): a random set would have pairs far closer.
  EXPECT_GT(min_angle, 0.1);
}

TEST(Arm7Reachability, IndexIsZeroOutsideTheReachSphereAndHighInsideTheDexterousBand) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  const auto seeds = hk::ik_seed_postures(m);
  const auto R = hk::sample_orientations(24);
  const Eigen::Vector3d shoulder(0, 0, 0.3105);
  // Beyond shoulder->flange reach (0.40 + 0.39 + 0.078 m): nothing.
  const auto far = hk::reachability(m, shoulder + Eigen::Vector3d(0.9, 0, 0), R, seeds);
  EXPECT_EQ(far.sampled, 24);
  EXPECT_EQ(far.reached, 0);
  // The wrist centre must lie 0.395..0.79 m from the shoulder (elbow limit
  // 120 deg .. straight): with the flange 0.60 m out every orientation puts
  // it 0.522..0.678 m away, so reach blocks none; the other joint limits may
  // cut a few.
  const auto mid = hk::reachability(m, shoulder + Eigen::Vector3d(0.42, 0.3, 0.3), R, seeds);
  std::printf("reachability at 0.60 m from the shoulder: %d / %d\n", mid.reached, mid.sampled);
  EXPECT_GE(mid.index(), 0.75);
}
