// What a held object adds to the hands in the operator's model (issue 25,
// parts 3 and 4): its weight, measured by the remote wrists, and, held by
// both grippers, the rigid coupling between the hands, so that the operator
// feels the squeeze (or the stretch) the two hands put on it.
//
// Pure and allocation-free: the servo tick runs it once for both hands.
//
// * Weight (per gripper that holds, its hand engaged): the load the remote
//   wrist measures along -z_A (the environment's force on the gripper, at G:
//   the held object hangs from it), low-passed and rate-limited into the
//   felt weight, so that a delayed, noisy measurement corrects the model
//   without steps; clamped to [0, max_weight_n] (a downward push is the
//   contact rendering's, not the weight's). Released or let go, the felt
//   weight fades to 0 at the same rate.
// * Two-hand coupling (both grippers hold, both hands engaged): at the
//   moment the hold begins the commanded grasp frames' relative pose is the
//   object's (r = R_A_G0^T (p1 - p0), R_G0_G1 = R_A_G0^T R_A_G1); after it, the
//   displacement of G1 from where a rigid object held by G0 would put it,
//   e = (p1 - p0) - R_A_G0 r, and the relative turn w = Log(R_A_G1 (R_A_G0
//   R_G0_G1)^T) are pulled back by a spring and a damper between the hands:
//   F1 = -(K e + B de/dt), F0 = -F1; tau1 = -K_r w, tau0 = -tau1 (clamped).
//   Internal forces only: the pair moves the object nowhere, it tells the
//   hands that they deform it. squeeze_n = F1 . u (u from G0 to G1):
//   positive when the hands are nearer than the object allows. A gripper's
//   holding flag that drops fades the coupling out over coupling_fade_s
//   (no step); back within it, the hold goes on from the same anchor (the
//   flag flickers while the fingers settle on the object). A dead-man
//   released or the remote state lost ends it at once, as it ends every
//   displayed force.
//
// The object's inertia is not rendered (the commanded poses' acceleration
// is the servo's double difference of a rate-clamped signal: too noisy to
// feed back at 1 kHz without a filter whose lag would be felt).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>

namespace hemm::op::telemanip {

struct HeldObjectParams {
  bool weight = true;     // render the measured weight of what a gripper holds
  bool coupling = true;   // couple the hands when both grippers hold
  // Coupling, in A (the hand feels s^2 K through the translation scale s).
  double stiffness_n_per_m = 300.0;
  double damping_ns_per_m = 10.0;
  double rot_stiffness_nm_per_rad = 3.0;
  double max_force_n = 20.0;   // per hand, in A
  double max_torque_nm = 2.0;  // per hand, in A
  double coupling_fade_s = 0.2;  // a holding flag's drop fades the coupling over this
  // Weight: the measurement's low-pass time constant and the felt weight's rate.
  double weight_filter_s = 0.2;
  double weight_rate_n_per_s = 20.0;
  double max_weight_n = 30.0;  // per hand, in A
};
// Empty when usable (finite, >= 0, the filter and rate > 0).
std::string validate(const HeldObjectParams& p);

struct HeldObjectInputs {
  std::array<bool, 2> pressed{false, false};   // each hand's dead-man (the arm is engaged)
  std::array<bool, 2> holding{false, false};   // each remote gripper says it holds
  bool remote_valid = false;                   // a remote state was seen (else nothing is held)
  std::array<Eigen::Isometry3d, 2> T_A_G{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};  // commanded
  std::array<Eigen::Vector3d, 2> remote_force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // environment on gripper
};

struct HeldObjectState {
  bool both_held = false;  // the coupling is on (anchored)
  double fade = 0.0;       // its share, 1 while both hold, down to 0 over coupling_fade_s after
  Eigen::Vector3d r_G0 = Eigen::Vector3d::Zero();          // G1's origin in G0 at the hold's start
  Eigen::Matrix3d R_G0_G1 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d e_prev = Eigen::Vector3d::Zero();
  bool e_prev_valid = false;
  std::array<double, 2> load_filtered_n{0.0, 0.0};  // the measured load, low-passed
  std::array<double, 2> weight_n{0.0, 0.0};         // the felt weight (rate-limited)
  std::uint64_t holds = 0;        // two-hand holds begun
  std::uint64_t held_ticks = 0;   // steps with the coupling on
  double peak_squeeze_n = 0.0;    // |squeeze| at its largest
};

struct HeldObjectWrench {
  std::array<Eigen::Vector3d, 2> force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};   // on each hand's G
  std::array<Eigen::Vector3d, 2> torque_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double squeeze_n = 0.0;
};

// One servo step of dt seconds (> 0). Non-finite inputs hold the state and
// give no wrench.
void held_object_step(const HeldObjectParams& p, const HeldObjectInputs& in, double dt, HeldObjectState* s,
                      HeldObjectWrench* out) noexcept;

}  // namespace hemm::op::telemanip
