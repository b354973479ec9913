// The SIMULATED task human (operator/telemanip/task_human.h) on a fake
// believed state, without a device or a link: the hand's D pose, mapped by
// the task's own mapping from the anchor the servo task would publish, is
// the script's target for that arm; the lever is the gripper target's
// opening inverted through the mapping; the dead-man is the script's; and
// the task settings are refused with a clear reason.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "config_operator.pb.h"
#include "operator/telemanip/task_human.h"
#include "tests/robot_side/twoarm/believed_state.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace tele = hemm::op::telemanip;
namespace hs = hemm::twoarm_tasks;

namespace {

tele::ArmMappingParams task_human_test_mapping() {
  tele::ArmMappingParams m;
  m.R_A_D = Eigen::AngleAxisd(30.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  m.translation_scale = 1.5;
  m.opening_open_m = 0.22;
  m.opening_closed_m = 0.0;
  m.force_open_n = 5.0;
  m.force_closed_n = 30.0;
  return m;
}

}  // namespace

TEST(TaskHuman, HandPoseMapsBackToTheScriptsTargetThroughTheMapping) {
  const tele::ArmMappingParams m = task_human_test_mapping();
  const hs::TaskScript plan = tele::task_plan("peg", hemm::test::kWorkbenchScene);
  tele::TaskHumanBrain brain(plan, {m, m});
  hs::ScriptState twin;  // the same script on the same inputs: what the brain must want
  const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d rest_l =
      Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX());
  const hemm::wire::ArmsState believed = hemm::test::believed_arms_state({rest_r, rest_l});

  hemm::NewestMailbox<tele::MappingAnchor> anchors;
  hemm::device::bimanual::HumanTarget rest;
  rest.position_D = Eigen::Vector3d(0.35, 0.2, 0.1);
  rest.orientation_D = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()));
  const tele::TaskHumanHand left(rest, m, &brain.wishes(1), &anchors, 0.0, nullptr);  // lever: the joystick

  // Nothing believed: no wish, the hand rests released.
  brain.tick(0.0);
  hemm::device::bimanual::HumanTarget g = left.at(0.0);
  EXPECT_FALSE(g.deadman);
  EXPECT_LT((g.position_D - rest.position_D).norm(), 1e-12);

  brain.believed().publish(believed);
  brain.tick(0.05);
  hs::ScriptOutput out = hs::script_step(plan, twin, &believed, 0.05);
  g = left.at(0.05);
  EXPECT_FALSE(g.deadman);  // the script releases first (the re-arm wants a neutral command)

  // The servo task anchors at the press: the hand where it rests, the arm's commanded pose where G was.
  tele::MappingAnchor anchor;
  anchor.engaged = true;
  anchor.state.initialized = anchor.state.engaged = true;
  anchor.state.T_A_anchor = rest_l;
  anchor.state.T_D_anchor = hemm::device::bimanual::pose_D(rest);
  anchors.publish(anchor);
  // Two seconds of the first step (the left arm over the peg, at the script's speed).
  for (double t = 0.06; t < 2.0; t += 0.01) {
    brain.tick(t);
    out = hs::script_step(plan, twin, &believed, t);
  }
  // The arm already commanded where the script wants it: no turn to correct.
  anchor.state.T_A_G_cmd = out.targets.T_A_G[1];
  anchors.publish(anchor);
  g = left.at(2.0);
  EXPECT_TRUE(g.deadman);
  const Eigen::Isometry3d want = out.targets.T_A_G[1];
  EXPECT_GT((want.translation() - rest_l.translation()).norm(), 0.05);  // the target has moved on
  const Eigen::Isometry3d asked = tele::mapped_pose_A(m, anchor.state, hemm::device::bimanual::pose_D(g));
  EXPECT_LT((asked.translation() - want.translation()).norm(), 1e-9);
  EXPECT_LT(Eigen::AngleAxisd(asked.linear().transpose() * want.linear()).angle(), 1e-6);
  // The lever (the joystick's forward axis) gives the target's opening through the mapping.
  double opening = 0.0, force = 0.0;
  tele::grip_to_gripper(m, g.joystick.y() * m.grip_travel_m, &opening, &force);
  EXPECT_NEAR(opening, out.targets.gripper[1].opening_m, 1e-9);
  EXPECT_GT(g.joystick.y(), 0.0);
  EXPECT_LT(g.joystick.y(), 1.0);
  // The right hand's arm was not told to move: its wish is where its G is.
  const tele::TaskHandWish* right = brain.wishes(0).take();
  ASSERT_NE(right, nullptr);
  EXPECT_LT((right->T_A_G.translation() - rest_r.translation()).norm(), 1e-12);
  const tele::TaskProgress p = brain.progress();
  EXPECT_TRUE(p.started);
  EXPECT_FALSE(p.done);
  EXPECT_EQ(p.steps_done, 0u);
  EXPECT_EQ(p.steps, plan.steps.size());
}

// While the hands index (the clutch held) the plan waits, and resume_s
// after the release: the wish does not move on, and afterwards it is the
// script's on a clock without the pause (a person holds the motion while
// re-centring; a plan that ran on left the hand behind its target).
TEST(TaskHuman, ThePlanWaitsWhileTheHandsIndex) {
  const tele::ArmMappingParams m = task_human_test_mapping();
  const hs::TaskScript plan = tele::task_plan("peg", hemm::test::kWorkbenchScene);
  tele::TaskHumanBrain brain(plan, {m, m});
  const double resume = brain.indexing().p.resume_s;
  ASSERT_GT(resume, 0.0);
  hs::ScriptState twin;
  const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d rest_l = Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::Isometry3d::Identity();
  const hemm::wire::ArmsState believed = hemm::test::believed_arms_state({rest_r, rest_l});
  brain.believed().publish(believed);
  Eigen::Vector3d wish = Eigen::Vector3d::Zero();
  const auto step = [&](double t) {
    brain.tick(t);
    // The twin on the brain's plan clock: the caller's less the pause so far.
    const hs::ScriptOutput out = hs::script_step(plan, twin, &believed, t - brain.progress().indexing_pause_s);
    const tele::TaskHandWish* w = brain.wishes(1).take();
    EXPECT_NE(w, nullptr);
    if (w == nullptr) return;
    wish = w->T_A_G.translation();
    EXPECT_LT((wish - out.targets.T_A_G[1].translation()).norm(), 1e-12) << "at t " << t;
  };
  double t = 0.0;
  for (; t < 1.0; t += 0.01) step(t);
  const Eigen::Vector3d before = wish;
  EXPECT_GT((before - rest_l.translation()).norm(), 0.02);  // the left arm is on its way
  brain.indexing().held[1].store(true);
  const double pressed_t = t;
  for (; t < pressed_t + 0.8; t += 0.01) {
    step(t);
    EXPECT_LT((wish - before).norm(), 2e-3) << "at t " << t;  // at most the tick it took to see the press
  }
  brain.indexing().held[1].store(false);
  const double released_t = t;
  for (; t < released_t + resume - 0.02; t += 0.01) {
    step(t);
    EXPECT_LT((wish - before).norm(), 2e-3) << "resuming, at t " << t;
  }
  for (; t < released_t + resume + 0.5; t += 0.01) step(t);
  EXPECT_GT((wish - before).norm(), 0.02);  // on its way again
  EXPECT_NEAR(brain.progress().indexing_pause_s, 0.8 + resume, 0.03);
}

// The human turns its hand further while the commanded G lacks some of the
// wished turn (integrated: kTurnGain_per_s of the lack, seen in D at 1/k),
// never more than kTurnBiasMax_rad beyond its spring's target, and starts
// over at a new press.
TEST(TaskHuman, HandTurnsFurtherWhileTheCommandedGripperLacksTheWishedTurn) {
  tele::ArmMappingParams m = task_human_test_mapping();
  m.rotation_scale = 3.0;
  hemm::NewestMailbox<tele::TaskHandWish> wishes;
  hemm::NewestMailbox<tele::MappingAnchor> anchors;
  hemm::device::bimanual::HumanTarget rest;
  rest.position_D = Eigen::Vector3d(0.35, 0.2, 0.1);
  const tele::TaskHumanHand hand(rest, m, &wishes, &anchors, 0.0, nullptr);
  tele::TaskHandWish w;
  w.active = w.deadman = true;
  w.T_A_G = Eigen::Translation3d(0.6, 0.3, 0.9) * Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX());
  wishes.publish(w);
  tele::MappingAnchor a;
  a.engaged = a.state.initialized = a.state.engaged = true;
  a.state.T_A_anchor = Eigen::Translation3d(0.6, 0.3, 0.9) * Eigen::Isometry3d::Identity();
  a.state.T_D_anchor = hemm::device::bimanual::pose_D(rest);
  // The commanded G 0.06 rad short of the wish, about the same axis.
  a.state.T_A_G_cmd = Eigen::Translation3d(0.6, 0.3, 0.9) * Eigen::AngleAxisd(0.44, Eigen::Vector3d::UnitX());
  anchors.publish(a);
  const Eigen::Matrix3d spring_D = tele::hand_pose_D(m, a.state, w.T_A_G).linear();
  const Eigen::Vector3d lack_D = m.R_A_D.transpose() * Eigen::Vector3d(0.06, 0.0, 0.0) / 3.0;
  hemm::device::bimanual::HumanTarget g = hand.at(0.0);
  EXPECT_TRUE(g.orientation_D.toRotationMatrix().isApprox(spring_D, 1e-12));  // no time has passed
  for (int i = 1; i <= 1000; ++i) g = hand.at(i * 1e-3);
  // After 1 s: 1.5 x the lack, turned about the lack's own axis.
  const Eigen::AngleAxisd extra(g.orientation_D.toRotationMatrix() * spring_D.transpose());
  EXPECT_NEAR(extra.angle(), tele::TaskHumanHand::kTurnGain_per_s * 1.0 * lack_D.norm(), 1e-9);
  EXPECT_GT(extra.axis().dot(lack_D.normalized()), 1.0 - 1e-9);
  // Bounded however long the lack stays.
  for (int i = 1; i <= 200; ++i) g = hand.at(1.0 + i * 0.1);
  const Eigen::AngleAxisd most(g.orientation_D.toRotationMatrix() * spring_D.transpose());
  EXPECT_NEAR(most.angle(), tele::TaskHumanHand::kTurnBiasMax_rad, 1e-9);
  // Released and pressed again: the correction starts over.
  a.engaged = false;
  anchors.publish(a);
  hand.at(21.1);
  a.engaged = true;
  anchors.publish(a);
  g = hand.at(21.1);
  EXPECT_TRUE(g.orientation_D.toRotationMatrix().isApprox(spring_D, 1e-12));
}

// Indexing: the right hand's target beyond its reach makes the left hand
// (which holds the clutch) press its button, for hold_s, only with the
// dead-man pressed; while its mapping is not engaged each hand moves back
// towards its rest at kReturnSpeed_mps from where it was asked last; the
// next press waits cooldown_s after the release.
TEST(TaskHuman, TheHandWithTheClutchPressesItWhenEitherHandIsBeyondItsReach) {
  namespace hb = hemm::device::bimanual;
  const tele::ArmMappingParams m = task_human_test_mapping();
  tele::TaskIndexing indexing;
  indexing.p.reach_m = 0.07;
  indexing.p.hold_s = 0.6;
  indexing.p.cooldown_s = 0.4;
  std::array<hemm::NewestMailbox<tele::TaskHandWish>, 2> wishes;
  std::array<hemm::NewestMailbox<tele::MappingAnchor>, 2> anchors;
  std::array<hb::HumanTarget, 2> rest;
  rest[0].position_D = Eigen::Vector3d(0.35, -0.2, 0.1);
  rest[1].position_D = Eigen::Vector3d(0.35, 0.2, 0.1);
  constexpr std::uint32_t kClutch = 1u << 2;  // button 3
  const tele::TaskHumanHand right(rest[0], m, &wishes[0], &anchors[0], 0.025, nullptr, &indexing, 0, 0);
  const tele::TaskHumanHand left(rest[1], m, &wishes[1], &anchors[1], 0.0, nullptr, &indexing, 1, kClutch);
  // Both anchored at rest on G0; the right's wish 0.12 m of A away: 0.08 m of D at scale 1.5.
  const Eigen::Isometry3d G0 = Eigen::Translation3d(0.6, -0.3, 0.9) * Eigen::Isometry3d::Identity();
  for (int k = 0; k < 2; ++k) {
    tele::MappingAnchor a;
    a.engaged = a.state.initialized = a.state.engaged = true;
    a.state.T_A_anchor = a.state.T_A_G_cmd = G0;
    a.state.T_D_anchor = hb::pose_D(rest[static_cast<std::size_t>(k)]);
    anchors[static_cast<std::size_t>(k)].publish(a);
    tele::TaskHandWish w;
    w.active = w.deadman = true;
    w.T_A_G = G0;
    wishes[static_cast<std::size_t>(k)].publish(w);
  }
  EXPECT_EQ(left.at(0.0).buttons, 0u);  // both within reach
  EXPECT_EQ(right.at(0.0).buttons, 0u);
  tele::TaskHandWish far;
  far.active = far.deadman = true;
  far.T_A_G = Eigen::Translation3d(0.6 - 0.12, -0.3, 0.9) * Eigen::Isometry3d::Identity();
  wishes[0].publish(far);
  const hb::HumanTarget asked = right.at(0.01);
  EXPECT_NEAR((asked.position_D - rest[0].position_D).norm(), 0.08, 1e-12);
  EXPECT_TRUE(indexing.wants[0].load());
  EXPECT_EQ(right.at(0.01).buttons, 0u);  // the right's handle holds no clutch
  EXPECT_EQ(left.at(0.02).buttons, kClutch);
  EXPECT_EQ(indexing.presses[1].load(), 1u);
  EXPECT_TRUE(indexing.held[1].load());  // the brain's plan waits on it
  EXPECT_FALSE(indexing.held[0].load());
  // The servo's mapping, clutched, is not engaged: the right hand goes back towards its rest.
  tele::MappingAnchor clutched;
  clutched.engaged = false;
  anchors[0].publish(clutched);
  hb::HumanTarget g = right.at(0.02);
  for (int i = 1; i <= 100; ++i) g = right.at(0.02 + i * 1e-3);
  // 0.11 s since it was last asked (at 0.01).
  EXPECT_NEAR((g.position_D - asked.position_D).norm(), tele::TaskHumanHand::kReturnSpeed_mps * 0.11, 1e-9);
  EXPECT_NEAR((g.position_D - rest[0].position_D).norm(), 0.08 - tele::TaskHumanHand::kReturnSpeed_mps * 0.11, 1e-9);
  EXPECT_FALSE(indexing.wants[0].load());  // not engaged: it asks nothing
  for (int i = 1; i <= 300; ++i) g = right.at(0.12 + i * 1e-3);
  EXPECT_LT((g.position_D - rest[0].position_D).norm(), 1e-12);  // back at rest, and stays
  // Held for hold_s, then released.
  EXPECT_EQ(left.at(0.5).buttons, kClutch);
  EXPECT_EQ(left.at(0.63).buttons, 0u);
  EXPECT_FALSE(indexing.held[1].load());
  // Far again at once: no press within the cooldown; one after it.
  indexing.wants[0].store(true);
  EXPECT_EQ(left.at(0.9).buttons, 0u);
  EXPECT_EQ(left.at(1.04).buttons, kClutch);
  EXPECT_EQ(indexing.presses[1].load(), 2u);
  // The dead-man released: no clutch pressed.
  tele::TaskHandWish off;
  off.active = true;
  off.deadman = false;
  off.T_A_G = G0;
  wishes[1].publish(off);
  EXPECT_EQ(left.at(1.05).buttons, 0u);
}

TEST(TaskHuman, LeverInvertsTheMappingsOpening) {
  const tele::ArmMappingParams m = task_human_test_mapping();
  EXPECT_DOUBLE_EQ(tele::lever_for_gripper(m, {0.22, 5.0}), 0.0);
  EXPECT_DOUBLE_EQ(tele::lever_for_gripper(m, {0.0, 30.0}), 1.0);
  EXPECT_NEAR(tele::lever_for_gripper(m, {0.055, 30.0}), 0.75, 1e-12);
  EXPECT_DOUBLE_EQ(tele::lever_for_gripper(m, {0.5, 30.0}), 0.0);  // wider than the lever opens: open
  EXPECT_DOUBLE_EQ(tele::lever_for_gripper(m, {std::nan(""), 30.0}), 0.0);
}

TEST(TaskHuman, TaskSettingsAreRefusedWithAReason) {
  hemm::config::TelemanipConfig c;
  std::string scene = "unchanged";
  EXPECT_EQ(tele::check_task_config(c, "/cfg/op.pbtxt", &scene), "");  // no task
  EXPECT_EQ(scene, "");
  c.set_task("ball");
  EXPECT_NE(tele::check_task_config(c, "/cfg/op.pbtxt", &scene).find("must be box, peg or bar"), std::string::npos);
  c.set_task("peg");
  EXPECT_NE(tele::check_task_config(c, "/cfg/op.pbtxt", &scene).find("needs telemanip.task_scene"), std::string::npos);
  c.set_task_scene("../scenes/workbench.xml");
  c.set_task_settle_s(-1.0);
  EXPECT_NE(tele::check_task_config(c, "/cfg/op.pbtxt", &scene).find("task_settle_s"), std::string::npos);
  c.set_task_settle_s(1.0);
  EXPECT_EQ(tele::check_task_config(c, "/cfg/op.pbtxt", &scene), "");
  EXPECT_EQ(scene, "/scenes/workbench.xml");
  c.clear_task();
  EXPECT_NE(tele::check_task_config(c, "/cfg/op.pbtxt", &scene).find("needs telemanip.task"), std::string::npos);
  EXPECT_THROW(tele::task_plan("peg", "/nonexistent/workbench.xml"), std::invalid_argument);
  EXPECT_THROW(tele::task_plan("ball", hemm::test::kWorkbenchScene), std::invalid_argument);
}

// The direct mode's drift correction, one arm (closed forms): a constant
// lack integrates at the gain; an axis whose wrist force pushes back against
// its lack by more than contact_N is held (a press is the plan's); the
// offset is bounded; the target handed on is translated and turned by it.
TEST(TaskHuman, DriftCorrectionIntegratesTheLackExceptAgainstAContact) {
  tele::DriftCorrectionParams p;
  p.gain_per_s = 0.25;
  EXPECT_EQ(tele::validate(p), "");
  const Eigen::Isometry3d target =
      Eigen::Translation3d(0.5, 0.1, 0.9) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY());
  hs::BelievedArm b;
  // 2 cm short in x, 1 cm too high in z, 0.1 rad short about z.
  b.T_A_G = Eigen::Translation3d(0.48, 0.1, 0.91) * Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY());
  tele::DriftOffset o;
  for (int i = 0; i < 100; ++i) tele::integrate_drift(p, target, b, 0.01, &o);
  EXPECT_NEAR(o.p_A.x(), 0.25 * 0.02, 1e-12);
  EXPECT_NEAR(o.p_A.y(), 0.0, 1e-12);
  EXPECT_NEAR(o.p_A.z(), 0.25 * -0.01, 1e-12);
  EXPECT_NEAR(o.r_A.z(), 0.25 * 0.1, 1e-9);
  EXPECT_NEAR(o.r_A.head<2>().norm(), 0.0, 1e-9);
  // The bench pushes the gripper up (10 N) where the target is lower: z is a
  // press and is held; x goes on. 2 N is below the threshold: z integrates.
  b.force_A = Eigen::Vector3d(0.0, 0.0, 10.0);
  tele::DriftOffset pressed;
  for (int i = 0; i < 100; ++i) tele::integrate_drift(p, target, b, 0.01, &pressed);
  EXPECT_NEAR(pressed.p_A.z(), 0.0, 1e-15);
  EXPECT_NEAR(pressed.p_A.x(), 0.25 * 0.02, 1e-12);
  b.force_A = Eigen::Vector3d(0.0, 0.0, 2.0);
  tele::DriftOffset light;
  tele::integrate_drift(p, target, b, 0.01, &light);
  EXPECT_NEAR(light.p_A.z(), 0.25 * 0.01 * -0.01, 1e-12);
  // A force along the lack (the load pulls the way it should go) is no contact.
  b.force_A = Eigen::Vector3d(0.0, 0.0, -20.0);
  tele::DriftOffset load;
  tele::integrate_drift(p, target, b, 0.01, &load);
  EXPECT_NEAR(load.p_A.z(), 0.25 * 0.01 * -0.01, 1e-12);
  // A torque against the turn's lack holds the turn alone.
  b.force_A.setZero();
  b.torque_A = Eigen::Vector3d(0.0, 0.0, -1.0);
  tele::DriftOffset twisted;
  tele::integrate_drift(p, target, b, 0.01, &twisted);
  EXPECT_NEAR(twisted.r_A.z(), 0.0, 1e-15);
  EXPECT_GT(twisted.p_A.x(), 0.0);
  // Bounded.
  b.torque_A.setZero();
  p.max_m = 0.004;
  p.max_rad = 0.01;
  tele::DriftOffset big;
  for (int i = 0; i < 10000; ++i) tele::integrate_drift(p, target, b, 0.01, &big);
  EXPECT_NEAR(big.p_A.norm(), 0.004, 1e-12);
  EXPECT_NEAR(big.r_A.norm(), 0.01, 1e-12);
  // Off (gain 0) or no time: nothing.
  p.gain_per_s = 0.0;
  tele::DriftOffset off;
  tele::integrate_drift(p, target, b, 0.01, &off);
  EXPECT_EQ(off.p_A.norm() + off.r_A.norm(), 0.0);
  // The target handed on.
  tele::DriftOffset d;
  d.p_A = Eigen::Vector3d(0.01, -0.02, 0.005);
  d.r_A = Eigen::Vector3d(0.0, 0.0, 0.3);
  const Eigen::Isometry3d T = tele::offset_target(target, d);
  EXPECT_LT((T.translation() - target.translation() - d.p_A).norm(), 1e-15);
  EXPECT_LT((T.linear() - Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix() * target.linear()).norm(), 1e-12);
  // Bad parameters are refused, with a reason.
  tele::DriftCorrectionParams bad;
  bad.gain_per_s = std::nan("");
  EXPECT_NE(tele::validate(bad), "");
  bad = {};
  bad.max_m = -1.0;
  EXPECT_NE(tele::validate(bad), "");
  tele::TaskHumanBrain brain(tele::task_plan("peg", hemm::test::kWorkbenchScene),
                             {task_human_test_mapping(), task_human_test_mapping()});
  EXPECT_THROW(brain.set_drift_correction(bad), std::invalid_argument);
}

// In the brain: the correction waits until the plan's target has stood
// still for wait_s, then the wish moves beyond the target by what the
// believed G lacks, at the gain.
TEST(TaskHuman, TheBrainCorrectsTheDriftOnlyOnceTheTargetStandsStill) {
  const tele::ArmMappingParams m = task_human_test_mapping();
  const hs::TaskScript plan = tele::task_plan("peg", hemm::test::kWorkbenchScene);
  tele::TaskHumanBrain brain(plan, {m, m});
  tele::DriftCorrectionParams d;
  d.gain_per_s = 0.5;
  d.wait_s = 1.0;
  brain.set_drift_correction(d);
  hs::ScriptState twin;
  const Eigen::Isometry3d rest_r = Eigen::Translation3d(0.73, -0.25, 1.0) * Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d rest_l = Eigen::Translation3d(0.73, 0.25, 1.0) * Eigen::Isometry3d::Identity();
  // The peg's first step does not move the right arm: its target stands
  // still from the first tick where G was first believed. From 0.5 s the
  // believed right G is 2 cm short of it in y (drifted).
  const hemm::wire::ArmsState at_rest = hemm::test::believed_arms_state({rest_r, rest_l});
  const Eigen::Isometry3d drifted = Eigen::Translation3d(0.0, 0.02, 0.0) * rest_r;
  const hemm::wire::ArmsState lagging = hemm::test::believed_arms_state({drifted, rest_l});
  brain.believed().publish(at_rest);
  double first_offset_t = -1.0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  for (double t = 0.0; t < 3.0; t += 0.01) {
    if (std::abs(t - 0.5) < 0.005) brain.believed().publish(lagging);
    brain.tick(t);
    const hs::ScriptOutput out = hs::script_step(plan, twin, t < 0.495 ? &at_rest : &lagging, t);
    const tele::TaskHandWish* w = brain.wishes(0).take();
    ASSERT_NE(w, nullptr);
    EXPECT_LT((out.targets.T_A_G[0].translation() - rest_r.translation()).norm(), 1e-12);
    offset = w->T_A_G.translation() - rest_r.translation();
    if (first_offset_t < 0.0 && offset.norm() > 1e-12) first_offset_t = t;
  }
  // Not while the target had stood still less than wait_s (the lack was
  // there from 0.5 s), then 0.5/s of the 2 cm lack for 2 s: 2 cm, in -y.
  EXPECT_NEAR(first_offset_t, d.wait_s, 0.015);
  EXPECT_NEAR(offset.y(), -0.5 * 2.0 * 0.02, 5e-4);
  EXPECT_NEAR(offset.x(), 0.0, 1e-12);
  EXPECT_NEAR(brain.progress().drift_offset_max_m[0], 0.02, 5e-4);
}
