// Telemanipulation's direct force-feedback mode, the operator end (issue 25,
// part 5; docs/telemanipulation_passivity.md "Operator end"): one hand's
// servo tick. The hand's twist, mapped into the robot's torso frame A, is
// what the link sends as DirectTwist; the robot's wrench (ArmsState
// direct_wrench, in A) is what the hand feels, through the impedance-type
// passivity controller (common/haptics/passivity/tdpa_arm.h), so the
// delayed channel stays passive: E_out(operator) <= E_in(robot, received).
//
// The hand twist is the device's measured velocity (EndEffectorSample
// velocity_H, angular_velocity_H) mapped into A, unfiltered: the observer
// must pair each tick's displayed force with the velocity that force acts on
// at that tick (a filter's lag would book power the hand did not exchange),
// and the devices hemm runs report velocity from their own state estimate at
// 1 kHz (the SIMULATED bimanual arms: the plant's joint velocities).
//
// The dead-man gates both ways: released, the twist sent is zero and the
// displayed wrench fades out over fade_s (pressed again, it fades in): a step
// of the remote wrench on the hand at a press or a release would jerk it. The
// fade only scales the wrench the controller is offered, so the controller
// can only cut it further; the observer keeps running on the real hand
// velocity, so the hand's work against a fading force is still booked.
//
// Pure, allocation-free, lock-free: called by TelemanipTask::tick.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "common/haptics/passivity/tdpa_arm.h"
#include "operator/device/haptic_device.h"

namespace hemm::op::telemanip {

namespace tdpa = hemm::haptics::tdpa;

enum class FeedbackMode { kModel, kDirect };  // TelemanipConfig.mode "model" | "direct"
const char* to_string(FeedbackMode m) noexcept;

struct DirectHandParams {
  Eigen::Matrix3d R_A_D = Eigen::Matrix3d::Identity();  // the mapping's
  double translation_scale = 1.0;                       // A metres per D metre
  double rotation_scale = 1.0;                          // A radians per D radian (arm_mapping.h)
  double max_speed_mps = 1.0;                           // the twist sent is clamped to these (in A)
  double max_rate_radps = 3.0;
  double fade_s = 0.2;            // the dead-man's fade of the displayed wrench, (0, 2]
  double peak_force_n = 0.0;      // the device's, on the hand (D); 0: no clamp
  double peak_torque_nm = 0.0;    // 0: no clamp
  // A force-only device shows no torque: then none is offered to the
  // observer either (it would book hand rotation against a torque never felt).
  bool renders_torque = true;
  double contact_force_n = 1.0;   // a remote wrist force above this is a contact tick (the report's error)
  tdpa::PcMode pc_mode = tdpa::PcMode::kControl;
};

// The robot's newest port and wrench for one arm, as the link read them
// (network thread) from an ArmsState.
struct DirectPeer {
  bool has_port = false;  // a valid PassivityPort for this arm
  std::uint64_t seq = 0;  // the state's datagram sequence
  tdpa::Vec6 energy_in_J = tdpa::Vec6::Zero();
  bool has_wrench = false;                     // a valid DirectWrench for this arm
  tdpa::Vec6 wrench_A = tdpa::Vec6::Zero();    // the wrench the robot's observer paired with the twist
  Eigen::Vector3d wrist_force_A = Eigen::Vector3d::Zero();  // ArmState force_A (the wrist sensor)
};

struct DirectHandStats {
  std::uint64_t ticks = 0;
  std::uint64_t pressed_ticks = 0;
  std::uint64_t peer_accepted = 0;
  std::uint64_t contact_ticks = 0;    // the remote wrist force above contact_force_n
  double error_sum_sq = 0.0;          // |shown - wrist| force in A, over contact ticks
  double error_max_n = 0.0;
  double shown_sum_n = 0.0;           // |shown force|, over contact ticks
  double wrist_sum_n = 0.0;           // |wrist force|, over contact ticks
  double peak_shown_n = 0.0;          // |shown force| (A), over all ticks
  // How far the mapping's commanded G and the remote's reported G went from
  // where the direct mode started (TelemanipTask fills these: did the arm
  // move as the hand did).
  bool started = false;
  Eigen::Vector3d commanded_start_A = Eigen::Vector3d::Zero(), remote_start_A = Eigen::Vector3d::Zero();
  double max_commanded_travel_m = 0.0, max_remote_travel_m = 0.0;
};

struct DirectHandState {
  tdpa::ArmSide side;
  double gain = 0.0;                 // the dead-man's fade, 0..1
  tdpa::ArmTwist hand_A;             // this tick's hand twist in A (clamped)
  tdpa::ArmTwist sent_A;             // what the link sends (zero while released)
  tdpa::ArmWrench shown_A;           // what the hand was shown, in A
  DirectHandStats stats;
};

// Empty when usable.
std::string validate(const DirectHandParams& p);

// One tick of one hand. `fresh` is the peer data of a state newer than the
// last tick's (null: none came), `latest` the newest known (null: none yet).
// Writes the device wrench (frame D) into *cmd.
void direct_hand_tick(const DirectHandParams& p, const device::EndEffectorSample& e, bool pressed,
                      const DirectPeer* fresh, const DirectPeer* latest, double dt_s, DirectHandState* s,
                      device::EndEffectorCommand* cmd) noexcept;

}  // namespace hemm::op::telemanip
