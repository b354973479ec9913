// The 7-DoF light-weight arm of the bimanual haptic interface (DLR LWR III /
// KUKA LBR4+ class; bimanual paper Sec. 2.1, 3): forward kinematics to every
// joint (the partial chains of Sec. 3.1 and 3.3), partial and full geometric
// Jacobians, and rigid-body dynamics (gravity torque, bias torque, mass
// matrix). Pure functions over a const Arm7Model, fixed-size Eigen, no
// allocation, no I/O (Pinocchio style: f(model, frames, ...)).
//
// Frames. A is the arm base frame: origin at the mounting flange of link 0,
// z along the joint-1 axis (out of the mount). J_i (i = 1..7) is the frame of
// joint i: its origin on joint i's axis, rigidly attached to link i, so that
//
//   T_A_J1 = Tr(o_1) R(a_1, q1),   T_A_Ji = T_A_J(i-1) Tr(o_i) R(a_i, q_i)
//
// with o_i the joint offset and a_i the joint axis. At q = 0 every J_i is
// parallel to A and the arm is straight along z. J7's origin is the flange
// centre (the paper's end-effector, "7"); J4's origin is the elbow ("4").
//
// Geometry and mass data (lwr_arm_model()): joint positions along the arm
// (joint 1 at 0.102 m, shoulder 0.3105 m, joint 3 0.502 m, elbow 0.7105 m,
// joint 5 0.902 m, wrist 1.1005 m, flange 1.1785 m: shoulder ~0.31, upper arm
// 0.40, forearm 0.39, flange 0.078 m), axes z, -y, z, +y, z, -y, z, and link
// masses and centres of mass are the CAD-derived values of a public LWR4+
// description (rounded): 2.30 kg for links 1-4, 1.60, 1.49, 0.11 kg for links
// 5-7; with the fixed link 0 (1.2 kg) the arm weighs ~13.6 kg (paper: 14 kg).
// That description's inertia tensors are not physically consistent (link 7:
// 0.04 kg m^2 for 0.11 kg), so the inertias here are ASSUMED: solid cylinders
// about each centre of mass (radius 0.06 m for links 1-4, 0.05 m for 5-6,
// a 0.04 m disc for link 7). Limits: +-170/+-120 deg alternating; speeds
// 110, 110, 128, 128, 204, 184, 184 deg/s; torques 176, 176, 100, 100, 100,
// 38, 38 N m (LBR4+ data sheet). Armature (rotor inertia through the gear,
// as the joints' own torque control leaves it; ASSUMED, no public figure):
// 0.10, 0.10, 0.05, 0.05, 0.02, 0.01, 0.01 kg m^2 - it dominates the wrist's
// tiny link inertias, as on the real arm.
//
// Dynamics: our own recursive Newton-Euler (RNEA) and composite-rigid-body
// (CRBA) algorithms, in frame A. Why not MuJoCo or a library: the controller
// needs them every 1 ms on the servo thread, allocation-free, over a NOMINAL
// model that differs from the plant's (MuJoCo would need a second mjModel and
// mjData per arm and drag the engine into the pure core); KDL is not
// installed and its solvers use dynamic-size vectors; Pinocchio is not in
// Debian 12. A 7-link serial chain is ~150 lines of textbook code, and
// tests/common/kinematics/arm7_test.cpp checks it against MuJoCo's own
// mj_fullM / qfrc_bias / mj_jac on the same model (arm7_mjcf.h) and against
// closed forms. Joint friction, rotor inertia and the like are NOT in this
// rigid model (the plant has them; the controller does not know them).
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hemm::kinematics {

inline constexpr int kArm7Dof = 7;
inline constexpr int kArm7Elbow = 4;   // the paper's "4": J4's origin
inline constexpr int kArm7Flange = 7;  // the paper's "7": J7's origin
using Arm7Vector = Eigen::Matrix<double, kArm7Dof, 1>;
using Arm7Matrix = Eigen::Matrix<double, kArm7Dof, kArm7Dof>;
using Arm7Jacobian = Eigen::Matrix<double, 6, kArm7Dof>;  // rows: v (3), omega (3)
using Wrench6 = Eigen::Matrix<double, 6, 1>;              // force (3), torque (3)

// Mass, centre of mass and inertia about the centre of mass, in the frame of
// the body it belongs to.
struct RigidBodyInertia {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
};

struct Arm7Model {
  std::array<Eigen::Vector3d, kArm7Dof> offset;  // o_i: origin of J_i in J_(i-1) (J_0 = A) [m]
  std::array<Eigen::Vector3d, kArm7Dof> axis;    // a_i: unit joint axis in J_i
  std::array<RigidBodyInertia, kArm7Dof> link;   // link i in J_i
  // Reflected rotor inertia of each drive, added to the mass matrix's
  // diagonal (MuJoCo's joint armature) [kg m^2].
  Arm7Vector armature = Arm7Vector::Zero();
  Arm7Vector q_min, q_max;                       // [rad]
  Arm7Vector qd_max;                             // [rad/s]
  Arm7Vector tau_max;                            // [N m]
};

// The LWR-class arm described above.
Arm7Model lwr_arm_model();

// A solid cylinder along z about its centre (the assumed link inertias).
Eigen::Matrix3d cylinder_inertia(double mass, double radius, double length);

// Empty when usable: finite offsets, unit axes, non-negative masses,
// symmetric positive semi-definite inertias, q_min < q_max, positive speed
// and torque limits.
std::optional<std::string> validate(const Arm7Model& model);

bool within_limits(const Arm7Model& model, const Arm7Vector& q, double tolerance = 0.0);
Arm7Vector clamp_to_limits(const Arm7Model& model, const Arm7Vector& q);

// The model with a rigid payload (a handle, a tool) added to link 7; the
// payload is given in J7.
Arm7Model with_payload(const Arm7Model& model, const RigidBodyInertia& payload_J7);

// Sum of two rigid bodies given in the same frame.
RigidBodyInertia combine(const RigidBodyInertia& a, const RigidBodyInertia& b);

// Poses of every joint frame in A: T_A_J[i] is J_(i+1).
struct Arm7Frames {
  std::array<Eigen::Isometry3d, kArm7Dof> T_A_J;

  const Eigen::Isometry3d& joint(int i) const { return T_A_J[static_cast<std::size_t>(i - 1)]; }  // i = 1..7
  Eigen::Vector3d origin(int i) const { return joint(i).translation(); }
  Eigen::Vector3d axis_A(const Arm7Model& m, int i) const {
    return joint(i).linear() * m.axis[static_cast<std::size_t>(i - 1)];
  }
};

// Forward kinematics to every joint (the partial chains ^0T_i, i = 1..7).
void forward_kinematics(const Arm7Model& model, const Arm7Vector& q, Arm7Frames& frames);
// ^0T_7: the flange pose T_A_J7.
Eigen::Isometry3d flange_pose(const Arm7Model& model, const Arm7Vector& q);

// The elbow of the S-R-S arm (joints 1, 3, 5, 7 along their links, every
// offset along z, as lwr_arm_model): the shoulder (J2's origin, fixed in A)
// and the wrist centre (J6's origin, fixed in the flange frame J7) are
// sqrt(a^2 + b^2 + 2 a b cos q4) apart whatever the other joints (a: upper
// arm J2-J4, b: forearm J4-J6). So a flange pose alone fixes the elbow bend
// |q4| it needs; near |q4| = 0 (stretched) the arm is singular and cannot
// follow a hand that pulls it further.
struct Arm7Elbow {
  Eigen::Vector3d shoulder_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d wrist_J7 = Eigen::Vector3d::Zero();  // the wrist centre in J7
  double upper_arm_m = 0.0;
  double forearm_m = 0.0;
};
// Throws std::invalid_argument if the model is not S-R-S as above.
Arm7Elbow arm7_elbow(const Arm7Model& model);
// The elbow bend |q4| (rad) that puts the wrist centre at wrist_A; beyond
// full reach, minus the shortfall in metres (a negative number).
double elbow_bend(const Arm7Elbow& elbow, const Eigen::Vector3d& wrist_A);

// Geometric Jacobian ^0J_k of a point p_A rigidly attached to link k
// (1..7), in A: column i <= k is [a_i x (p - o_i); a_i], columns i > k are
// zero (joints beyond k do not move link k). [v; omega] = J qd, and a wrench
// w = [f; t] (t about p) at that point maps to joint torques J^T w.
Arm7Jacobian partial_jacobian(const Arm7Model& model, const Arm7Frames& frames, int k, const Eigen::Vector3d& p_A);
// ^0J_4 at the elbow (J4's origin; 6 x 7 with columns 5-7 zero).
Arm7Jacobian elbow_jacobian(const Arm7Model& model, const Arm7Frames& frames);
// ^0J_7 at the flange (J7's origin).
Arm7Jacobian flange_jacobian(const Arm7Model& model, const Arm7Frames& frames);

// The velocity-product ("drift") acceleration of a point p_A on link k:
// d/dt(J) qd = [a; alpha] of the point when qdd = 0 (no gravity).
Wrench6 drift_acceleration(const Arm7Model& model, const Arm7Frames& frames, const Arm7Vector& qd, int k,
                           const Eigen::Vector3d& p_A);

// Inverse dynamics (RNEA): tau = M(q) qdd + C(q, qd) qd + g(q) for
// gravity g_A (e.g. (0, 0, -9.81) expressed in A). `frames` must be
// forward_kinematics(model, q).
Arm7Vector inverse_dynamics(const Arm7Model& model, const Arm7Frames& frames, const Arm7Vector& qd,
                            const Arm7Vector& qdd, const Eigen::Vector3d& g_A);
// g(q): the torques that hold the arm still against gravity.
Arm7Vector gravity_torque(const Arm7Model& model, const Arm7Frames& frames, const Eigen::Vector3d& g_A);
// C(q, qd) qd + g(q) (MuJoCo's qfrc_bias).
Arm7Vector bias_torque(const Arm7Model& model, const Arm7Frames& frames, const Arm7Vector& qd,
                       const Eigen::Vector3d& g_A);
// M(q) by the composite-rigid-body algorithm (plus the armature).
Arm7Matrix mass_matrix(const Arm7Model& model, const Arm7Frames& frames);

}  // namespace hemm::kinematics
