// The SIMULATED two-arm robot with its safety, driven as the station drives
// it (commands in, one step per 1 ms period), against MuJoCo truth: commands
// move both arms; a malformed command is refused, reported, and changes
// nothing; on link loss the arms hold their pose in impedance and the
// gripper keeps the 2 kg box (not dropped), and motion resumes only after a
// neutral and then a pressed command; the e-stop stops both arms.
#include "robot_side/twoarm/twoarm_robot.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <limits>

#include <gtest/gtest.h>

namespace hk = hemm::kinematics;
namespace ht = hemm::twoarm;
namespace hw = hemm::wire;

namespace {

using hemm::test::kWorkbenchScene;

// A fake operator at 100 Hz: sends `targets` with the dead-man as given.
struct Driver {
  ht::TwoArmRobot robot{kWorkbenchScene, ht::TwoArmRobotOptions{}};
  uint64_t seq = 0;
  bool sending = true;

  void send(const ht::TwoArmTargets& t, bool deadman) {
    hw::ArmsCommand c;
    ht::to_wire(t, deadman, &c);
    robot.command(c, ++seq, robot.time_ns());
  }
  // Runs `seconds`; every 10 ms calls `targets_at(t)` and sends it.
  template <class F>
  void run(double seconds, bool deadman, F targets_at) {
    const int n = static_cast<int>(std::lround(seconds * 1000.0));
    for (int k = 0; k < n; ++k) {
      if (sending && k % 10 == 0) send(targets_at(k * 1e-3), deadman);
      robot.step();
    }
  }
  void run_idle(double seconds) {
    const int n = static_cast<int>(std::lround(seconds * 1000.0));
    for (int k = 0; k < n; ++k) robot.step();
  }
  Eigen::Vector3d grasp(ht::Side s) const { return robot.sim().grasp_site_A(s).translation(); }
  double grasp_speed(ht::Side s) const { return robot.control_output().arm[ht::idx(s)].twist_A.head<3>().norm(); }
  // Re-arms: a neutral command, then pressed ones.
  void arm(const ht::TwoArmTargets& t) {
    send(t, false);
    send(t, true);
  }
};

}  // namespace

TEST(TwoArmRobot, CommandsMoveBothArms) {
  Driver d;
  d.robot.set_link(true, true);
  ht::TwoArmTargets t = d.robot.active_targets();
  EXPECT_TRUE(d.robot.safety() == 0 || (d.robot.safety() & hw::SAFETY_REARM));
  // Pressed commands before re-arming move nothing.
  t.T_A_G[0].translation() += Eigen::Vector3d(0.05, 0.03, -0.04);
  t.T_A_G[1].translation() += Eigen::Vector3d(-0.04, 0.0, 0.06);
  const Eigen::Vector3d r0 = d.grasp(ht::Side::kRight);
  d.run(0.5, true, [&](double) { return t; });
  EXPECT_FALSE(d.robot.armed());
  EXPECT_LT((d.grasp(ht::Side::kRight) - r0).norm(), 0.002);
  d.arm(t);
  ASSERT_TRUE(d.robot.armed());
  d.run(2.0, true, [&](double) { return t; });
  EXPECT_TRUE(d.robot.following());
  EXPECT_EQ(d.robot.safety(), 0u);
  EXPECT_LT((d.grasp(ht::Side::kRight) - t.T_A_G[0].translation()).norm(), 0.003);
  EXPECT_LT((d.grasp(ht::Side::kLeft) - t.T_A_G[1].translation()).norm(), 0.003);
  // And the gripper opens to what it is told.
  t.gripper[1] = {0.09, 20.0};
  d.run(0.8, true, [&](double) { return t; });
  const ht::ArmReading l = d.robot.sim().reading(ht::Side::kLeft);
  EXPECT_NEAR(l.gripper.finger_m[0] + l.gripper.finger_m[1], 0.09, 0.001);
  hw::ArmsState s;
  d.robot.state(&s);
  EXPECT_EQ(s.last_command_seq(), d.seq);
  EXPECT_EQ(s.refusals(), 0u);
}

TEST(TwoArmRobot, MalformedCommandIsRefusedAndChangesNothing) {
  Driver d;
  d.robot.set_link(true, true);
  const ht::TwoArmTargets t = d.robot.active_targets();
  d.arm(t);
  d.run(0.5, true, [&](double) { return t; });
  const ht::TwoArmTargets before = d.robot.active_targets();
  const Eigen::Vector3d r0 = d.grasp(ht::Side::kRight), l0 = d.grasp(ht::Side::kLeft);
  hw::ArmsCommand bad;
  ht::TwoArmTargets far = t;
  far.T_A_G[0].translation().x() += 0.3;
  ht::to_wire(far, true, &bad);
  bad.mutable_arm(1)->mutable_t_a_g()->mutable_position()->set_z(std::numeric_limits<double>::quiet_NaN());
  EXPECT_FALSE(d.robot.command(bad, 777, d.robot.time_ns()));
  d.run_idle(0.1);
  // Nothing changed: the targets, and the arms stay (MuJoCo truth).
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_EQ((d.robot.active_targets().T_A_G[a].matrix() - before.T_A_G[a].matrix()).norm(), 0.0);
  }
  EXPECT_LT((d.grasp(ht::Side::kRight) - r0).norm(), 0.001);
  EXPECT_LT((d.grasp(ht::Side::kLeft) - l0).norm(), 0.001);
  hw::ArmsState s;
  d.robot.state(&s);
  EXPECT_EQ(s.refusals(), 1u);
  EXPECT_EQ(s.last_refusal(), hw::ARMS_REFUSAL_NONFINITE);
  EXPECT_EQ(s.last_refused_seq(), 777u);
  EXPECT_EQ(s.last_refused_index(), 1u);
  // An arm it does not have.
  hw::ArmsCommand third;
  ht::to_wire(t, true, &third);
  third.mutable_arm(0)->set_index(2);
  EXPECT_FALSE(d.robot.command(third, 778, d.robot.time_ns()));
  d.robot.state(&s);
  EXPECT_EQ(s.refusals(), 2u);
  EXPECT_EQ(s.last_refusal(), hw::ARMS_REFUSAL_UNKNOWN_ARM);
}

TEST(TwoArmRobot, LinkLossHoldsTheBoxAndThePose) {
  Driver d;
  const ht::ArmMount& right = d.robot.sim().model().arm(ht::Side::kRight);
  const Eigen::Vector3d box0 = d.robot.sim().body_pose_A("box").translation();
  const Eigen::Isometry3d grasp = ht::downward_grasp(box0 + Eigen::Vector3d(0, 0, 0.035));
  const auto q = ht::grasp_inverse_kinematics(right, grasp, right.rest_q);
  ASSERT_TRUE(q);
  d.robot.reset({*q, d.robot.sim().model().arm(ht::Side::kLeft).rest_q}, {0.108, 0.0});
  d.robot.set_link(true, true);
  ht::TwoArmTargets t = d.robot.active_targets();
  t.T_A_G[0] = grasp;
  d.arm(t);
  // Close on the box with 30 N, then lift it 12 cm in 1.2 s.
  t.gripper[0] = {0.0, 30.0};
  d.run(0.8, true, [&](double) { return t; });
  ASSERT_TRUE(d.robot.control_output().gripper[0].holding);
  const ht::TwoArmTargets grasped = t;
  d.run(1.2, true, [&](double s) {
    ht::TwoArmTargets u = grasped;
    u.T_A_G[0].translation().z() += 0.12 * std::min(1.0, s / 1.0);
    return u;
  });
  const double lifted = d.robot.sim().body_pose_A("box").translation().z();
  EXPECT_GT(lifted - box0.z(), 0.10);
  // Lose the link while the arm is still moving up (a new target 5 cm higher
  // was being followed).
  t = grasped;
  t.T_A_G[0].translation().z() += 0.17;
  d.run(0.05, true, [&](double) { return t; });
  d.robot.set_link(true, false);
  const Eigen::Vector3d at_loss = d.grasp(ht::Side::kRight);
  d.sending = false;
  double max_drift = 0.0;
  for (int k = 0; k < 3000; ++k) {
    d.robot.step();
    max_drift = std::max(max_drift, (d.grasp(ht::Side::kRight) - at_loss).norm());
  }
  const double box_z = d.robot.sim().body_pose_A("box").translation().z();
  EXPECT_TRUE(d.robot.safety() & hw::SAFETY_LINK_LOST);
  EXPECT_FALSE(d.robot.following());
  // Not dropped: the box is where the held gripper is, off the bench.
  EXPECT_GT(box_z - box0.z(), 0.10);
  EXPECT_TRUE(d.robot.control_output().gripper[0].holding);
  // At rest, near where the link was lost.
  EXPECT_LT(d.grasp_speed(ht::Side::kRight), 0.001);
  EXPECT_LT(d.grasp_speed(ht::Side::kLeft), 0.001);
  EXPECT_LT(max_drift, 0.015);
  std::printf("link loss: grasp frame at rest %.1f mm from where the link was lost (max %.1f mm), box %.1f mm above the bench start\n",
              1e3 * (d.grasp(ht::Side::kRight) - at_loss).norm(), 1e3 * max_drift, 1e3 * (box_z - box0.z()));
  // The link comes back: pressed commands alone do not move it.
  d.robot.set_link(true, true);
  d.sending = true;
  const Eigen::Vector3d held = d.grasp(ht::Side::kRight);
  ht::TwoArmTargets back = t;
  back.T_A_G[0].translation() = held + Eigen::Vector3d(0.0, 0.0, -0.05);
  d.run(0.5, true, [&](double) { return back; });
  EXPECT_FALSE(d.robot.following());
  EXPECT_LT((d.grasp(ht::Side::kRight) - held).norm(), 0.003);
  d.arm(back);
  d.run(1.0, true, [&](double) { return back; });
  EXPECT_TRUE(d.robot.following());
  EXPECT_LT((d.grasp(ht::Side::kRight) - back.T_A_G[0].translation()).norm(), 0.03);  // sags under the 2 kg box
}

TEST(TwoArmRobot, EStopStopsBothArms) {
  Driver d;
  d.robot.set_link(true, true);
  const ht::TwoArmTargets t0 = d.robot.active_targets();
  d.arm(t0);
  auto circling = [&](double s) {
    ht::TwoArmTargets u = t0;
    const double w = 2.0 * std::numbers::pi * 0.5;
    u.T_A_G[0].translation() += 0.08 * Eigen::Vector3d(std::cos(w * s) - 1.0, std::sin(w * s), 0.0);
    u.T_A_G[1].translation() += 0.08 * Eigen::Vector3d(0.0, std::sin(w * s), 1.0 - std::cos(w * s));
    return u;
  };
  d.run(1.2, true, circling);
  EXPECT_GT(d.grasp_speed(ht::Side::kRight), 0.05);  // moving
  d.robot.set_estop(true);
  const Eigen::Vector3d r_at = d.grasp(ht::Side::kRight), l_at = d.grasp(ht::Side::kLeft);
  // The operator keeps streaming: ignored.
  d.run(1.0, true, [&](double s) { return circling(1.2 + s); });
  EXPECT_TRUE(d.robot.safety() & hw::SAFETY_ESTOP);
  EXPECT_LT(d.grasp_speed(ht::Side::kRight), 0.01);
  EXPECT_LT(d.grasp_speed(ht::Side::kLeft), 0.01);
  std::printf("e-stop: 1 s after, the grasp frames move at %.1f and %.1f mm/s\n", 1e3 * d.grasp_speed(ht::Side::kRight),
              1e3 * d.grasp_speed(ht::Side::kLeft));
  const double r_stop = (d.grasp(ht::Side::kRight) - r_at).norm(), l_stop = (d.grasp(ht::Side::kLeft) - l_at).norm();
  EXPECT_LT(r_stop, 0.03);
  EXPECT_LT(l_stop, 0.03);
  std::printf("e-stop: stopped %.1f mm (right) and %.1f mm (left) from where it was engaged\n", 1e3 * r_stop, 1e3 * l_stop);
  // At rest 3 s after (the null-space motion settles last).
  d.run(2.0, true, [&](double s) { return circling(2.2 + s); });
  EXPECT_LT(d.grasp_speed(ht::Side::kRight), 0.0005);
  EXPECT_LT(d.grasp_speed(ht::Side::kLeft), 0.0005);
  std::printf("e-stop: 3 s after, %.2f and %.2f mm/s, %.1f and %.1f mm from where it was engaged\n",
              1e3 * d.grasp_speed(ht::Side::kRight), 1e3 * d.grasp_speed(ht::Side::kLeft),
              1e3 * (d.grasp(ht::Side::kRight) - r_at).norm(), 1e3 * (d.grasp(ht::Side::kLeft) - l_at).norm());
  // Released: still held until re-armed.
  d.robot.set_estop(false);
  d.run(0.3, true, [&](double s) { return circling(2.2 + s); });
  EXPECT_FALSE(d.robot.following());
}

// The 1 kHz tick (safety, both arms' control, the plant's step) does not
// touch the heap: counted by the replacement allocator, while following and
// while holding.
TEST(TwoArmRobot, StepDoesNotAllocate) {
  Driver d;
  d.robot.set_link(true, true);
  ht::TwoArmTargets t = d.robot.active_targets();
  t.T_A_G[0].translation().x() += 0.04;
  d.arm(t);
  d.run_idle(0.2);
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t probe = hemm::test::counted_allocations();
  {
    auto* p = new std::array<double, 16>{};  // the counter counts (kept from being optimised away)
    asm volatile("" : : "g"(p) : "memory");
    delete p;
  }
  ASSERT_GT(hemm::test::counted_allocations(), probe);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int k = 0; k < 1000; ++k) d.robot.step();
  d.robot.set_estop(true);
  for (int k = 0; k < 1000; ++k) d.robot.step();
  const std::uint64_t after = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_FALSE(d.robot.following());
}
