// The two-arm robot station's nominal model (issue 25): two 7-DoF LWR-class
// arms (common/kinematics lwr_arm_model(), the operator's bimanual device's
// arm) on a torso, each with a parallel-jaw gripper as payload, and the
// bench they work over. Pure data and free functions (no MuJoCo): the
// controllers run on it; workbench_sim.h reads it from the SIMULATED scene
// and refuses a scene whose arms are not this arm.
//
// Frames (docs/design.md): A the torso base (origin on the floor under the
// torso, x towards the bench, z up); Ar / Al the arms' base frames (the
// Arm7 functions' "A"), placed by T_A_Ar; J7 an arm's flange; G a gripper's
// grasp frame between its finger pads, T_J7_G from the flange.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/kinematics/arm7.h"

namespace hemm::twoarm {

inline constexpr int kArms = 2;
enum class Side { kRight = 0, kLeft = 1 };
inline constexpr std::size_t idx(Side s) { return static_cast<std::size_t>(s); }
const char* to_string(Side s);
// The prefix of a side's names in the scene: "r_" or "l_".
const char* prefix(Side s);

// A parallel-jaw gripper: two fingers on slides, each driven by a force
// motor; the opening is the distance between the pads (the sum of both
// fingers' strokes).
struct GripperSpec {
  double finger_stroke_m = 0.11;  // each finger, from closed (pads touching)
  double max_force_N = 100.0;     // per finger, the motor's limit
};

struct ArmMount {
  Eigen::Isometry3d T_A_Ar = Eigen::Isometry3d::Identity();
  kinematics::Arm7Model arm;                                 // with the gripper as a payload on link 7
  Eigen::Isometry3d T_J7_G = Eigen::Isometry3d::Identity();  // grasp frame from the flange
  GripperSpec gripper;
  kinematics::RigidBodyInertia gripper_J7;  // its mass and centre of mass (in `arm` as the payload)
  // Capsule radii of links 1..7 (the scene's collision geoms) [m].
  kinematics::Arm7Vector link_radius = kinematics::Arm7Vector::Zero();
  // The gripper's palm as a capsule in J7 (for the arm-arm avoidance).
  Eigen::Vector3d palm_a_J7 = Eigen::Vector3d::Zero(), palm_b_J7 = Eigen::Vector3d::Zero();
  double palm_radius_m = 0.0;
  // A posture within the limits the arm rests in (the null-space target).
  kinematics::Arm7Vector rest_q = kinematics::Arm7Vector::Zero();
};

// The bench top: a horizontal rectangle at height top_z (A), x and y ranges.
struct Bench {
  double top_z = 0.75;
  Eigen::Vector2d min_xy = Eigen::Vector2d(0.35, -0.9);
  Eigen::Vector2d max_xy = Eigen::Vector2d(1.05, 0.9);
};

struct TwoArmModel {
  std::array<ArmMount, kArms> arms;
  Bench bench;
  Eigen::Vector3d gravity_A = Eigen::Vector3d(0.0, 0.0, -9.81);

  const ArmMount& arm(Side s) const { return arms[idx(s)]; }
  Eigen::Vector3d gravity_Ar(Side s) const { return arm(s).T_A_Ar.linear().transpose() * gravity_A; }
};

// Empty when usable: valid arm models, rigid mounts, a grasp frame, positive
// stroke and force, positive radii, rest postures within the limits.
std::optional<std::string> validate(const TwoArmModel& model);

// The angle of the rotation that takes orientation a to b [rad, 0..pi].
double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

// The grasp frame in A for joint angles q (frames: forward_kinematics(q) in Ar).
Eigen::Isometry3d grasp_pose_A(const ArmMount& mount, const kinematics::Arm7Frames& frames_Ar);
Eigen::Isometry3d grasp_pose_A(const ArmMount& mount, const kinematics::Arm7Vector& q);
// The geometric Jacobian of G (link 7) in A: [v_G; omega] = J qd.
kinematics::Arm7Jacobian grasp_jacobian_A(const ArmMount& mount, const kinematics::Arm7Frames& frames_Ar);

// Inverse kinematics of the grasp frame: joint angles that put G at T_A_G,
// from q_seed and then from the library's seed postures; nothing when no
// seed reaches it within 1 mm and 0.01 rad, or T_A_G is not a finite rigid
// transform. Allocation-free per seed; not for the 1 kHz loop (tens of
// microseconds to milliseconds).
std::optional<kinematics::Arm7Vector> grasp_inverse_kinematics(const ArmMount& mount, const Eigen::Isometry3d& T_A_G,
                                                               const kinematics::Arm7Vector& q_seed);

// The joint angles within the limits that come closest to putting G at
// T_A_G (the same seeds, the first that reaches it, else the smallest
// residual at G: position plus 0.2 m per radian) and how far they leave G
// from it. reached: the solver converged (the flange within 1 mm and 0.01 rad). A T_A_G that is not a finite rigid
// transform gives reached false and infinite errors.
struct GraspReach {
  kinematics::Arm7Vector q = kinematics::Arm7Vector::Zero();
  bool reached = false;
  double position_error_m = 0.0;
  double orientation_error_rad = 0.0;
};
GraspReach grasp_closest_reach(const ArmMount& mount, const Eigen::Isometry3d& T_A_G, const kinematics::Arm7Vector& q_seed);

// The grasp frame pointing down at p_A (z_G = -z_A), its fingers' axis
// y_G along x_A: how the arms take the bench's objects from above.
Eigen::Isometry3d downward_grasp(const Eigen::Vector3d& p_A);

}  // namespace hemm::twoarm
