// The hand -> remote arm mapping against closed forms: the alignment and the
// scale, indexing (the commanded pose continuous across a dead-man press and
// across the clutch button), rotation composition, the rate clamp, the grip
// lever and the dead-man.
#include "operator/telemanip/arm_mapping.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace tele = hemm::op::telemanip;

namespace {

// The robot faces the operator: D's x (forward from the operator) is A's -x.
Eigen::Matrix3d mapping_test_R_A_D() { return Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

Eigen::Isometry3d mapping_test_pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  T.linear() = R;
  return T;
}

tele::HandReading mapping_test_hand(const Eigen::Isometry3d& T, bool deadman) {
  tele::HandReading h;
  h.T_D_E = T;
  h.deadman = deadman;
  return h;
}

// Big clamps: the tests of the mapping itself are not the clamp's.
tele::ArmMappingParams mapping_test_params(double scale) {
  tele::ArmMappingParams p;
  p.R_A_D = mapping_test_R_A_D();
  p.translation_scale = scale;
  p.max_step_m = 0.1;
  p.max_step_rad = 1.0;
  return p;
}

const Eigen::Isometry3d kMappingTestG0 =
    mapping_test_pose(Eigen::Vector3d(0.7, -0.25, 0.95), Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix());

}  // namespace

TEST(ArmMapping, TranslationIsScaledAndAligned) {
  for (double scale : {1.0, 0.5, 2.5}) {
    const tele::ArmMappingParams p = mapping_test_params(scale);
    ASSERT_EQ(tele::validate(p), "");
    tele::ArmMappingState s;
    tele::reset_arm_mapping(&s, kMappingTestG0);
    tele::ArmCommandOut out;
    const Eigen::Isometry3d hand0 = mapping_test_pose(Eigen::Vector3d(0.4, 0.1, 0.3), Eigen::Matrix3d::Identity());
    tele::map_arm_step(p, mapping_test_hand(hand0, true), &s, &out);
    ASSERT_TRUE(out.pressed);
    EXPECT_TRUE(out.T_A_G.isApprox(kMappingTestG0, 1e-12));  // pressing does not move the arm
    // The hand 2 cm forward (D +x), 5 mm left (+y), 1 cm up: in A (turned by pi
    // about z) that is (-0.02, -0.005, +0.01) times the scale (within one step's clamp).
    Eigen::Isometry3d hand1 = hand0;
    hand1.translation() += Eigen::Vector3d(0.02, 0.005, 0.01);
    tele::map_arm_step(p, mapping_test_hand(hand1, true), &s, &out);
    EXPECT_FALSE(out.clamped);
    const Eigen::Vector3d want = kMappingTestG0.translation() + scale * Eigen::Vector3d(-0.02, -0.005, 0.01);
    EXPECT_LT((out.T_A_G.translation() - want).norm(), 1e-12) << scale;
    EXPECT_TRUE(out.T_A_G.linear().isApprox(kMappingTestG0.linear(), 1e-12));  // a pure translation
  }
}

TEST(ArmMapping, IndexingKeepsTheRemotePoseContinuousAcrossAClutch) {
  const tele::ArmMappingParams p = mapping_test_params(1.0);
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  Eigen::Isometry3d hand = mapping_test_pose(Eigen::Vector3d(0.3, 0.0, 0.2), Eigen::Matrix3d::Identity());
  const Eigen::Vector3d step_D(0.05, 0.0, 0.0);
  // Press, 5 cm forward.
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  hand.translation() += step_D;
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  const Eigen::Isometry3d after_first = out.T_A_G;
  // Release, hand back 5 cm: the arm holds.
  hand.translation() -= step_D;
  tele::map_arm_step(p, mapping_test_hand(hand, false), &s, &out);
  EXPECT_FALSE(out.pressed);
  EXPECT_TRUE(out.T_A_G.isApprox(after_first, 1e-15));
  // Press again: no jump (the old anchor would have put the arm back at G0).
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  EXPECT_TRUE(out.pressed);
  EXPECT_TRUE(out.T_A_G.isApprox(after_first, 1e-15));
  EXPECT_EQ(s.presses, 2u);
  // 5 cm forward again: 10 cm in total (A's -x), with the hand only 5 cm from where it began.
  hand.translation() += step_D;
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  const Eigen::Vector3d want = kMappingTestG0.translation() + Eigen::Vector3d(-0.10, 0.0, 0.0);
  EXPECT_LT((out.T_A_G.translation() - want).norm(), 1e-12);
}

// The clutch button: held with the dead-man pressed, the arm keeps its
// pose (still pressed: the robot sees one steady pose) while the hand goes
// back; at its release the mapping re-anchors without a jump; a clutch
// reading on a mapping without a clutch button changes nothing.
TEST(ArmMapping, ClutchHoldsTheArmPressedWhileTheHandGoesBack) {
  tele::ArmMappingParams p = mapping_test_params(2.0);
  p.clutch_button = 1;
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  Eigen::Isometry3d hand = mapping_test_pose(Eigen::Vector3d(0.3, 0.0, 0.2), Eigen::Matrix3d::Identity());
  const Eigen::Vector3d step_D(0.04, 0.01, -0.02);
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  hand.translation() += step_D;
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  const Eigen::Isometry3d after_first = out.T_A_G;
  EXPECT_LT((after_first.translation() - (kMappingTestG0.translation() + 2.0 * Eigen::Vector3d(-0.04, -0.01, -0.02))).norm(), 1e-12);
  // Clutched: the hand back where it began (and turned), the arm holds, pressed.
  tele::HandReading clutched = mapping_test_hand(hand, true);
  clutched.clutch = true;
  for (int k = 0; k < 4; ++k) {
    clutched.T_D_E.translation() -= step_D / 4.0;
    clutched.T_D_E.linear() = Eigen::AngleAxisd(0.1 * (k + 1), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    tele::map_arm_step(p, clutched, &s, &out);
    EXPECT_TRUE(out.pressed);
    EXPECT_TRUE(out.clutched);
    EXPECT_FALSE(s.engaged);
    EXPECT_TRUE(out.T_A_G.isApprox(after_first, 1e-15));
  }
  EXPECT_EQ(s.clutch_steps, 4u);
  // Released: no jump, then the same hand motion moves the arm on from there.
  hand = clutched.T_D_E;
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  EXPECT_FALSE(out.clutched);
  EXPECT_TRUE(out.T_A_G.isApprox(after_first, 1e-15));
  EXPECT_EQ(s.presses, 2u);
  hand.translation() += step_D;
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  EXPECT_LT((out.T_A_G.translation() - (kMappingTestG0.translation() + 4.0 * Eigen::Vector3d(-0.04, -0.01, -0.02))).norm(), 1e-12);
  EXPECT_TRUE(out.T_A_G.linear().isApprox(after_first.linear(), 1e-12));  // the hand's turn while clutched is not the arm's
  // The clutch does not act without the dead-man: released is released.
  clutched = mapping_test_hand(hand, false);
  clutched.clutch = true;
  tele::map_arm_step(p, clutched, &s, &out);
  EXPECT_FALSE(out.pressed);
  EXPECT_FALSE(out.clutched);
  // No clutch button configured: a clutch reading is ignored.
  tele::ArmMappingParams none = mapping_test_params(2.0);
  tele::ArmMappingState s2;
  tele::reset_arm_mapping(&s2, kMappingTestG0);
  clutched = mapping_test_hand(hand, true);
  tele::map_arm_step(none, clutched, &s2, &out);
  clutched.clutch = true;
  clutched.T_D_E.translation() += step_D;
  tele::map_arm_step(none, clutched, &s2, &out);
  EXPECT_FALSE(out.clutched);
  EXPECT_TRUE(s2.engaged);
  EXPECT_LT((out.T_A_G.translation() - (kMappingTestG0.translation() + 2.0 * Eigen::Vector3d(-0.04, -0.01, -0.02))).norm(), 1e-12);
}

TEST(ArmMapping, RotationsComposeAboutTheGraspFrameAsRotations) {
  const tele::ArmMappingParams p = mapping_test_params(1.0);
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  const Eigen::Matrix3d R_D0 = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).toRotationMatrix();  // the hand's grasp
  const Eigen::Vector3d p_D(0.3, 0.1, 0.2);
  tele::map_arm_step(p, mapping_test_hand(mapping_test_pose(p_D, R_D0), true), &s, &out);
  // Two turns of the hand in D: 0.3 rad about D's z, then 0.2 rad about D's x.
  const Eigen::Matrix3d turn1 = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d turn2 = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  tele::map_arm_step(p, mapping_test_hand(mapping_test_pose(p_D, turn1 * R_D0), true), &s, &out);
  tele::map_arm_step(p, mapping_test_hand(mapping_test_pose(p_D, turn2 * turn1 * R_D0), true), &s, &out);
  // Closed form: D's z is A's z (a turn about it is the same turn in A); D's x is A's -x.
  const Eigen::Matrix3d turn1_A = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d turn2_A = Eigen::AngleAxisd(0.2, -Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d want = turn2_A * turn1_A * kMappingTestG0.linear();
  EXPECT_TRUE(out.T_A_G.linear().isApprox(want, 1e-12));
  EXPECT_NEAR(out.T_A_G.linear().determinant(), 1.0, 1e-12);
  EXPECT_TRUE((out.T_A_G.linear() * out.T_A_G.linear().transpose()).isIdentity(1e-12));
  // A turn about the hand's own point leaves G's origin where it was.
  EXPECT_LT((out.T_A_G.translation() - kMappingTestG0.translation()).norm(), 1e-12);
}

TEST(ArmMapping, HandPoseIsTheMappingsInverse) {
  const tele::ArmMappingParams p = mapping_test_params(1.7);
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  tele::map_arm_step(p, mapping_test_hand(mapping_test_pose(Eigen::Vector3d(0.2, -0.3, 0.1),
                                                          Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitX()).toRotationMatrix()),
                                        true),
                   &s, &out);
  const Eigen::Isometry3d goal_A = mapping_test_pose(
      Eigen::Vector3d(0.65, -0.2, 1.0), Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -0.5, 0.3).normalized()).toRotationMatrix());
  const Eigen::Isometry3d hand = tele::hand_pose_D(p, s, goal_A);
  EXPECT_TRUE(tele::mapped_pose_A(p, s, hand).isApprox(goal_A, 1e-12));
}

// Rotation scale k: the hand's turn, about the same axis (in A's axes), k
// times as far; the inverse turns the hand 1/k of the goal's turn; a hand
// turned back to where it was pressed gives the anchor's orientation.
TEST(ArmMapping, RotationScaleTurnsTheGripperKTimesAboutTheSameAxis) {
  for (double k : {0.5, 2.0, 3.0}) {
    tele::ArmMappingParams p = mapping_test_params(1.0);
    p.rotation_scale = k;
    ASSERT_EQ(tele::validate(p), "");
    tele::ArmMappingState s;
    tele::reset_arm_mapping(&s, kMappingTestG0);
    tele::ArmCommandOut out;
    const Eigen::Matrix3d R_D0 = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Vector3d p_D(0.3, 0.1, 0.2);
    tele::map_arm_step(p, mapping_test_hand(mapping_test_pose(p_D, R_D0), true), &s, &out);
    const Eigen::Vector3d axis_D = Eigen::Vector3d(0.3, -1.0, 0.5).normalized();
    const double turn = 0.25;
    const Eigen::Matrix3d R_D1 = Eigen::AngleAxisd(turn, axis_D).toRotationMatrix() * R_D0;
    const Eigen::Isometry3d got = tele::mapped_pose_A(p, s, mapping_test_pose(p_D, R_D1));
    // D's axes in A: x and y flip, z stays.
    const Eigen::Vector3d axis_A = p.R_A_D * axis_D;
    const Eigen::Matrix3d want = Eigen::AngleAxisd(k * turn, axis_A).toRotationMatrix() * kMappingTestG0.linear();
    EXPECT_TRUE(got.linear().isApprox(want, 1e-12)) << "k " << k;
    EXPECT_LT((got.translation() - kMappingTestG0.translation()).norm(), 1e-12);
    // The inverse: a goal turned 0.6 rad needs the hand turned 0.6 / k.
    const Eigen::Isometry3d goal_A = mapping_test_pose(
        kMappingTestG0.translation(),
        Eigen::AngleAxisd(0.6, Eigen::Vector3d(1.0, 0.2, -0.4).normalized()).toRotationMatrix() * kMappingTestG0.linear());
    const Eigen::Isometry3d hand = tele::hand_pose_D(p, s, goal_A);
    EXPECT_NEAR(Eigen::AngleAxisd(hand.linear() * R_D0.transpose()).angle(), 0.6 / k, 1e-12) << "k " << k;
    EXPECT_TRUE(tele::mapped_pose_A(p, s, hand).isApprox(goal_A, 1e-12)) << "k " << k;
    // Back where it was pressed: the anchor's orientation.
    EXPECT_TRUE(tele::mapped_pose_A(p, s, mapping_test_pose(p_D, R_D0)).linear().isApprox(kMappingTestG0.linear(), 1e-12));
  }
}

TEST(ArmMapping, RateClampLimitsEachStep) {
  tele::ArmMappingParams p = mapping_test_params(1.0);
  p.max_step_m = 0.002;
  p.max_step_rad = 0.01;
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  Eigen::Isometry3d hand = mapping_test_pose(Eigen::Vector3d(0.3, 0.0, 0.2), Eigen::Matrix3d::Identity());
  tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
  // A 2.9 cm yank and a 0.1 rad turn in one sample.
  hand.translation() += Eigen::Vector3d(0.0, 0.029, 0.0);
  hand.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d dir_A(0.0, -1.0, 0.0);
  for (int k = 1; k <= 15; ++k) {
    tele::map_arm_step(p, mapping_test_hand(hand, true), &s, &out);
    const Eigen::Vector3d moved = out.T_A_G.translation() - kMappingTestG0.translation();
    EXPECT_LT((moved - dir_A * std::min(0.002 * k, 0.029)).norm(), 1e-12) << k;
    const double turned = Eigen::Quaterniond(out.T_A_G.linear()).angularDistance(Eigen::Quaterniond(kMappingTestG0.linear()));
    EXPECT_NEAR(turned, std::min(0.01 * k, 0.1), 1e-9) << k;
    EXPECT_EQ(out.clamped, k < 15);
  }
}

TEST(ArmMapping, DeadManReleasedPressesNothingAndHoldsTheCommand) {
  const tele::ArmMappingParams p = mapping_test_params(1.0);
  tele::ArmMappingState s;
  tele::ArmCommandOut out;
  // Not initialized yet (no robot state): nothing pressed, whatever the hand does.
  tele::map_arm_step(p, mapping_test_hand(Eigen::Isometry3d::Identity(), true), &s, &out);
  EXPECT_FALSE(out.pressed);
  tele::reset_arm_mapping(&s, kMappingTestG0);
  Eigen::Isometry3d hand = mapping_test_pose(Eigen::Vector3d(0.3, 0.0, 0.2), Eigen::Matrix3d::Identity());
  for (int k = 0; k < 10; ++k) {
    hand.translation().z() += 0.01;
    tele::map_arm_step(p, mapping_test_hand(hand, false), &s, &out);
    EXPECT_FALSE(out.pressed);
    EXPECT_TRUE(out.T_A_G.isApprox(kMappingTestG0, 1e-15));
  }
  // An invalid reading with the dead-man held counts as released.
  tele::HandReading bad = mapping_test_hand(hand, true);
  bad.valid = false;
  tele::map_arm_step(p, bad, &s, &out);
  EXPECT_FALSE(out.pressed);
  EXPECT_EQ(s.presses, 0u);
}

TEST(ArmMapping, GripLeverGivesOpeningAndForceLinearly) {
  tele::ArmMappingParams p;
  p.grip_travel_m = 0.025;
  p.opening_open_m = 0.12;
  p.opening_closed_m = 0.02;
  p.force_open_n = 4.0;
  p.force_closed_n = 44.0;
  double o = 0, f = 0;
  tele::grip_to_gripper(p, 0.0, &o, &f);
  EXPECT_DOUBLE_EQ(o, 0.12);
  EXPECT_DOUBLE_EQ(f, 4.0);
  tele::grip_to_gripper(p, 0.01, &o, &f);  // 40 % of the travel
  EXPECT_NEAR(o, 0.12 - 0.4 * 0.10, 1e-15);
  EXPECT_NEAR(f, 4.0 + 0.4 * 40.0, 1e-12);
  tele::grip_to_gripper(p, 0.05, &o, &f);  // past the travel: closed
  EXPECT_DOUBLE_EQ(o, 0.02);
  EXPECT_DOUBLE_EQ(f, 44.0);
  tele::grip_to_gripper(p, NAN, &o, &f);  // a broken reading: open
  EXPECT_DOUBLE_EQ(o, 0.12);
  // Through a step: only a handle with a lever commands the gripper.
  tele::ArmMappingState s;
  tele::reset_arm_mapping(&s, kMappingTestG0);
  tele::ArmCommandOut out;
  tele::HandReading h = mapping_test_hand(Eigen::Isometry3d::Identity(), true);
  tele::map_arm_step(p, h, &s, &out);
  EXPECT_FALSE(out.has_gripper);
  h.has_grip = true;
  h.grip_position_m = 0.025;
  tele::map_arm_step(p, h, &s, &out);
  EXPECT_TRUE(out.has_gripper);
  EXPECT_DOUBLE_EQ(out.opening_m, 0.02);
}

TEST(ArmMapping, BadParametersAreRefused) {
  tele::ArmMappingParams p;
  EXPECT_EQ(tele::validate(p), "");
  tele::ArmMappingParams reflect = p;
  reflect.R_A_D = Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal();  // orthonormal but a mirror
  EXPECT_NE(tele::validate(reflect), "");
  tele::ArmMappingParams scale = p;
  scale.translation_scale = 0.0;
  EXPECT_NE(tele::validate(scale), "");
  scale.translation_scale = NAN;
  EXPECT_NE(tele::validate(scale), "");
  for (double k : {0.0, 0.2, 4.5, double(NAN)}) {
    tele::ArmMappingParams rot = p;
    rot.rotation_scale = k;
    EXPECT_EQ(tele::validate(rot).rfind("rotation_scale: must be in [0.25, 4]", 0), 0u) << k;
  }
  // The ranges' ends are allowed (one check for the mapping, the direct mode and the config).
  EXPECT_EQ(tele::check_scales(10.0, 0.25), "");
  EXPECT_EQ(tele::check_scales(1e-3, 4.0), "");
  EXPECT_EQ(tele::check_scales(10.5, 1.0), "translation_scale: must be in (0, 10]");
  tele::ArmMappingParams step = p;
  step.max_step_m = -1.0;
  EXPECT_NE(tele::validate(step), "");
  tele::ArmMappingParams ee = p;
  ee.deadman_ee = 2;
  EXPECT_NE(tele::validate(ee), "");
  tele::ArmMappingParams force = p;
  force.force_closed_n = -3.0;
  EXPECT_NE(tele::validate(force), "");
  for (int b : {-1, 9}) {
    tele::ArmMappingParams clutch = p;
    clutch.clutch_button = b;
    EXPECT_EQ(tele::validate(clutch), "clutch_button must be 0 (none) or a button 1-8") << b;
  }
}
