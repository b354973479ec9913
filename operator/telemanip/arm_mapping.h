// Telemanipulation (issue 25, part 2): one hand of the bimanual device drives
// one remote arm. Pure, allocation-free: the servo tick runs it per hand.
//
// Frames (DESIGN.md "Frames and names"): D the device base, E the hand's
// end-effector frame on its flange (Dr/Dl), A the robot's torso base, G the
// remote gripper's grasp frame. The mapping is
//
//   p_A_G = p_A_anchor + s R_A_D (p_D_E - p_D_anchor)
//   R_A_G = Exp(k Log(R_A_D R_D_E R_D_anchor^T R_A_D^T)) R_A_anchor
//
// with R_A_D the fixed alignment of D's axes in A, s the translation scale,
// k the rotation scale (the hand's turn since the press, about the same
// axis, k times as far),
// and (p_D_anchor, R_D_anchor) / (p_A_anchor, R_A_anchor) the indexing
// offset T_Ar_Dr: the hand's pose and the arm's commanded pose when the
// dead-man was last pressed. Re-anchoring at each press (a clutch) is what
// lets the operator move the hand back without the arm following, and keeps
// the commanded pose continuous: the arm never jumps at a press. The hand's
// rotation since the press turns the gripper about G's origin, in A's axes
// as D's axes are aligned to them (rotation scale 1: the bimanual paper maps
// its arms 1:1 in rotation; above 1 a grasp turned far from the rest
// orientation is reached without the operator's wrist at its limit, and the
// hand feels k times the remote torque, so power stays the same at both
// ends, as F_D = s F_A does for the translation).
//
// Per step the commanded pose moves towards the mapped one by at most
// max_step_m and max_step_rad (a rate clamp: a hand yanked or a sample
// glitch cannot ask the remote arm for a jump). The grip lever's travel
// [0, grip_travel_m] (0 open) maps linearly to the gripper's opening
// [opening_open_m .. opening_closed_m] and its grip force
// [force_open_n .. force_closed_n]. Dead-man released: the command is not
// pressed and the commanded pose holds (the robot holds in impedance).
//
// The clutch (indexing without letting go): a button on the gating
// handle (clutch_button). Held with the dead-man pressed, the arm keeps its
// commanded pose, still pressed (the robot sees one steady pose, no re-arm),
// while the hand moves freely - the device stays powered, as it does not
// with the dead-man released (the device brakes an arm no one holds). At
// the button's release the mapping re-anchors, as at a dead-man press: the
// operator brings the hand back to where it is comfortable and goes on.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>

namespace hemm::op::telemanip {

struct ArmMappingParams {
  Eigen::Matrix3d R_A_D = Eigen::Matrix3d::Identity();  // D's axes in A (a rotation)
  double translation_scale = 1.0;                        // A metres per D metre, (0, 10]
  double rotation_scale = 1.0;                           // A radians per D radian, [1/4, 4]
  double max_step_m = 0.002;     // per step (1 kHz: 2 m/s), (0, 0.1]
  double max_step_rad = 0.006;   // per step (1 kHz: 6 rad/s), (0, 1]
  // Which end-effector's dead-man gates this arm (the grip-force handle has
  // none: its arm may be gated by the other hand's joystick dead-man).
  int deadman_ee = 0;
  // The clutch: button number (1 = kButton1, ...) on deadman_ee's handle; 0: none.
  int clutch_button = 0;
  // Grip lever -> gripper (only when the hand's handle has a grip lever).
  double grip_travel_m = 0.025;   // the lever's travel (handles.h, grip-force interface)
  double opening_open_m = 0.12;   // lever at 0
  double opening_closed_m = 0.0;  // lever at full travel
  double force_open_n = 5.0;      // grip force at lever 0 (small: fingers close gently)
  double force_closed_n = 40.0;   // at full travel
};
// The clutch button's bit in HandleInputs::buttons (0: no clutch).
constexpr std::uint32_t clutch_bit(const ArmMappingParams& p) noexcept {
  return p.clutch_button > 0 && p.clutch_button <= 32 ? 1u << (p.clutch_button - 1) : 0u;
}
// Empty when usable: finite, R_A_D a rotation (det +1), ranges as above,
// openings and forces >= 0.
std::string validate(const ArmMappingParams& p);

// The scales' allowed ranges (the mapping, the direct mode and the config
// all refuse the same): empty if both are allowed, else "<name>: must be in
// <range>" for the first that is not, named as the config's fields are.
std::string check_scales(double translation_scale, double rotation_scale);

// One hand's reading, in D (the device API's "H" for the bimanual device).
struct HandReading {
  Eigen::Isometry3d T_D_E = Eigen::Isometry3d::Identity();
  bool valid = true;      // a finite pose from an enabled end-effector
  bool deadman = false;   // the gating dead-man (ArmMappingParams::deadman_ee) pressed
  bool clutch = false;    // the clutch button (ArmMappingParams::clutch_button) held
  bool has_grip = false;  // the handle has a grip lever
  double grip_position_m = 0.0;
};

struct ArmMappingState {
  bool initialized = false;  // the commanded pose was set (from the robot's G)
  bool engaged = false;      // anchored: the dead-man is pressed and the clutch not held
  Eigen::Isometry3d T_A_G_cmd = Eigen::Isometry3d::Identity();  // what the arm is told
  Eigen::Isometry3d T_A_anchor = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_D_anchor = Eigen::Isometry3d::Identity();
  std::uint64_t presses = 0;          // re-anchorings (dead-man presses, clutch releases)
  std::uint64_t clutch_steps = 0;     // steps with the clutch held (dead-man pressed)
  std::uint64_t clamped_steps = 0;    // steps the rate clamp shortened
};

// What the servo task publishes per hand each tick (for the SIMULATED
// human's closed loop, telemanip_human.h).
struct MappingAnchor {
  bool engaged = false;
  ArmMappingState state;
};

// Off the servo thread or at its start: the commanded pose starts where the
// remote G is (first ArmsState), not anchored.
void reset_arm_mapping(ArmMappingState* s, const Eigen::Isometry3d& T_A_G) noexcept;

struct ArmCommandOut {
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();  // the commanded pose
  bool pressed = false;    // send it with the dead-man pressed
  bool clutched = false;   // pressed, but the clutch holds the pose: display nothing
  bool has_gripper = false;  // a gripper target (the handle has a lever)
  double opening_m = 0.0;
  double force_n = 0.0;
  bool clamped = false;    // this step's move was shortened by the rate clamp
};

// The pose the mapping asks for right now, unclamped (anchored state only).
Eigen::Isometry3d mapped_pose_A(const ArmMappingParams& p, const ArmMappingState& s,
                                const Eigen::Isometry3d& T_D_E) noexcept;
// Its inverse: where the hand must be in D for the mapping to ask T_A_G
// (the SIMULATED human's closed loop: targets given in A).
Eigen::Isometry3d hand_pose_D(const ArmMappingParams& p, const ArmMappingState& s,
                              const Eigen::Isometry3d& T_A_G) noexcept;

// The lever's position -> opening and force (clamped to the travel).
void grip_to_gripper(const ArmMappingParams& p, double grip_position_m, double* opening_m, double* force_n) noexcept;

// One step. Uninitialized state: nothing pressed, out->T_A_G identity. A
// non-valid reading releases (as the dead-man does) and holds the command.
void map_arm_step(const ArmMappingParams& p, const HandReading& hand, ArmMappingState* s, ArmCommandOut* out) noexcept;

}  // namespace hemm::op::telemanip
