// The two-arm station's wire messages: a good ArmsCommand gives the targets
// it names (others kept), every kind of bad one is refused with its reason
// and index and leaves the targets as they were; the state the robot reports
// round-trips through the wire and its check.
#include "robot_side/twoarm/arms_wire.h"

#include <cmath>
#include <functional>
#include <limits>

#include <gtest/gtest.h>

#include "robot_side/twoarm/workbench_sim.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace hk = hemm::kinematics;
namespace ht = hemm::twoarm;
namespace hw = hemm::wire;

namespace {

using hemm::test::kWorkbenchScene;
struct Fixture {
  ht::WorkbenchSim sim{kWorkbenchScene};
  std::array<ht::ArmReading, ht::kArms> readings{sim.reading(ht::Side::kRight), sim.reading(ht::Side::kLeft)};
  ht::TwoArmTargets current = ht::hold_targets(sim.model(), readings, {5.0, 5.0});
  ht::ArmsCommandLimits limits;

  hw::ArmsCommand moved(double dx) const {
    ht::TwoArmTargets t = current;
    t.T_A_G[0].translation().x() += dx;
    t.T_A_G[1].translation().z() -= dx;
    t.gripper[1] = {0.08, 25.0};
    hw::ArmsCommand c;
    ht::to_wire(t, true, &c);
    return c;
  }
  ht::ArmsCommandResult apply(const hw::ArmsCommand& c) const {
    return ht::apply_arms_command(sim.model(), limits, c, current, readings);
  }
};

}  // namespace

TEST(ArmsWire, GoodCommandGivesItsTargets) {
  Fixture f;
  const auto r = f.apply(f.moved(0.05));
  ASSERT_TRUE(r.targets) << r.refusal.detail;
  EXPECT_NEAR(r.targets->T_A_G[0].translation().x(), f.current.T_A_G[0].translation().x() + 0.05, 1e-12);
  EXPECT_NEAR(r.targets->T_A_G[1].translation().z(), f.current.T_A_G[1].translation().z() - 0.05, 1e-12);
  EXPECT_DOUBLE_EQ(r.targets->gripper[1].opening_m, 0.08);
  EXPECT_DOUBLE_EQ(r.targets->gripper[1].force_N, 25.0);
  // Naming only the left gripper keeps everything else.
  hw::ArmsCommand only;
  hw::GripperTarget* g = only.add_gripper();
  g->set_index(1);
  g->set_opening_m(0.02);
  g->set_force_n(10.0);
  const auto r2 = f.apply(only);
  ASSERT_TRUE(r2.targets);
  EXPECT_TRUE((r2.targets->T_A_G[0].matrix() - f.current.T_A_G[0].matrix()).norm() == 0.0);
  EXPECT_TRUE((r2.targets->T_A_G[1].matrix() - f.current.T_A_G[1].matrix()).norm() == 0.0);
  EXPECT_DOUBLE_EQ(r2.targets->gripper[0].force_N, f.current.gripper[0].force_N);
  EXPECT_DOUBLE_EQ(r2.targets->gripper[1].opening_m, 0.02);
}

TEST(ArmsWire, BadCommandsAreRefusedWithTheirReason) {
  Fixture f;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Bad {
    const char* what;
    std::function<void(hw::ArmsCommand&)> spoil;
    hw::ArmsRefusalReason reason;
    uint32_t index;
  };
  const Bad cases[] = {
      {"nan position", [&](hw::ArmsCommand& c) { c.mutable_arm(1)->mutable_t_a_g()->mutable_position()->set_y(nan); },
       hw::ARMS_REFUSAL_NONFINITE, 1},
      {"inf quaternion",
       [&](hw::ArmsCommand& c) {
         c.mutable_arm(0)->mutable_t_a_g()->mutable_orientation()->set_w(std::numeric_limits<double>::infinity());
       },
       hw::ARMS_REFUSAL_NONFINITE, 0},
      {"nan grip force", [&](hw::ArmsCommand& c) { c.mutable_gripper(0)->set_force_n(nan); }, hw::ARMS_REFUSAL_NONFINITE, 0},
      {"arm 2", [&](hw::ArmsCommand& c) { c.mutable_arm(1)->set_index(2); }, hw::ARMS_REFUSAL_UNKNOWN_ARM, 2},
      {"arm 0 twice", [&](hw::ArmsCommand& c) { c.mutable_arm(1)->set_index(0); }, hw::ARMS_REFUSAL_UNKNOWN_ARM, 0},
      {"gripper 7", [&](hw::ArmsCommand& c) { c.mutable_gripper(0)->set_index(7); }, hw::ARMS_REFUSAL_UNKNOWN_GRIPPER, 7},
      {"no pose", [&](hw::ArmsCommand& c) { c.mutable_arm(0)->clear_t_a_g(); }, hw::ARMS_REFUSAL_BAD_POSE, 0},
      {"quaternion not unit",
       [&](hw::ArmsCommand& c) { c.mutable_arm(1)->mutable_t_a_g()->mutable_orientation()->set_w(2.0); },
       hw::ARMS_REFUSAL_BAD_POSE, 1},
      {"2 m away", [&](hw::ArmsCommand& c) { c.mutable_arm(0)->mutable_t_a_g()->mutable_position()->set_x(2.5); },
       hw::ARMS_REFUSAL_OUT_OF_REACH, 0},
      // 0.49 m forward and out from the left grasp frame: within the jump
      // limit, but its wrist centre would be 1.0 m from the shoulder (the
      // arm reaches 0.79 m).
      {"beyond the arm",
       [&](hw::ArmsCommand& c) {
         auto* p = c.mutable_arm(1)->mutable_t_a_g()->mutable_position();
         p->set_x(p->x() + 0.45);
         p->set_y(p->y() + 0.2);
       },
       hw::ARMS_REFUSAL_OUT_OF_REACH, 1},
      {"opening 0.5 m", [&](hw::ArmsCommand& c) { c.mutable_gripper(1)->set_opening_m(0.5); }, hw::ARMS_REFUSAL_GRIPPER_RANGE, 1},
      {"force 300 N", [&](hw::ArmsCommand& c) { c.mutable_gripper(0)->set_force_n(300.0); }, hw::ARMS_REFUSAL_GRIPPER_RANGE, 0},
      {"negative force", [&](hw::ArmsCommand& c) { c.mutable_gripper(0)->set_force_n(-1.0); }, hw::ARMS_REFUSAL_GRIPPER_RANGE, 0},
  };
  for (const Bad& b : cases) {
    SCOPED_TRACE(b.what);
    hw::ArmsCommand c = f.moved(0.02);
    ASSERT_TRUE(f.apply(c).targets);  // good before it is spoiled
    b.spoil(c);
    const auto r = f.apply(c);
    EXPECT_FALSE(r.targets);
    EXPECT_EQ(r.refusal.reason, b.reason) << r.refusal.detail;
    EXPECT_EQ(r.refusal.index, b.index);
    EXPECT_FALSE(r.refusal.detail.empty());
  }
}

// A target a few millimetres past what the joint limits reach (found by
// walking the left grasp frame out along the line from its shoulder) is
// taken within the reach margin and flagged as at the edge, with the error
// the closest pose leaves; with the margin at 0 it is refused as out of
// reach; well past the margin it is refused with how far the closest is.
TEST(ArmsWire, TargetJustPastTheReachIsTakenWithinTheMarginAndFlagged) {
  Fixture f;
  const ht::ArmMount& arm = f.sim.model().arms[1];
  const Eigen::Isometry3d G = ht::grasp_pose_A(arm, f.readings[1].q);
  const Eigen::Vector3d shoulder = arm.T_A_Ar.translation();
  const Eigen::Vector3d out = (G.translation() - shoulder).normalized();
  Eigen::Isometry3d T = G;
  double step_out = 0.0;
  for (; step_out < 0.45; step_out += 0.002) {
    T.translation() = G.translation() + step_out * out;
    if (!ht::grasp_closest_reach(arm, T, f.readings[1].q).reached) break;
  }
  ASSERT_LT(step_out, 0.45) << "the walk never left the reach";
  const ht::GraspReach edge = ht::grasp_closest_reach(arm, T, f.readings[1].q);
  ASSERT_FALSE(edge.reached);
  ASSERT_LT(edge.position_error_m, f.limits.reach_margin_m) << "the first unreached step is past the margin";
  // The closest pose is within the joint limits and puts G where it says.
  for (int j = 0; j < 7; ++j) {
    EXPECT_GE(edge.q[j], arm.arm.q_min[j] - 1e-9);
    EXPECT_LE(edge.q[j], arm.arm.q_max[j] + 1e-9);
  }
  EXPECT_NEAR((ht::grasp_pose_A(arm, edge.q).translation() - T.translation()).norm(), edge.position_error_m, 1e-9);

  ht::TwoArmTargets t = f.current;
  t.T_A_G[1] = T;
  hw::ArmsCommand c;
  ht::to_wire(t, true, &c);
  ht::ValidatedArmsCommand v;
  ASSERT_FALSE(ht::validate_arms_command(f.sim.model(), f.limits, c, f.readings, &v));
  EXPECT_TRUE(v.at_reach_edge[1]);
  EXPECT_FALSE(v.at_reach_edge[0]);
  EXPECT_NEAR(v.reach_error_m[1], edge.position_error_m, 1e-6);  // T went through the wire
  EXPECT_TRUE(v.named.T_A_G[1].isApprox(T, 1e-12));

  ht::ArmsCommandLimits strict = f.limits;
  strict.reach_margin_m = 0.0;
  strict.reach_margin_rad = 0.0;
  const auto r = ht::apply_arms_command(f.sim.model(), strict, c, f.current, f.readings);
  EXPECT_FALSE(r.targets);
  EXPECT_EQ(r.refusal.reason, hw::ARMS_REFUSAL_OUT_OF_REACH);
  EXPECT_EQ(r.refusal.index, 1u);

  // 10 cm farther out: past the margin, refused, and the detail says how far.
  t.T_A_G[1].translation() += 0.10 * out;
  ht::to_wire(t, true, &c);
  const auto far = f.apply(c);
  EXPECT_FALSE(far.targets);
  EXPECT_EQ(far.refusal.reason, hw::ARMS_REFUSAL_OUT_OF_REACH);
  EXPECT_NE(far.refusal.detail.find("the closest within the limits"), std::string::npos) << far.refusal.detail;
}

TEST(ArmsWire, StateRoundTrips) {
  Fixture f;
  ht::TwoArmParams p;
  ht::TwoArmOutput out;
  ht::twoarm_control(f.sim.model(), p, f.readings, f.current, out);
  hw::ArmsState s;
  ht::to_wire(f.sim.model(), f.readings, f.current, out, 123, &s);
  hw::StreamMessage m;
  *m.mutable_arms_state() = s;
  hw::StreamMessage back;
  ASSERT_TRUE(back.ParseFromString(m.SerializeAsString()));
  ASSERT_TRUE(back.has_arms_state());
  EXPECT_FALSE(ht::check_arms_state(back.arms_state()));
  ASSERT_EQ(back.arms_state().arm_size(), 2);
  for (int i = 0; i < 2; ++i) {
    const hw::ArmState& a = back.arms_state().arm(i);
    for (int j = 0; j < 7; ++j) EXPECT_EQ(a.q(j), f.readings[static_cast<std::size_t>(i)].q(j));
    const Eigen::Vector3d p_G = ht::grasp_pose_A(f.sim.model().arms[static_cast<std::size_t>(i)], f.readings[static_cast<std::size_t>(i)].q).translation();
    EXPECT_NEAR(a.t_a_g().position().x(), p_G.x(), 1e-12);
    EXPECT_NEAR(a.t_a_g().position().z(), p_G.z(), 1e-12);
  }
  // A 250 Hz stream of this: its size.
  std::printf("ArmsState datagram body: %zu bytes\n", m.SerializeAsString().size());
  hw::ArmsState bad = back.arms_state();
  bad.mutable_arm(0)->set_qd(3, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(ht::check_arms_state(bad));
  bad = back.arms_state();
  bad.mutable_arm(1)->mutable_q()->RemoveLast();
  EXPECT_TRUE(ht::check_arms_state(bad));
}
