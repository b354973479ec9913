// The rig: the left arm mirrors the right one (frames and capsules), home
// postures keep away from the limits and from the table, validation.
#include "operator/device/bimanual/rig.h"

#include <random>

#include <gtest/gtest.h>

#include "operator/device/bimanual/collision.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

TEST(Rig, LeftArmIsTheMirrorImageOfTheRight) {
  const hb::RigGeometry rig = hb::default_rig();
  ASSERT_FALSE(hb::validate(rig));
  const Eigen::Matrix3d M = Eigen::Vector3d(1, -1, 1).asDiagonal();
  std::mt19937_64 rng(51);
  for (int k = 0; k < 100; ++k) {
    hk::Arm7Vector q;
    for (int i = 0; i < 7; ++i) q(i) = std::uniform_real_distribution<double>(rig.arm.q_min(i), rig.arm.q_max(i))(rng);
    hk::Arm7Frames fr, fl;
    hk::forward_kinematics(rig.arm, q, fr);
    hk::forward_kinematics(rig.arm, hb::mirror_posture(q), fl);
    for (int i = 1; i <= 7; ++i) {
      const Eigen::Vector3d pr = rig.T_D_A[0] * fr.origin(i), pl = rig.T_D_A[1] * fl.origin(i);
      ASSERT_LT((pl - M * pr).norm(), 1e-12) << "joint " << i;
    }
  }
  // Right arm at -y, joint axes pointing outwards.
  EXPECT_LT(rig.T_D_A[0].translation().y(), 0.0);
  EXPECT_GT((rig.T_D_A[0].linear() * Eigen::Vector3d::UnitZ()).dot(-Eigen::Vector3d::UnitY()), 0.99);
  EXPECT_GT((rig.T_D_A[1].linear() * Eigen::Vector3d::UnitZ()).dot(Eigen::Vector3d::UnitY()), 0.99);
  EXPECT_NEAR(rig.T_D_A[1].linear().determinant(), 1.0, 1e-12);
}

TEST(Rig, HomePosturesAreClearOfLimitsTableAndEachOther) {
  const hb::RigGeometry rig = hb::default_rig();
  std::array<hk::Arm7Frames, 2> f;
  std::array<hb::ArmCapsules, 2> caps;
  for (int a = 0; a < 2; ++a) {
    const auto side = static_cast<hb::ArmSide>(a);
    const hk::Arm7Vector q = rig.home(side);
    EXPECT_GT(std::min((q - rig.arm.q_min).minCoeff(), (rig.arm.q_max - q).minCoeff()), 0.6);
    hk::forward_kinematics(rig.arm, q, f[static_cast<size_t>(a)]);
    caps[static_cast<size_t>(a)] = hb::arm_capsules(rig, side, hb::handle_spec(hb::HandleKind::kJoystick), f[static_cast<size_t>(a)]);
  }
  hb::CollisionResult r;
  hb::collision_avoidance(rig, hb::CollisionParams{}, caps, f, {hk::Arm7Vector::Zero(), hk::Arm7Vector::Zero()}, r);
  EXPECT_EQ(r.count, 0);  // nothing within the avoidance's reach at home
  EXPECT_GT(r.min_arm_table_m, hb::CollisionParams{}.activation_m);
}

TEST(Rig, ValidateRejectsBadGeometry) {
  auto bad = [](auto mutate) {
    hb::RigGeometry r = hb::default_rig();
    mutate(r);
    return hb::validate(r).has_value();
  };
  EXPECT_FALSE(bad([](hb::RigGeometry&) {}));
  EXPECT_TRUE(bad([](hb::RigGeometry& r) { r.T_D_A[0].linear() *= 2.0; }));
  EXPECT_TRUE(bad([](hb::RigGeometry& r) { r.table.max_D.z() = r.table.min_D.z(); }));
  EXPECT_TRUE(bad([](hb::RigGeometry& r) { r.link_radius(3) = -0.1; }));
  EXPECT_TRUE(bad([](hb::RigGeometry& r) { r.home_right(1) = 3.0; }));
  EXPECT_TRUE(bad([](hb::RigGeometry& r) { r.arm.link[2].mass = NAN; }));
}
