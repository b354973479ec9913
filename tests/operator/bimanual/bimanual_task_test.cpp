// The bimanual station's environment task: the plane pushes back along its
// normal in proportion to the depth (never pulls), the orientation spring
// turns the handle back, the grip object pushes on the forefinger only with
// a grip handle past the contact, a disabled end-effector gets nothing, and
// no setpoint goes to a robot.
#include "operator/bimanual/bimanual_task.h"

#include <gtest/gtest.h>

using hemm::op::BimanualTask;
using hemm::op::HandEnvironment;
namespace hd = hemm::device;

TEST(BimanualTask, PlaneOrientationAndGrip) {
  HandEnvironment e;
  e.plane_point_H = Eigen::Vector3d(0, 0, 0.2);
  e.plane_normal_H = Eigen::Vector3d::UnitZ();
  e.plane_stiffness = 2000;
  e.plane_damping = 10;
  e.orientation_stiffness = 3.0;
  e.orientation_damping = 0.0;
  e.grip_object = true;
  e.grip_object_at_m = 0.01;
  e.grip_object_stiffness = 500;
  BimanualTask task({e, e});
  hd::DeviceSample s;
  s.end_effectors = 2;
  s.ee[0].position_H = Eigen::Vector3d(0.1, 0.0, 0.25);  // above: nothing
  s.ee[1].position_H = Eigen::Vector3d(0.1, 0.0, 0.18);  // 2 cm in, moving down at 0.1 m/s
  s.ee[1].velocity_H = Eigen::Vector3d(0, 0, -0.1);
  s.ee[1].handle.has_grip = true;
  s.ee[1].handle.grip_position = 0.014;
  s.ee[0].handle.grip_position = 0.014;  // no grip handle: no grip force
  hemm::servo::ModelSnapshot m;
  hemm::servo::TickOutput out;
  task.tick(s, m, out);  // the first tick takes the starting orientations
  EXPECT_FALSE(out.publish_setpoint);
  EXPECT_TRUE(out.command.ee[0].force_H.isZero(0.0));
  EXPECT_LT((out.command.ee[1].force_H - Eigen::Vector3d(0, 0, 2000 * 0.02 + 10 * 0.1)).norm(), 1e-9);
  EXPECT_LT((out.points[1].proxy_position_H - Eigen::Vector3d(0.1, 0.0, 0.2)).norm(), 1e-12);
  EXPECT_NEAR(out.command.ee[1].grip_force, 500 * 0.004, 1e-12);
  EXPECT_EQ(out.command.ee[0].grip_force, 0.0);
  // Leaving fast: the damper would pull, the plane does not.
  s.ee[1].position_H.z() = 0.199;
  s.ee[1].velocity_H = Eigen::Vector3d(0, 0, 5.0);
  hemm::servo::TickOutput out2;
  task.tick(s, m, out2);
  EXPECT_TRUE(out2.command.ee[1].force_H.isZero(0.0));
  // Turned 0.2 rad about z from the start: the spring turns it back.
  s.ee[0].orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
  hemm::servo::TickOutput out3;
  task.tick(s, m, out3);
  EXPECT_LT((out3.command.ee[0].torque_H - Eigen::Vector3d(0, 0, -3.0 * 0.2)).norm(), 1e-12);
  // Disabled: nothing at all.
  s.ee[1].enabled = false;
  hemm::servo::TickOutput out4;
  task.tick(s, m, out4);
  EXPECT_TRUE(out4.command.ee[1].force_H.isZero(0.0) && out4.command.ee[1].torque_H.isZero(0.0));
  EXPECT_EQ(out4.command.ee[1].grip_force, 0.0);
}
