// The two-arm robot's 1 kHz arm controller (issue 25), one arm: Cartesian
// impedance of the grasp frame G with gravity and Coriolis compensation, a
// null-space posture, joint-limit springs and the torque limits; the wrist
// force limit beyond which the commanded pose yields. Free functions over the
// nominal model (Pinocchio style); allocation-free, no I/O. The arm-arm and
// arm-bench repulsion (avoidance.h) is added by the caller as joint torques.
//
//   w     = [ K_t e_p - D_t v ;  K_r e_r - D_r omega ]   at G, in A
//   e_p   = p_d - p,  e_r = log(R_d R^T) (rotation vector)
//   the spring parts K_t e_p and K_r e_r yield at force_limit_N and
//   torque_limit_Nm: capped so that the spring plus the static wrench at G
//   of the other torques (joint-limit springs, avoidance, the projector's
//   leakage near singularities) stays within the limit. Past it the
//   commanded pose yields (the set point the arm works to is moved to where
//   the spring force is what the limit allows), so at rest the arm never
//   pushes on what it meets harder than the limit, whatever it is told.
//   Damping is dissipative and not capped; the gravity model's errors are
//   not in it (the nominal model is the simulated arm here).
//   tau   = J_G^T w + C(q, qd) qd + g(q) + N (K_n (q_rest - q) - D_n qd)
//           + tau_joint_limits,    N = I - J^T (J J^T + lambda^2 I)^-1 J
//   then each joint clamped to +-tau_max.
// The null-space projector N takes out of the posture torque what would act
// at G, so the posture does not change the stiffness G shows.
#pragma once

#include <optional>
#include <string>

#include "common/kinematics/arm7.h"
#include "robot_side/twoarm/twoarm_model.h"

namespace hemm::twoarm {

struct ImpedanceParams {
  double stiffness_N_per_m = 1000.0;
  double damping_Ns_per_m = 60.0;
  double rot_stiffness_Nm_per_rad = 60.0;
  double rot_damping_Nms_per_rad = 2.5;
  double force_limit_N = 40.0;    // the wrist force limit
  double torque_limit_Nm = 8.0;   // its rotational part
  double null_stiffness_Nm_per_rad = 8.0;
  double null_damping_Nms_per_rad = 2.0;
  double null_lambda = 0.01;      // damping of the projector near singularities
  double joint_limit_margin_rad = 0.12;  // springs start this far inside the limits
  double joint_limit_stiffness_Nm_per_rad = 300.0;
  double joint_limit_damping_Nms_per_rad = 10.0;
  bool compensate_coriolis = true;
};

// Empty when usable (finite, non-negative; positive limits; a margin below
// half the smallest joint range).
std::optional<std::string> validate(const ImpedanceParams& p, const kinematics::Arm7Model& arm);

struct ImpedanceInput {
  kinematics::Arm7Vector q = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector qd = kinematics::Arm7Vector::Zero();
  Eigen::Isometry3d T_A_G_d = Eigen::Isometry3d::Identity();  // the commanded grasp pose
  // Extra joint torques added before the torque limit (the avoidance's).
  kinematics::Arm7Vector tau_extra = kinematics::Arm7Vector::Zero();
};

struct ImpedanceOutput {
  kinematics::Arm7Vector tau = kinematics::Arm7Vector::Zero();  // after the torque limits
  kinematics::Arm7Vector tau_bias = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector tau_task = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector tau_null = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector tau_limits = kinematics::Arm7Vector::Zero();
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();  // where G is
  kinematics::Wrench6 twist_A = kinematics::Wrench6::Zero();  // v, omega of G
  kinematics::Wrench6 wrench_A = kinematics::Wrench6::Zero(); // the commanded wrench at G
  Eigen::Isometry3d T_A_G_yielded = Eigen::Isometry3d::Identity();  // the set point after the limits
  bool force_limited = false;   // the commanded pose yielded
  bool torque_limited = false;  // a joint torque was clamped
};

// `frames` must be forward_kinematics(mount.arm, in.q). Allocation-free.
void arm_impedance(const ArmMount& mount, const Eigen::Vector3d& gravity_Ar, const ImpedanceParams& p,
                   const ImpedanceInput& in, const kinematics::Arm7Frames& frames, ImpedanceOutput& out) noexcept;

// The rotation vector of R (angle times axis; angle in [0, pi]).
Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R);

}  // namespace hemm::twoarm
