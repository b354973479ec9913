// The tasks' truth judge (task_truth.h) on states built by hand in the
// SIMULATED workbench: objects put where the verdict must say yes and where
// it must say no, the forces against closed forms (the robot's wrist force
// limit, twice the grip force) and against MuJoCo's own wrist sensor.
#include "robot_side/twoarm/task_truth.h"
#include "robot_side/twoarm/twoarm_robot.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

namespace ht = hemm::twoarm;
namespace hw = hemm::wire;

namespace {

using hemm::test::kWorkbenchScene;

// Puts a free body at p (A = W) with rotation R, zero velocity.
void truth_test_place(ht::WorkbenchSim& sim, const char* body, const Eigen::Vector3d& p,
                      const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  mjModel* m = sim.m();
  mjData* d = sim.d();
  const int b = mj_name2id(m, mjOBJ_BODY, body);
  ASSERT_GE(b, 0);
  const int j = m->body_jntadr[b];
  const int q = m->jnt_qposadr[j], v = m->jnt_dofadr[j];
  const Eigen::Quaterniond qu(R);
  const double x[7] = {p.x(), p.y(), p.z(), qu.w(), qu.x(), qu.y(), qu.z()};
  for (int i = 0; i < 7; ++i) d->qpos[q + i] = x[i];
  for (int i = 0; i < 6; ++i) d->qvel[v + i] = 0.0;
  mj_forward(m, d);
}

// The robot holding its arms (disarmed) while the judge watches `seconds`.
void truth_test_run(ht::TwoArmRobot& robot, const ht::TaskTruthModel& tm, ht::TaskTruthData& data, double seconds) {
  const int n = static_cast<int>(std::lround(seconds * 1000.0));
  for (int k = 0; k < n; ++k) {
    robot.step();
    ht::task_truth_tick(tm, robot.sim(), data);
  }
}

struct TruthDriver {
  ht::TwoArmRobot robot{kWorkbenchScene, ht::TwoArmRobotOptions{}};
  uint64_t seq = 0;
  void send(const ht::TwoArmTargets& t, bool deadman) {
    hw::ArmsCommand c;
    ht::to_wire(t, deadman, &c);
    robot.command(c, ++seq, robot.time_ns());
  }
  void run(const ht::TwoArmTargets& t, const ht::TaskTruthModel& tm, ht::TaskTruthData& data, double seconds) {
    const int n = static_cast<int>(std::lround(seconds * 1000.0));
    for (int k = 0; k < n; ++k) {
      if (k % 10 == 0) send(t, true);
      robot.step();
      ht::task_truth_tick(tm, robot.sim(), data);
    }
  }
};

}  // namespace

// The names the configs use read back into the tasks they name, and nothing else does.
TEST(TaskTruth, TaskNamesReadBack) {
  for (const ht::Task t : {ht::Task::kBox, ht::Task::kPeg, ht::Task::kBar})
    EXPECT_EQ(ht::task_from_string(ht::to_string(t)), t);
  for (const char* bad : {"", "Box", "ball", "?", "box "}) EXPECT_FALSE(ht::task_from_string(bad).has_value()) << bad;
}

TEST(TaskTruth, BoxOnTheShelfOrNot) {
  ht::TwoArmRobot robot(kWorkbenchScene, ht::TwoArmRobotOptions{});
  const ht::TaskTruthModel tm = ht::make_task_truth_model(robot.sim(), ht::Task::kBox);
  // The board's top centre, from the scene's numbers: shelf at (0.60, -0.72), board top 0.95.
  EXPECT_NEAR((tm.goal - Eigen::Vector3d(0.60, -0.72, 0.95)).norm(), 0.0, 1e-9);
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.3);  // on the bench, where it starts
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_FALSE(v.goal);
    EXPECT_FALSE(v.success);
    EXPECT_TRUE(v.end.on_start_support);
    EXPECT_FALSE(v.dropped);
    EXPECT_NEAR(v.end.object_env_force_N, 2.0 * 9.81, 0.5);  // its weight on the bench
  }
  // Set on the board (0.3 mm into it), at its centre: on the shelf.
  truth_test_place(robot.sim(), "box", Eigen::Vector3d(0.60, -0.72, 0.95 + 0.075 - 0.0003));
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.3);
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_TRUE(v.goal) << v.why;
    // Put there by hand, carried by no gripper: the task (both hands) is not done...
    EXPECT_FALSE(v.success);
    EXPECT_FALSE(v.carried[0] || v.carried[1]);
    EXPECT_NE(v.why.find("carried by 0 hand(s), not 2"), std::string::npos) << v.why;
    // ...and judged without the carry, it is.
    ht::TaskTruthParams no_hands;
    no_hands.box_hands = 0;
    EXPECT_TRUE(ht::task_truth_verdict(ht::make_task_truth_model(robot.sim(), ht::Task::kBox, no_hands), data).success) << v.why;
    EXPECT_TRUE(v.end.on_goal_support);
    EXPECT_LT(v.end.goal_xy_err_m, 1e-3);
    EXPECT_LT(std::abs(v.end.goal_z_err_m), 2e-3);
    EXPECT_GE(v.completion_s, 0.0);
  }
  // On the board 4 cm off its centre (still resting on it): beyond the 3 cm tolerance.
  truth_test_place(robot.sim(), "box", Eigen::Vector3d(0.64, -0.72, 0.95 + 0.075 - 0.0003));
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.3);
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_TRUE(v.end.on_goal_support);
    EXPECT_NEAR(v.end.goal_xy_err_m, 0.04, 2e-3);
    EXPECT_FALSE(v.goal);
  }
  // On the floor: dropped.
  truth_test_place(robot.sim(), "box", Eigen::Vector3d(0.20, -0.60, 0.075 - 0.0003));
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.1);
    EXPECT_TRUE(data.touched_floor);
    EXPECT_TRUE(ht::task_truth_verdict(tm, data).dropped);
  }
}

TEST(TaskTruth, PegInTheHoleOrBeside) {
  ht::TwoArmRobot robot(kWorkbenchScene, ht::TwoArmRobotOptions{});
  const ht::TaskTruthModel tm = ht::make_task_truth_model(robot.sim(), ht::Task::kPeg);
  // In the hole, resting on its bottom (the base plate's top, 0.76): 40 mm in.
  truth_test_place(robot.sim(), "peg", Eigen::Vector3d(0.55, 0.30, 0.76 + 0.05 - 0.0003));
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.3);
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_NEAR(v.end.depth_m, 0.040, 1e-3);
    EXPECT_LT(v.end.axis_offset_m, 0.001);
    EXPECT_TRUE(v.goal) << v.why;
    EXPECT_TRUE(v.success) << v.why;
  }
  // Standing on the bench beside the fixture: not in.
  truth_test_place(robot.sim(), "peg", Eigen::Vector3d(0.55, 0.40, 0.75 + 0.05 - 0.0003));
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.3);
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_NEAR(v.end.depth_m, 0.80 - 0.75, 1e-3);  // its end 5 cm below the hole's top...
    EXPECT_GT(v.end.axis_offset_m, 0.09);            // ...but 10 cm beside its axis
    EXPECT_FALSE(v.goal);
  }
}

TEST(TaskTruth, BarHeldByTheRightOnlyOrDropped) {
  TruthDriver dr;
  ht::TwoArmRobot& robot = dr.robot;
  const ht::TaskTruthModel tm = ht::make_task_truth_model(robot.sim(), ht::Task::kBar);
  {
    ht::TaskTruthData data;
    truth_test_run(robot, tm, data, 0.2);  // on its stands
    const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
    EXPECT_TRUE(v.end.on_start_support);
    EXPECT_FALSE(v.goal);
  }
  // The right gripper in the air, open round the bar (put there by hand).
  const ht::ArmMount& right = robot.sim().model().arm(ht::Side::kRight);
  const Eigen::Isometry3d G = ht::downward_grasp(Eigen::Vector3d(0.45, -0.10, 0.95));
  const auto q = ht::grasp_inverse_kinematics(right, G, right.rest_q);
  ASSERT_TRUE(q);
  robot.reset({*q, robot.sim().model().arm(ht::Side::kLeft).rest_q}, {0.02, 0.0});
  robot.set_link(true, true);
  truth_test_place(robot.sim(), "bar", robot.sim().grasp_site_A(ht::Side::kRight).translation() + Eigen::Vector3d(0, 0.10, 0));  // the bar's geom lies along the body's y
  ht::TwoArmTargets t = robot.active_targets();
  t.T_A_G[0] = G;
  t.gripper[0] = {0.0, 30.0};
  dr.send(t, false);
  ht::TaskTruthData data;
  dr.run(t, tm, data, 1.0);
  ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
  EXPECT_EQ(v.end.pads_on_object[0], 2);
  EXPECT_TRUE(v.goal) << v.why;
  EXPECT_TRUE(v.success) << v.why;
  EXPECT_TRUE(data.lifted);
  // Twice the grip force between the pads (MuJoCo's touch sensors).
  EXPECT_NEAR(v.end.squeeze_N, 2.0 * 30.0, 0.1 * 60.0);
  // All of it the right hand's; the right carried it (both pads, off the stands), the left not.
  EXPECT_NEAR(v.end.hand_squeeze_N[0], 2.0 * 30.0, 0.1 * 60.0);
  EXPECT_EQ(v.end.hand_squeeze_N[1], 0.0);
  EXPECT_TRUE(v.carried[0]);
  EXPECT_FALSE(v.carried[1]);
  // The bar's weight (0.5 kg) on the gripper.
  EXPECT_NEAR(v.end.gripper_force_A[0].z(), -0.5 * 9.81, 0.5);
  // Let go: it falls to the bench, unsupported: dropped.
  t.gripper[0] = {0.06, 30.0};
  dr.run(t, tm, data, 1.0);
  v = ht::task_truth_verdict(tm, data);
  EXPECT_TRUE(v.dropped);
  EXPECT_FALSE(v.goal);
  EXPECT_FALSE(v.success);
}

// Pressing on the bench at the robot's wrist force limit: the judge's
// contact force on the gripper is the limit (closed form, 40 N up) and what
// MuJoCo's wrist sensor reads without the gripper's weight.
TEST(TaskTruth, WristForceIsTheContactForceOnTheGripper) {
  TruthDriver dr;
  ht::TwoArmRobot& robot = dr.robot;
  const ht::TaskTruthModel tm = ht::make_task_truth_model(robot.sim(), ht::Task::kBox);
  robot.set_link(true, true);
  ht::TwoArmTargets t = robot.active_targets();
  dr.send(t, false);
  // The right grasp frame down onto the bench at (0.50, -0.10), told to go 10 cm in.
  ht::TaskTruthData data;
  for (double z : {0.90, 0.80, 0.65}) {
    t.T_A_G[0] = ht::downward_grasp(Eigen::Vector3d(0.50, -0.10, z));
    dr.run(t, tm, data, 1.5);
  }
  const ht::TaskTruthSample s = ht::task_truth_sample(tm, robot.sim());
  ASSERT_TRUE(s.gripper_in_contact[0]);
  // Up, at the limit (the spring yields at 40 N; the bench's friction takes a
  // part of it sideways).
  EXPECT_NEAR(s.gripper_force_A[0].norm(), 40.0, 2.0);
  EXPECT_GT(s.gripper_force_A[0].z(), 35.0);
  const Eigen::Vector3d sensor = robot.control_output().wrench_ext_A[0].head<3>();
  EXPECT_LT((s.gripper_force_A[0] - sensor).norm(), 1.0) << s.gripper_force_A[0].transpose() << " vs " << sensor.transpose();
  const ht::TaskVerdict v = ht::task_truth_verdict(tm, data);
  EXPECT_GE(v.wrist_peak_N[0], 38.0);
  EXPECT_LE(v.wrist_rms_N[0], v.wrist_peak_N[0]);
  EXPECT_FALSE(s.gripper_in_contact[1]);
  std::printf("pressing on the bench at the 40 N limit: contact force on the gripper %.2f N (wrist sensor %.2f N), peak %.2f N (the impact)\n",
              s.gripper_force_A[0].norm(), sensor.norm(), v.wrist_peak_N[0]);
}
