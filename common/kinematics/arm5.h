// The 5-DoF arm of the HEMM paper (Pioneer2 Arm; Section 2.2, Eq. 2-4):
// forward kinematics, geometric Jacobian, damped-least-squares rates and
// inverse kinematics. Pure computation over a const Arm5Model: no I/O, no
// clocks, no allocation.
//
// Frames. A is the arm base frame: origin on the joint-1 (yaw) axis at the
// height of the joint-2 (shoulder) axis, x forward, z up. E is the tool frame:
// origin at the tool tip, x along the tool axis. Eq. 2's ^M T_B is, in our
// naming, T_A_E (the pose of E in A).
//
// The chain (derived from the position column of Eq. 3, which is right):
//
//   T_A_E = Rz(q1) Tx(A1) Ry(-q2) Tx(A2) Ry(-q3) Tx(A4) Rx(-q4) Ry(q5) Tx(A5)
//
//   q1 base yaw, q2 shoulder pitch (positive lifts), q3 elbow pitch, q4 forearm
//   roll (about -x of the forearm), q5 wrist pitch. Eq. 3 names the link
//   lengths A1, A2, A4, A5 (Eq. 4's "i = 1, 2, 3, 5" is a misprint: A3 = 0).
//
// As a standard DH table (T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)):
//
//   i  theta_i        d_i    a_i   alpha_i
//   1  q1             0      A1    +90 deg
//   2  q2             0      A2      0
//   3  q3 - 90 deg    0      0     +90 deg
//   4  q4 + 180 deg  -A4     0     -90 deg
//   5  q5 + 90 deg    0      A5    +90 deg
//
// FIX OF EQ. 3. As printed, the second column of the rotation (a12, a22, a32)
// has the wrong sign: with it det R = -1, a reflection. The chain above gives
//   a12 =  c1 s23 s4 - s1 c4
//   a22 =  s1 s23 s4 + c1 c4
//   a32 = -c23 s4
// (the printed entries negated); all other entries, and the whole position
// column a14, a24, a34, are as printed. With the fix det R = +1.
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hemm::kinematics {

inline constexpr int kArm5Dof = 5;
using Arm5Vector = Eigen::Matrix<double, kArm5Dof, 1>;
using Arm5Jacobian = Eigen::Matrix<double, 6, kArm5Dof>;  // rows: v (3), omega (3)

// Link lengths (m) and joint limits (rad). The defaults are a Pioneer2-Arm-like
// arm with 50 cm reach from the base joint (A1 + A2 + A4 + A5).
struct Arm5Model {
  double A1 = 0.06;  // base yaw axis -> shoulder axis, radial offset
  double A2 = 0.16;  // upper arm
  double A4 = 0.14;  // forearm (shoulder.. wrist)
  double A5 = 0.14;  // wrist pitch axis -> tool tip
  Arm5Vector q_min = (Arm5Vector() << -1.75, -0.60, -2.40, -1.60, -1.60).finished();
  Arm5Vector q_max = (Arm5Vector() << 1.75, 1.60, 0.30, 1.60, 1.60).finished();

  double reach() const { return A1 + A2 + A4 + A5; }
};

// Empty when the model is usable: finite positive lengths, q_min < q_max.
std::optional<std::string> validate(const Arm5Model& model);

bool within_limits(const Arm5Model& model, const Arm5Vector& q, double tolerance = 0.0);
Arm5Vector clamp_to_limits(const Arm5Model& model, const Arm5Vector& q);

// T_A_E by the corrected closed form of Eq. 3.
Eigen::Isometry3d forward_kinematics(const Arm5Model& model, const Arm5Vector& q);

// T_A_E through the DH table above (a second, independent evaluation).
struct DhRow {
  double theta_offset;  // added to q_i
  double d;
  double a;
  double alpha;
};
std::array<DhRow, kArm5Dof> dh_table(const Arm5Model& model);
Eigen::Isometry3d dh_forward_kinematics(const Arm5Model& model, const Arm5Vector& q);

// Positions (frame A) of the joint origins 2..5 and the tool tip: used by the
// collision guard to know how far the arm sticks out.
std::array<Eigen::Vector3d, 4> arm_points(const Arm5Model& model, const Arm5Vector& q);

// Geometric Jacobian in frame A of the tool-tip velocity and tool angular
// velocity: [v_A; omega_A] = J qd.
Arm5Jacobian jacobian(const Arm5Model& model, const Arm5Vector& q);

// Tool pitch: elevation of the tool axis x_E above the horizontal plane of A,
// in [-pi/2, pi/2].
double tool_pitch(const Eigen::Isometry3d& T_A_E);

// The 5-DoF task the operator commands: tool-tip position, tool pitch, and the
// forearm roll q4 ("wrist roll", taken as a joint target).
struct Arm5Target {
  Eigen::Vector3d p_A_E = Eigen::Vector3d::Zero();
  double tool_pitch = 0.0;
  double wrist_roll = 0.0;
};

enum class IkStatus {
  kConverged,    // target reached within tolerance and joint limits
  kUnreachable,  // out of reach or limits: q is the nearest pose found
  kInvalidInput  // non-finite target or seed: q is the seed clamped to limits
};
const char* to_string(IkStatus status);

struct IkOptions {
  int max_iterations = 200;
  double position_tolerance_m = 1e-6;
  double pitch_tolerance_rad = 1e-5;
  double pitch_weight_m = 0.05;  // metres of position error worth 1 rad of pitch
  double roll_weight_m = 0.05;
  double damping = 1e-3;         // initial Levenberg-Marquardt damping (m)
  double max_step_rad = 0.3;     // per iteration, infinity norm
};

struct IkResult {
  Arm5Vector q = Arm5Vector::Zero();
  IkStatus status = IkStatus::kInvalidInput;
  double position_error_m = 0.0;  // |p_target - p(q)|
  double pitch_error_rad = 0.0;
  double roll_error_rad = 0.0;
  int iterations = 0;
};

// Damped least squares with joint-limit projection, started from the analytic
// solution for the roll-free arm and from `q_seed` (the better result wins).
// Always returns q within the limits and finite.
IkResult inverse_kinematics(const Arm5Model& model, const Arm5Target& target, const Arm5Vector& q_seed,
                            const IkOptions& options = {});

// Joint rates for a desired tool-tip velocity v_A (m/s) by damped least
// squares: qd = J^T (J J^T + lambda^2 I)^-1 v. Finite everywhere; at a
// singularity |qd| <= |v| / (2 lambda).
Arm5Vector damped_rates(const Arm5Model& model, const Arm5Vector& q, const Eigen::Vector3d& v_A, double lambda);

}  // namespace hemm::kinematics
