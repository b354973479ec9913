// The controllers of the bimanual interface's arms (paper Sec. 3), running
// at 1 kHz in the device layer: impedance control with gravity (and
// Coriolis) compensation, the environment's wrench reaching the arm as
// J^T w; null-space elbow motion (Eq. 1-4) and, beside it, the dynamically
// consistent projector; feed-forward inertia reduction from the wrist
// force-torque sensor with separate gains for translation and rotation;
// collision avoidance (collision.h); and the device's own torque, speed,
// joint-range and workspace limits, enforced whatever the renderer asks.
// Pure functions plus a controller object holding the little state they need
// (the previous end-effector twist); update() is allocation-free.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "common/kinematics/arm7.h"
#include "operator/device/bimanual/collision.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/rig.h"

namespace hemm::device::bimanual {

// ---------------------------------------------------------------- null space
// The paper's Eq. 1-4 with every intermediate:
//   T_d = ^0J_4^T F_d                       (1)  (a 7-vector: [T_d; 0])
//   F_E = (^0J_7^T)^+ [T_d; 0]              (2)
//   T_comp = -^0J_7^T F_E                   (3)
//   T = [T_d; 0] + T_comp                   (4)
// i.e. T = (I - J7^T (J7^T)^+) [T_d; 0]: the projection onto the null space
// of J7. The pseudo-inverse comes from the SVD of J7^T with singular values
// below rel_tol * sigma_max taken as zero, so it is defined at singular
// configurations too.
struct NullSpaceTorques {
  kinematics::Arm7Vector T_d = kinematics::Arm7Vector::Zero();  // [T_d; 0]
  kinematics::Wrench6 F_E = kinematics::Wrench6::Zero();
  kinematics::Arm7Vector T_comp = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector T = kinematics::Arm7Vector::Zero();
};
NullSpaceTorques null_space_eq1_4(const kinematics::Arm7Jacobian& J4, const kinematics::Arm7Jacobian& J7,
                                  const kinematics::Wrench6& F_d, double rel_tol = 1e-9);

// Projectors P (tau_null = P tau_0) onto torques that do not act on the
// end-effector: kinematic, P = I - J^T (J^T)^+ (Eq. 1-4: no static force at
// the end-effector), and dynamically consistent, P = I - J^T Lambda J M^-1
// with Lambda = (J M^-1 J^T)^+ (no end-effector acceleration either).
kinematics::Arm7Matrix kinematic_null_projector(const kinematics::Arm7Jacobian& J7, double rel_tol = 1e-9);
kinematics::Arm7Matrix dynamic_null_projector(const kinematics::Arm7Jacobian& J7, const kinematics::Arm7Matrix& M,
                                              double rel_tol = 1e-9);

// Lambda = (J M^-1 J^T)^+: the end-effector's operational-space inertia
// (eigenvalues below rel_tol of the largest of J M^-1 J^T dropped).
Eigen::Matrix<double, 6, 6> operational_space_inertia(const kinematics::Arm7Jacobian& J,
                                                      const kinematics::Arm7Matrix& M, double rel_tol = 1e-9);

// kKinematic: the paper's Eq. 1-4. kDynamic: the dynamically consistent
// projector plus the compensation of the end-effector's velocity-product
// acceleration (-J^T Lambda dJ/dt qd), so that the elbow's motion does not
// accelerate the end-effector either.
enum class NullSpaceProjector { kKinematic = 0, kDynamic = 1 };
const char* to_string(NullSpaceProjector p);

// ---------------------------------------------------------- wrist sensor
// The wrench the hand applies at E (force, torque about E, in D), from the
// wrist F/T reading (handle on flange, about the flange, J7 axes) minus the
// handle's own weight and inertia (sensor load compensation). Accelerations
// are those of E (linear a_E, angular alpha) with angular velocity omega.
kinematics::Wrench6 hand_wrench_at_E(const kinematics::Wrench6& ft_J7, const Eigen::Isometry3d& T_D_J7,
                                     const HandleSpec& handle, const Eigen::Vector3d& gravity_D,
                                     const Eigen::Vector3d& a_E_D, const Eigen::Vector3d& alpha_D,
                                     const Eigen::Vector3d& omega_D);

// Moves a wrench (force, torque about `from`) to be about `to`.
kinematics::Wrench6 shift_wrench(const kinematics::Wrench6& w, const Eigen::Vector3d& from, const Eigen::Vector3d& to);

// ---------------------------------------------------------- controller
struct ArmControlParams {
  // Feed-forward inertia reduction (paper: to 33 % and 25 %). Applied as
  // inertia shaping at E: w = (1/r - 1) w_hand + (1/r) w_env per direction
  // group, so the hand feels 1/r less inertia and exactly the rendered
  // wrench at rest. r = 1 switches it off.
  bool feedforward = true;
  double inertia_ratio_translation = 0.33;
  double inertia_ratio_rotation = 0.25;
  // Null space: a force F_d at the elbow pushing it outwards (right arm to
  // -y of D, left arm to +y), projected as chosen, plus damping of the
  // null-space motion (tau = -P c M qd). The default is the dynamically
  // consistent projector: with Eq. 1-4 the elbow's motion (and the damping
  // of it) reaches the hand as a reaction force of ~0.6 N, with it a few mN
  // (arm_control_test's table).
  double elbow_force = 20.0;  // [N]
  NullSpaceProjector projector = NullSpaceProjector::kDynamic;
  double null_space_damping = 8.0;  // c [1/s]
  // Damping the hand feels (part of the rendered wrench). No plain joint
  // damping: it would resist the null-space motion with torques that reach
  // the hand.
  double cartesian_damping = 5.0;             // [N s/m]
  double cartesian_rot_damping = 0.05;        // [N m s/rad]
  bool compensate_coriolis = true;
  CollisionParams collision{};
  // Limits the device enforces whatever the renderer asks.
  double peak_force = 150.0;   // [N] rendered force at E (the LWR's ~150 N)
  double peak_torque = 25.0;   // [N m]
  Box workspace_D{};           // E must stay in this box (a stiff wall outside)
  double workspace_stiffness = 3000.0;  // [N/m]
  double workspace_damping = 60.0;      // [N s/m]
  double max_linear_speed = 1.5;        // [m/s] at E, damped beyond
  double speed_limit_damping = 400.0;   // [N s/m]
  double joint_speed_fraction = 0.8;    // joint rates damped beyond this fraction of qd_max
  double joint_speed_damping = 20.0;    // [1/s] times M_ii
  double joint_limit_margin = 0.09;     // [rad] springs start this far inside the limits
  double joint_limit_stiffness = 400.0; // [N m/rad]
};

// The box the default rig's end-effectors stay in (D): in front of the
// column, above the table.
Box default_workspace();
ArmControlParams default_arm_control();
// Empty when usable (finite, ratios in [0.1, 1], non-negative gains, a box
// with min < max above the table).
std::optional<std::string> validate(const ArmControlParams& p);

struct ArmInput {
  kinematics::Arm7Vector q = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector qd = kinematics::Arm7Vector::Zero();
  kinematics::Wrench6 ft_J7 = kinematics::Wrench6::Zero();
  kinematics::Wrench6 w_env_D = kinematics::Wrench6::Zero();  // renderer's wrench at E (force, torque), D
  bool enabled = true;  // false: brakes on / detached / dead-man open: no torque, state reset
};

struct ArmOutput {
  kinematics::Arm7Vector tau = kinematics::Arm7Vector::Zero();  // after limits
  // The terms (before the torque limit):
  kinematics::Arm7Vector tau_bias = kinematics::Arm7Vector::Zero();       // gravity (+ Coriolis)
  kinematics::Arm7Vector tau_task = kinematics::Arm7Vector::Zero();       // J_E^T (shaped wrench)
  kinematics::Arm7Vector tau_null = kinematics::Arm7Vector::Zero();       // elbow force + null damping (+ drift)
  kinematics::Arm7Vector tau_collision = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector tau_limits = kinematics::Arm7Vector::Zero();     // joint range and speed
  Eigen::Isometry3d T_D_E = Eigen::Isometry3d::Identity();
  kinematics::Wrench6 twist_E_D = kinematics::Wrench6::Zero();            // v, omega
  kinematics::Wrench6 w_env_applied_D = kinematics::Wrench6::Zero();      // renderer's wrench after the limits
  kinematics::Wrench6 w_hand_D = kinematics::Wrench6::Zero();             // estimated hand wrench at E
  kinematics::Wrench6 w_limits_D = kinematics::Wrench6::Zero();           // workspace and speed walls at E
  Eigen::Vector3d elbow_D = Eigen::Vector3d::Zero();
  bool torque_limited = false;
  bool wrench_limited = false;
  bool nonfinite_wrench = false;
};

class BimanualController {
 public:
  // Throws std::invalid_argument on a bad rig or params.
  BimanualController(const RigGeometry& rig, const std::array<HandleKind, kArms>& handles,
                     const std::array<ArmControlParams, kArms>& params, double period_s);

  void update(const std::array<ArmInput, kArms>& in, std::array<ArmOutput, kArms>& out) noexcept;
  void reset() noexcept;  // forget the previous twists (after a stop)

  const CollisionResult& collisions() const noexcept { return collision_; }
  const RigGeometry& rig() const noexcept { return rig_; }
  const HandleSpec& handle(ArmSide s) const noexcept { return handles_[static_cast<std::size_t>(index(s))]; }
  const kinematics::Arm7Model& nominal(ArmSide s) const noexcept { return nominal_[static_cast<std::size_t>(index(s))]; }
  ArmControlParams& params(ArmSide s) noexcept { return params_[static_cast<std::size_t>(index(s))]; }

 private:
  RigGeometry rig_;
  std::array<HandleSpec, kArms> handles_;
  std::array<ArmControlParams, kArms> params_;
  std::array<kinematics::Arm7Model, kArms> nominal_;  // arm + nominal handle
  double dt_;
  std::array<kinematics::Wrench6, kArms> prev_twist_{};
  std::array<bool, kArms> have_prev_{};
  std::array<kinematics::Arm7Frames, kArms> frames_{};
  std::array<ArmCapsules, kArms> capsules_{};
  CollisionResult collision_{};
};

}  // namespace hemm::device::bimanual
