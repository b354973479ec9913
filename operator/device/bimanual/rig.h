// The bimanual haptic interface's rig (bimanual paper Sec. 2, Fig. 1): two
// 7-DoF LWR-class arms mounted horizontally at a column above a table, with a
// handle on each flange. Geometry only: pure data and free functions.
//
// Frame D (the device frame, H of the HapticDevice API): origin on the table
// top below the column's axis; x forward (from the operator towards the
// column), y to the operator's left, z up. The operator stands at x < 0 and
// faces +x. The RIGHT arm is the one the operator's right hand holds (y < 0);
// "pushing the right elbow to the right" is -y.
//
// Mounts. Each arm's frame A sits on a side face of the column at shoulder
// height, its joint-1 axis horizontal and pointing outwards (right: -y,
// left: +y). The right mount is [x_D, z_D, -y_D] turned by 45 deg about
// z_A so that the home posture has q1 ~ 0; the left mount is its mirror
// image in the plane y = 0 (with A's y axis flipped to stay right-handed), so
// the left arm mirrors the right one with q_left = diag(-1, 1, -1, 1, -1, 1,
// -1) q_right (mirror_posture). The masses are not mirrored: both arms are
// the same robot.
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/kinematics/arm7.h"

namespace hemm::device::bimanual {

inline constexpr int kArms = 2;
enum class ArmSide { kRight = 0, kLeft = 1 };
inline int index(ArmSide s) { return static_cast<int>(s); }
const char* to_string(ArmSide s);

// An axis-aligned box in D.
struct Box {
  Eigen::Vector3d min_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_D = Eigen::Vector3d::Zero();
};

struct RigGeometry {
  kinematics::Arm7Model arm = kinematics::lwr_arm_model();
  std::array<Eigen::Isometry3d, kArms> T_D_A;  // the mounts
  Box table;                                   // top face at z = 0
  Box column;
  // Capsule radii of links 1..7 (collision shapes of the plant and of the
  // collision avoidance): LWR-sized tubes, ~0.13 m diameter at the shoulder.
  kinematics::Arm7Vector link_radius;
  Eigen::Vector3d gravity_D = Eigen::Vector3d(0.0, 0.0, -9.81);
  // The right arm's home posture (hand ~0.6 m in front of the shoulder,
  // elbow out and down, every joint >= 0.7 rad from its limit); the left's
  // is mirror_posture of it.
  kinematics::Arm7Vector home_right;

  kinematics::Arm7Vector home(ArmSide s) const;
  Eigen::Vector3d gravity_A(ArmSide s) const { return T_D_A[static_cast<std::size_t>(index(s))].linear().transpose() * gravity_D; }
};

RigGeometry default_rig();

// Empty when usable (a valid arm model, finite right-handed mounts, boxes with
// min < max, positive radii, home postures within the limits).
std::optional<std::string> validate(const RigGeometry& rig);

kinematics::Arm7Vector mirror_posture(const kinematics::Arm7Vector& q);

// The mirror image of a pose in the plane y = 0 of D, with its y axis
// flipped to stay right-handed: mirror_mount(T_D_Ar) = T_D_Al.
Eigen::Isometry3d mirror_mount(const Eigen::Isometry3d& T_D_A);

}  // namespace hemm::device::bimanual
