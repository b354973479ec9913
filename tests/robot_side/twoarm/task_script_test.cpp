// The SIMULATED human's scripts (operator/twoarm_tasks/task_script.h) on
// believed states built by hand: the dead-man is released first, then
// pressed; a step does not end until the believed state confirms it (the
// grasp frame at the step's target, a gripper holding), however long that
// takes; a believed state it cannot read moves nothing.
#include "common/mapping/depth_stream.h"
#include "operator/twoarm_tasks/task_script.h"
#include "tests/robot_side/twoarm/believed_state.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

#include <limits>

#include <gtest/gtest.h>

namespace hs = hemm::twoarm_tasks;
namespace hw = hemm::wire;

namespace {

// The peg's plan: its first steps move one arm (the left) alone.
hs::TaskScript script_test_peg() {
  const hs::TaskSceneResult r = hs::load_task_scene(hemm::test::kWorkbenchScene);
  if (!r.scene) throw std::runtime_error(r.error);
  return hs::peg_script(*r.scene);
}

}  // namespace

TEST(TaskScript, WaitsForTheBelievedStateAtAnyDelay) {
  const hs::TaskScript sc = script_test_peg();
  ASSERT_GE(sc.steps.size(), 3u);
  hs::ScriptState st;
  // Nothing believed yet: nothing sent.
  EXPECT_FALSE(hs::script_step(sc, st, nullptr, 0.0).send);
  const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d rest_l = Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::Isometry3d::Identity();
  const hw::ArmsState at_rest = hemm::test::believed_arms_state({rest_r, rest_l});
  hs::ScriptOutput out = hs::script_step(sc, st, &at_rest, 1.0);
  ASSERT_TRUE(out.send);
  EXPECT_FALSE(out.deadman);  // released first: the re-arm wants a neutral command
  EXPECT_LT((out.targets.T_A_G[1].translation() - rest_l.translation()).norm(), 1e-12);
  // The arm is believed at rest for a minute: the targets go to the first
  // step's pose at its speed, and the step never ends.
  const Eigen::Vector3d goal = sc.steps[0].pose[1]->translation();
  for (double t = 1.1; t < 61.0; t += 0.01) out = hs::script_step(sc, st, &at_rest, t);
  EXPECT_TRUE(out.deadman);
  EXPECT_EQ(st.step, 0u);
  EXPECT_LT((out.targets.T_A_G[1].translation() - goal).norm(), 1e-9);
  // What it waits on: the left G's distance and turn from the goal, not the right's.
  EXPECT_NEAR(st.wait_pos_m[1], (rest_l.translation() - goal).norm(), 1e-9);
  EXPECT_NEAR(st.wait_rot_rad[1], Eigen::AngleAxisd(rest_l.linear().transpose() * st.to[1].linear()).angle(), 1e-9);
  EXPECT_GT(st.wait_rot_rad[1], sc.p.rot_tol_rad);
  EXPECT_EQ(st.wait_pos_m[0], 0.0);
  EXPECT_EQ(st.wait_rot_rad[0], 0.0);
  // The right arm was not told to move.
  EXPECT_LT((out.targets.T_A_G[0].translation() - rest_r.translation()).norm(), 1e-12);
  // Believed there (orientation as targeted): the step ends, the next begins.
  const hw::ArmsState there = hemm::test::believed_arms_state({rest_r, out.targets.T_A_G[1]});
  out = hs::script_step(sc, st, &there, 61.0);
  EXPECT_EQ(st.step, 1u);
  ASSERT_EQ(st.step_end_t.size(), 1u);  // when it ended, on the script's clock
  EXPECT_EQ(st.step_end_t[0], 61.0);
  // The closing step waits for the gripper to hold, however long.
  const hw::ArmsState down = hemm::test::believed_arms_state({rest_r, *sc.steps[1].pose[1]});
  for (double t = 61.01; t < 90.0; t += 0.01) out = hs::script_step(sc, st, &down, t);
  EXPECT_EQ(st.step, 2u);
  EXPECT_EQ(out.targets.gripper[1].opening_m, 0.0);  // told to close
  for (double t = 90.0; t < 120.0; t += 0.01) out = hs::script_step(sc, st, &down, t);
  EXPECT_EQ(st.step, 2u);
  const hw::ArmsState holding = hemm::test::believed_arms_state({rest_r, *sc.steps[1].pose[1]}, {false, true});
  hs::script_step(sc, st, &holding, 120.0);
  EXPECT_EQ(st.step, 3u);
  ASSERT_EQ(st.step_end_t.size(), 3u);
  // Believed down all along: the descent ends when its 10 cm at the slow speed do.
  EXPECT_NEAR(st.step_end_t[1], 61.0 + 0.10 / sc.p.slow_speed_mps, 0.02);
  EXPECT_EQ(st.step_end_t[2], 120.0);
  EXPECT_TRUE(st.error.empty());
}

TEST(TaskScript, UnreadableBelievedStateMovesNothing) {
  const hs::TaskScript sc = script_test_peg();
  hs::ScriptState st;
  const Eigen::Isometry3d rest = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  hw::ArmsState bad = hemm::test::believed_arms_state({rest, rest});
  bad.mutable_arm(0)->mutable_t_a_g()->mutable_position()->set_x(std::numeric_limits<double>::quiet_NaN());
  // Never a good one: nothing sent, a reason kept.
  EXPECT_FALSE(hs::script_step(sc, st, &bad, 0.0).send);
  EXPECT_FALSE(st.error.empty());
  // Started on a good one, then a bad one at the step's target: no step ends.
  const hw::ArmsState good = hemm::test::believed_arms_state({rest, rest});
  hs::ScriptOutput out;
  for (double t = 1.0; t < 20.0; t += 0.01) out = hs::script_step(sc, st, &good, t);
  hw::ArmsState bad_there = hemm::test::believed_arms_state({out.targets.T_A_G[0], rest});
  bad_there.mutable_arm(1)->set_q(3, std::numeric_limits<double>::infinity());
  out = hs::script_step(sc, st, &bad_there, 20.0);
  EXPECT_EQ(st.step, 0u);
  EXPECT_TRUE(out.send);
}

// A slow squeeze (ScriptStep::grip_speed_mps): the opening goes from where
// it was to the step's at that rate, not at once; the step ends when the
// gripper holds, and then the opening is the step's (the full grip force).
// The box's plan closes so.
TEST(TaskScript, SlowSqueezeRampsTheOpeningUntilTheGripperHolds) {
  hs::ScriptStep close;
  close.name = "close slowly";
  close.grip[0] = hemm::twoarm::GripperTarget{0.0, 30.0};
  close.grip_speed_mps = 0.05;
  close.wait_grasped[0] = true;
  const hs::TaskScript sc{"test", hs::ScriptParams{}, {close}};
  const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d rest_l = Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::Isometry3d::Identity();
  hw::ArmsState open = hemm::test::believed_arms_state({rest_r, rest_l});
  open.mutable_gripper(0)->set_target_opening_m(0.2);
  hs::ScriptState st;
  hs::ScriptOutput out = hs::script_step(sc, st, &open, 0.0);
  EXPECT_DOUBLE_EQ(out.targets.gripper[0].opening_m, 0.2);
  const double t0 = sc.p.deadman_delay_s;  // the step begins with the dead-man
  out = hs::script_step(sc, st, &open, t0);
  EXPECT_NEAR(out.targets.gripper[0].opening_m, 0.2, 1e-12);
  out = hs::script_step(sc, st, &open, t0 + 1.0);
  EXPECT_NEAR(out.targets.gripper[0].opening_m, 0.15, 1e-9);
  EXPECT_DOUBLE_EQ(out.targets.gripper[0].force_N, 30.0);
  out = hs::script_step(sc, st, &open, t0 + 2.0);
  EXPECT_NEAR(out.targets.gripper[0].opening_m, 0.10, 1e-9);
  EXPECT_EQ(st.step, 0u);  // not holding yet
  const hw::ArmsState holding = hemm::test::believed_arms_state({rest_r, rest_l}, {true, false});
  out = hs::script_step(sc, st, &holding, t0 + 2.5);
  EXPECT_EQ(st.step, 1u);
  EXPECT_DOUBLE_EQ(out.targets.gripper[0].opening_m, 0.0);
  // The left gripper, not named, kept its target all along.
  EXPECT_DOUBLE_EQ(out.targets.gripper[1].opening_m, 0.0);
  // The box's plan closes on the box so.
  const hs::TaskSceneResult r = hs::load_task_scene(hemm::test::kWorkbenchScene);
  ASSERT_TRUE(r.scene) << r.error;
  bool slow = false;
  for (const hs::ScriptStep& s : hs::box_script(*r.scene).steps)
    if (s.wait_grasped[0] && s.wait_grasped[1]) slow = s.grip_speed_mps > 0.0;
  EXPECT_TRUE(slow);
}

// The guarded set-down (ScriptStep::lower_until_unloaded): both targets go
// down together at place_speed_mps while the wrists carry the load; once
// they carry less than unloaded_N together, both go to where G is believed,
// less place_press_m - down when the arms sag above it (G below the
// target), up when the descent ran on (G above it).
TEST(TaskScript, SetDownGoesToTheBelievedGLessThePressOnceUnloaded) {
  for (const double g_off : {-0.008, +0.012}) {  // G below (sagging) / above (ran on) the target at the stop
    hs::ScriptStep place;
    place.name = "set down";
    place.lower_until_unloaded = true;
    place.lower_max_m = 0.08;
    place.dwell_s = 0.3;
    const hs::TaskScript sc{"test", hs::ScriptParams{}, {place}};
    const hs::ScriptParams& p = sc.p;
    const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
    const Eigen::Isometry3d rest_l = Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::Isometry3d::Identity();
    hw::ArmsState loaded = hemm::test::believed_arms_state({rest_r, rest_l}, {true, true});
    for (int a = 0; a < 2; ++a) loaded.mutable_arm(a)->mutable_force_a()->set_z(-9.81);
    hs::ScriptState st;
    hs::script_step(sc, st, &loaded, 0.0);
    const double t0 = p.deadman_delay_s;
    hs::ScriptOutput out = hs::script_step(sc, st, &loaded, t0);
    out = hs::script_step(sc, st, &loaded, t0 + 2.0);
    for (int a = 0; a < 2; ++a)  // 2 s down at place_speed_mps
      EXPECT_NEAR(out.targets.T_A_G[a].translation().z(), 1.0 - 2.0 * p.place_speed_mps, 1e-9) << a;
    // The board takes the load: the wrists carry 3 N each; G is believed g_off from the target.
    const double target_z = 1.0 - 2.5 * p.place_speed_mps;
    const double g_z = target_z + g_off;
    hw::ArmsState rests = hemm::test::believed_arms_state(
        {Eigen::Translation3d(0.73, -0.25, g_z) * Eigen::Isometry3d::Identity(),
         Eigen::Translation3d(0.73, 0.25, g_z) * Eigen::Isometry3d::Identity()},
        {true, true});
    for (int a = 0; a < 2; ++a) rests.mutable_arm(a)->mutable_force_a()->set_z(-3.0);
    out = hs::script_step(sc, st, &rests, t0 + 2.5);
    EXPECT_TRUE(st.lower_stopped);
    for (int a = 0; a < 2; ++a)
      EXPECT_NEAR(out.targets.T_A_G[a].translation().z(), g_z - p.place_press_m, 1e-9) << "G off " << g_off << ", arm " << a;
    // Held there (no further descent), and done after the dwell.
    out = hs::script_step(sc, st, &rests, t0 + 2.7);
    EXPECT_NEAR(out.targets.T_A_G[0].translation().z(), g_z - p.place_press_m, 1e-9);
    EXPECT_EQ(st.step, 0u);
    out = hs::script_step(sc, st, &rests, t0 + 2.85);
    EXPECT_EQ(st.step, 1u);
  }
}
