// The held object's weight and two-hand coupling (held_object.h) against
// closed forms: the felt weight's bounded rate and its end value, the
// coupling's spring and damper, no force for a rigid motion of both grasps,
// the clamp, a new hold re-anchoring, and bad input changing nothing.
#include "operator/telemanip/held_object.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/math/frames.h"

namespace hemm::op::telemanip {
namespace {

constexpr double kDt = 1e-3;

Eigen::Isometry3d held_pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  return hemm::math::make_transform(R, p);
}

HeldObjectInputs both_holding(const Eigen::Isometry3d& T0, const Eigen::Isometry3d& T1) {
  HeldObjectInputs in;
  in.remote_valid = true;
  in.pressed = {true, true};
  in.holding = {true, true};
  in.T_A_G = {T0, T1};
  return in;
}

// The coupling alone (no weight).
struct CouplingRun {
  HeldObjectParams p;
  HeldObjectState s;
  HeldObjectWrench w;
  CouplingRun() { p.weight = false; }
  // Both grasps take hold of a box 0.30 m long at its ends (G0 at the -y
  // end); returns G0's pose.
  Eigen::Isometry3d hold_a_box() {
    const Eigen::Isometry3d T0 = held_pose({0.6, -0.15, 0.9});
    held_object_step(p, both_holding(T0, held_pose({0.6, 0.15, 0.9})), kDt, &s, &w);
    return T0;
  }
};

TEST(HeldObject, FeltWeightFollowsTheMeasuredLoadAtABoundedRateAndFadesWhenLetGo) {
  HeldObjectParams p;
  p.coupling = false;
  HeldObjectState s;
  HeldObjectInputs in;
  in.remote_valid = true;
  in.pressed = {true, true};
  in.holding = {true, false};  // the right holds, the left does not
  in.remote_force_A[0] = Eigen::Vector3d(0.3, -0.2, -9.81);  // 1 kg hangs from the right gripper
  in.remote_force_A[1] = Eigen::Vector3d(0.0, 0.0, -5.0);    // the left reads a load but holds nothing
  HeldObjectWrench w;
  double prev = 0.0, max_step = 0.0;
  for (int i = 0; i < 3000; ++i) {
    held_object_step(p, in, kDt, &s, &w);
    max_step = std::max(max_step, std::abs(s.weight_n[0] - prev));
    prev = s.weight_n[0];
    EXPECT_DOUBLE_EQ(w.force_A[0].z(), -s.weight_n[0]);
    EXPECT_DOUBLE_EQ(w.force_A[0].x(), 0.0);  // the weight only: down
    EXPECT_EQ(w.force_A[1], Eigen::Vector3d::Zero());
  }
  EXPECT_LE(max_step, p.weight_rate_n_per_s * kDt + 1e-12);  // no steps
  EXPECT_NEAR(s.weight_n[0], 9.81, 1e-3);                   // 3 s: rate and filter have settled
  // Let go: it fades at the same rate, to nothing.
  in.holding[0] = false;
  const double held = s.weight_n[0];
  held_object_step(p, in, kDt, &s, &w);
  EXPECT_NEAR(s.weight_n[0], held - p.weight_rate_n_per_s * kDt, 1e-12);
  for (int i = 0; i < 1000; ++i) held_object_step(p, in, kDt, &s, &w);
  EXPECT_EQ(s.weight_n[0], 0.0);
  EXPECT_EQ(w.force_A[0], Eigen::Vector3d::Zero());
  EXPECT_EQ(s.holds, 0u);  // one hand never couples
}

TEST(HeldObject, AnUpwardPushIsNotAWeightAndTheWeightIsClamped) {
  HeldObjectParams p;
  p.coupling = false;
  p.max_weight_n = 12.0;
  HeldObjectState s;
  HeldObjectInputs in;
  in.remote_valid = true;
  in.pressed = {true, true};
  in.holding = {true, true};
  in.remote_force_A[0] = Eigen::Vector3d(0, 0, 20.0);   // pressed on a support from below
  in.remote_force_A[1] = Eigen::Vector3d(0, 0, -50.0);  // far beyond the clamp
  HeldObjectWrench w;
  for (int i = 0; i < 5000; ++i) held_object_step(p, in, kDt, &s, &w);
  EXPECT_EQ(s.weight_n[0], 0.0);
  EXPECT_NEAR(s.weight_n[1], 12.0, 1e-6);
}

TEST(HeldObject, CouplingIsASpringAndDamperBetweenTheGraspsWithASqueezeSign) {
  CouplingRun r;
  const HeldObjectParams& p = r.p;
  HeldObjectState& s = r.s;
  HeldObjectWrench& w = r.w;
  // A box 0.30 m long held at its ends, G0 turned 0.4 rad about z: the
  // spring acts in A whatever the grasps' orientations.
  const Eigen::Matrix3d R0 = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d p0(0.6, -0.15, 0.9), p1(0.6, 0.15, 0.9);
  held_object_step(p, both_holding(held_pose(p0, R0), held_pose(p1)), kDt, &s, &w);
  EXPECT_TRUE(s.both_held);
  EXPECT_EQ(s.holds, 1u);
  EXPECT_LT(w.force_A[1].norm(), 1e-12);  // the hold starts unstrained
  // The right hand 1 cm nearer the left, held there: the spring pushes the hands apart.
  const Eigen::Vector3d p1n = p1 - Eigen::Vector3d(0, 0.01, 0);
  held_object_step(p, both_holding(held_pose(p0, R0), held_pose(p1n)), kDt, &s, &w);
  // The first step of the move also sees its speed: 1 cm in 1 ms.
  EXPECT_NEAR(w.force_A[1].y(), std::min(p.max_force_n, 300.0 * 0.01 + 10.0 * 10.0), 1e-9);
  held_object_step(p, both_holding(held_pose(p0, R0), held_pose(p1n)), kDt, &s, &w);
  EXPECT_NEAR(w.force_A[1].y(), p.stiffness_n_per_m * 0.01, 1e-9);  // at rest: the spring alone
  EXPECT_NEAR(w.force_A[1].x(), 0.0, 1e-12);
  EXPECT_NEAR(w.force_A[1].z(), 0.0, 1e-12);
  EXPECT_NEAR((w.force_A[0] + w.force_A[1]).norm(), 0.0, 1e-12);  // internal: equal and opposite
  EXPECT_NEAR(w.squeeze_n, p.stiffness_n_per_m * 0.01, 1e-9);       // squeezed: positive
  // Pulled 2 cm apart: a stretch, negative.
  const Eigen::Vector3d p1f = p1 + Eigen::Vector3d(0, 0.02, 0);
  for (int i = 0; i < 2; ++i) held_object_step(p, both_holding(held_pose(p0, R0), held_pose(p1f)), kDt, &s, &w);
  EXPECT_NEAR(w.squeeze_n, -p.stiffness_n_per_m * 0.02, 1e-9);
  EXPECT_NEAR(s.peak_squeeze_n, std::min(p.max_force_n, 300.0 * 0.03 + 10.0 * 30.0), 1e-9);  // the step's damper
}

TEST(HeldObject, ARigidMotionOfBothGraspsIsNotFelt) {
  CouplingRun r;
  const HeldObjectParams& p = r.p;
  HeldObjectState& s = r.s;
  HeldObjectWrench& w = r.w;
  const Eigen::Isometry3d T0 = held_pose({0.6, -0.15, 0.9}, Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()).toRotationMatrix());
  const Eigen::Isometry3d T1 = held_pose({0.62, 0.14, 0.93}, Eigen::AngleAxisd(-1.0, Eigen::Vector3d::UnitX()).toRotationMatrix());
  held_object_step(p, both_holding(T0, T1), kDt, &s, &w);
  // The object carried 10 cm up and across, turned 0.3 rad about an oblique axis,
  // over 300 steps: the grasps move as one body.
  for (int i = 1; i <= 300; ++i) {
    const double f = i / 300.0;
    Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
    M.linear() = Eigen::AngleAxisd(0.3 * f, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    M.translation() = f * Eigen::Vector3d(0.05, -0.05, 0.07);
    held_object_step(p, both_holding(M * T0, M * T1), kDt, &s, &w);
    ASSERT_LT(w.force_A[1].norm(), 1e-9) << i;
    ASSERT_LT(w.torque_A[1].norm(), 1e-9) << i;
  }
}

TEST(HeldObject, ARelativeTurnIsPulledBackAndTheWrenchIsClamped) {
  CouplingRun r;
  const HeldObjectParams& p = r.p;
  HeldObjectState& s = r.s;
  HeldObjectWrench& w = r.w;
  const Eigen::Isometry3d T0 = r.hold_a_box();
  // G1 turned 0.1 rad about x_A about its own origin: a torque back, no force.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix();
  held_object_step(p, both_holding(T0, held_pose({0.6, 0.15, 0.9}, R)), kDt, &s, &w);
  EXPECT_NEAR(w.torque_A[1].x(), -p.rot_stiffness_nm_per_rad * 0.1, 1e-9);
  EXPECT_NEAR(w.torque_A[0].x(), p.rot_stiffness_nm_per_rad * 0.1, 1e-9);
  EXPECT_LT(w.force_A[1].norm(), 1e-12);
  // 1 rad and 20 cm: clamped to the limits.
  const Eigen::Matrix3d R1 = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (int i = 0; i < 2; ++i) held_object_step(p, both_holding(T0, held_pose({0.6, 0.35, 0.9}, R1)), kDt, &s, &w);
  EXPECT_NEAR(w.force_A[1].norm(), p.max_force_n, 1e-9);
  EXPECT_NEAR(w.torque_A[1].norm(), p.max_torque_nm, 1e-9);
}

TEST(HeldObject, AFlickeringHoldFadesAndResumesALetGoEndsAndANewHoldStartsFromWhereTheHandsAre) {
  CouplingRun r;
  const HeldObjectParams& p = r.p;
  HeldObjectState& s = r.s;
  HeldObjectWrench& w = r.w;
  const Eigen::Isometry3d T0 = r.hold_a_box();
  // Squeezed by 1 cm and held there.
  HeldObjectInputs in = both_holding(T0, held_pose({0.6, 0.14, 0.9}));
  for (int i = 0; i < 2; ++i) held_object_step(p, in, kDt, &s, &w);
  const double spring = p.stiffness_n_per_m * 0.01;
  ASSERT_NEAR(w.squeeze_n, spring, 1e-9);
  // The left's holding flag drops for 50 ms: the coupling fades, no step...
  in.holding[1] = false;
  held_object_step(p, in, kDt, &s, &w);
  EXPECT_TRUE(s.both_held);
  EXPECT_NEAR(w.squeeze_n, spring * (1.0 - kDt / p.coupling_fade_s), 1e-9);
  for (int i = 1; i < 50; ++i) held_object_step(p, in, kDt, &s, &w);
  EXPECT_NEAR(w.squeeze_n, spring * (1.0 - 0.05 / p.coupling_fade_s), 1e-6);
  // ...and back, the same hold goes on from its anchor, at full strength.
  in.holding[1] = true;
  held_object_step(p, in, kDt, &s, &w);
  EXPECT_EQ(s.holds, 1u);
  EXPECT_NEAR(w.squeeze_n, spring, 1e-9);
  // Let go for longer than the fade: it ends.
  in.holding[1] = false;
  const int fade_steps = static_cast<int>(std::ceil(p.coupling_fade_s / kDt));
  for (int i = 0; i < fade_steps + 1; ++i) held_object_step(p, in, kDt, &s, &w);
  EXPECT_FALSE(s.both_held);
  EXPECT_EQ(w.force_A[1], Eigen::Vector3d::Zero());
  // The left's hand moved 5 cm meanwhile and takes hold again there: no strain.
  in.T_A_G[1] = held_pose({0.6, 0.10, 0.9});
  in.holding[1] = true;
  for (int i = 0; i < 3; ++i) held_object_step(p, in, kDt, &s, &w);
  EXPECT_EQ(s.holds, 2u);
  EXPECT_LT(w.force_A[1].norm(), 1e-12);
  // Strained again, then the dead-man released on one hand: it ends at once,
  // as every displayed force does; so does a lost remote state.
  in.T_A_G[1] = held_pose({0.6, 0.09, 0.9});
  for (int i = 0; i < 2; ++i) held_object_step(p, in, kDt, &s, &w);
  ASSERT_GT(w.squeeze_n, 0.5 * spring);
  in.pressed[0] = false;
  held_object_step(p, in, kDt, &s, &w);
  EXPECT_FALSE(s.both_held);
  EXPECT_EQ(w.force_A[1], Eigen::Vector3d::Zero());
  in.pressed[0] = true;
  held_object_step(p, in, kDt, &s, &w);  // a new hold, unstrained
  EXPECT_EQ(s.holds, 3u);
  in.remote_valid = false;
  held_object_step(p, in, kDt, &s, &w);
  EXPECT_FALSE(s.both_held);
  EXPECT_EQ(w.force_A[1], Eigen::Vector3d::Zero());
}

TEST(HeldObject, BadInputGivesNoWrenchAndChangesNothing) {
  HeldObjectParams p;
  HeldObjectState s;
  HeldObjectWrench w;
  HeldObjectInputs in = both_holding(held_pose({0.6, -0.15, 0.9}), held_pose({0.6, 0.15, 0.9}));
  in.remote_force_A = {Eigen::Vector3d(0, 0, -9.81), Eigen::Vector3d(0, 0, -9.81)};
  for (int i = 0; i < 100; ++i) held_object_step(p, in, kDt, &s, &w);
  const HeldObjectState before = s;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int bad = 0; bad < 3; ++bad) {
    HeldObjectInputs b = in;
    if (bad == 0) b.T_A_G[1].translation().x() = nan;
    if (bad == 1) b.remote_force_A[0].z() = std::numeric_limits<double>::infinity();
    held_object_step(p, b, bad == 2 ? nan : kDt, &s, &w);
    EXPECT_EQ(w.force_A[0], Eigen::Vector3d::Zero()) << bad;
    EXPECT_EQ(w.torque_A[1], Eigen::Vector3d::Zero()) << bad;
    EXPECT_EQ(s.weight_n, before.weight_n) << bad;
    EXPECT_EQ(s.held_ticks, before.held_ticks) << bad;
    EXPECT_EQ(s.load_filtered_n, before.load_filtered_n) << bad;
  }
}

TEST(HeldObject, ValidateNamesWhatIsWrong) {
  EXPECT_EQ(validate(HeldObjectParams{}), "");
  HeldObjectParams p;
  p.stiffness_n_per_m = -1.0;
  EXPECT_NE(validate(p).find("stiffness"), std::string::npos);
  p = HeldObjectParams{};
  p.max_torque_nm = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(validate(p), "");
  p = HeldObjectParams{};
  p.weight_filter_s = 0.0;
  EXPECT_NE(validate(p).find("filter"), std::string::npos);
  p = HeldObjectParams{};
  p.weight_rate_n_per_s = 0.0;
  EXPECT_NE(validate(p).find("rate"), std::string::npos);
  p = HeldObjectParams{};
  p.coupling_fade_s = -1.0;
  EXPECT_NE(validate(p).find("fade"), std::string::npos);
}

}  // namespace
}  // namespace hemm::op::telemanip
