// The SIMULATED two-arm robot (issue 25) as the station drives it: the
// workbench plant (workbench_sim.h), both arms' and grippers' 1 kHz control
// (twoarm_control.h), the commands the operator sends (arms_wire.h) and the
// robot's safety, with the mobile robot's watchdog (watchdog.h) and re-arm
// gate (motion_gate.h):
//
//   * A command is validated whole (arms_wire.h); a refused one changes
//     nothing and is counted with its reason, sequence number and index, and
//     reported in every ArmsState.
//   * The arms follow the commanded targets only while the robot is armed,
//     the newest command has the dead-man pressed and the watchdog has not
//     expired. Otherwise - dead-man released, watchdog expired, link lost, no
//     operator in control, e-stop - both arms HOLD: each works, in
//     impedance, to the grasp pose it had when the stop began (not to the
//     last target, which it may not have reached), offset by the external
//     wrench the wrist sensor measured then over the stiffness so that the
//     load it carries does not make it sag, and the grippers keep their
//     targets, so a grasped object is not dropped.
//   * After a stop other than the dead-man (e-stop, lost link, expired
//     watchdog, no operator) the robot follows nothing until re-armed: a
//     neutral command (dead-man released), then a pressed one; the pressed
//     one's targets are what it follows then (SAFETY_REARM).
//   * Direct force-feedback mode (issue 25 part 5): an arm whose newest
//     applied command carries a DirectTwist follows that twist. Each tick
//     the robot end's TDPA (tdpa_arm.h, admittance type) scales it against
//     the operator's received input energy and the twist moves the arm's
//     target (advance_target); past the wrist force limit the target is
//     pulled back to where the spring yields, so it never winds up into what
//     the arm presses on. A twist older than direct_twist_hold_ns is zero.
//     The wrench the observer pairs with it, and streams back
//     (ArmsState.direct_wrench), is the impedance's spring wrench by default
//     (a passive terminal: docs/telemanipulation_passivity.md).
//
// Not thread-safe: one thread (the station's control thread) owns it.
#pragma once

#include <cstdint>
#include <string>

#include "common/realtime/timing_stats.h"
#include "robot_side/control/motion_gate.h"
#include "robot_side/control/watchdog.h"
#include "robot_side/twoarm/arms_wire.h"
#include "robot_side/twoarm/twoarm_control.h"
#include "robot_side/twoarm/workbench_sim.h"
#include "wire.pb.h"

namespace hemm::twoarm {

struct TwoArmRobotOptions {
  TwoArmParams control{};
  ArmsCommandLimits limits{};
  int64_t watchdog_ns = 250'000'000;
  // Grip force of the grippers' initial targets (open, at the rest opening).
  double initial_grip_force_N = 10.0;
  // Direct mode (TwoArmConfig passivity, 41, 42).
  haptics::tdpa::PcMode pc_mode = haptics::tdpa::PcMode::kControl;
  bool direct_feedback_measured = false;  // false: the impedance's spring wrench
  int64_t direct_twist_hold_ns = 50'000'000;
};

struct TwoArmRobotCounters {
  uint64_t commands = 0;   // offered
  uint64_t applied = 0;    // their targets followed
  uint64_t refusals = 0;   // refused by validation (state unchanged)
  wire::ArmsRefusalReason last_refusal = wire::ARMS_REFUSAL_UNSPECIFIED;
  uint64_t last_refused_seq = 0;
  uint32_t last_refused_index = 0;
  std::string last_refusal_detail;
  uint64_t last_command_seq = 0;  // the newest applied command's
  uint64_t direct_commands = 0;     // applied with a DirectTwist
  uint64_t direct_stale_ticks = 0;  // direct ticks whose twist was too old (zeroed)
};

// What the robot reports, as plain values: the station's control thread
// copies it into a mailbox at the state rate, and the network thread makes
// the ArmsState of it (to_wire below), off the 1 kHz loop.
struct TwoArmSnapshot {
  int64_t stamp_ns = 0;
  std::array<ArmReading, kArms> readings{};
  TwoArmTargets targets;  // what the controllers work to (the commanded ones, or the hold)
  TwoArmOutput control;
  uint32_t safety = 0;
  bool armed = false, following = false;
  uint64_t last_command_seq = 0;
  uint64_t commands = 0, applied = 0;
  // The robot's own refusal record (TwoArmRobot::command; the station
  // validates on its network thread and reports its own record instead).
  uint64_t refusals = 0;
  wire::ArmsRefusalReason last_refusal = wire::ARMS_REFUSAL_UNSPECIFIED;
  uint64_t last_refused_seq = 0;
  uint32_t last_refused_index = 0;
  // The direct mode: each arm's robot-end TDPA port and the wrench it pairs
  // with the tracked twist (the environment's on the gripper, in A).
  std::array<haptics::tdpa::ArmSide, kArms> port{};
  std::array<kinematics::Wrench6, kArms> feedback_A{kinematics::Wrench6::Zero(), kinematics::Wrench6::Zero()};
  std::array<bool, kArms> direct{};
  haptics::tdpa::PcMode pc_mode = haptics::tdpa::PcMode::kControl;
  bool feedback_measured = false;
  uint64_t direct_commands = 0, direct_stale_ticks = 0;
};

// The ArmsState of a snapshot (mode and frame epoch are the station's).
void to_wire(const TwoArmModel& model, const TwoArmSnapshot& s, wire::ArmsState* out);

class TwoArmRobot {
 public:
  // Throws std::runtime_error for a bad scene or params.
  TwoArmRobot(const std::string& scene_path, const TwoArmRobotOptions& options);

  // Robot time: the simulation's (steps x timestep), ns, plus the origin
  // (0 unless set: the station sets it to its steady clock at start, so
  // stamps are station time, and moves it after a stall it skips).
  int64_t time_ns() const noexcept;
  void set_time_origin_ns(int64_t now_ns) noexcept;  // time_ns() is now_ns from here
  int64_t timestep_ns() const noexcept;

  // An operator command received at time_ns() (the watchdog counts from
  // sent_ns, at most now). False: refused (counters() say why).
  // Validates on the caller's thread, then apply().
  bool command(const wire::ArmsCommand& cmd, uint64_t seq, int64_t sent_ns);
  // The control thread's half: a command already validated
  // (validate_arms_command against recent readings) goes to the watchdog, the
  // re-arm gate and, pressed and armed, the targets. Allocation-free.
  void apply(const ValidatedArmsCommand& v, uint64_t seq, int64_t sent_ns) noexcept;
  // The robot's own neutral command (a session mode change): the arms hold as
  // after a dead-man release until the next pressed command; re-arms nothing.
  void stop_commanded_motion() noexcept;
  // The link's state, each tick before step().
  void set_link(bool operator_in_control, bool link_up) noexcept;
  void set_estop(bool engaged) noexcept;

  // SIMULATION ONLY: both arms put at joint angles q, fingers at finger_m,
  // the objects at the scene's poses; the robot holds there (disarmed).
  void reset(const std::array<kinematics::Arm7Vector, kArms>& q, const std::array<double, kArms>& finger_m);

  // One control period: safety, control, one plant step. Allocation-free.
  void step() noexcept;

  // The direct mode's robot end (read-only views for tests and the station).
  const haptics::tdpa::ArmSide& port(std::size_t arm) const noexcept { return port_[arm]; }
  // The wrench the observer paired with the twist in the newest tick.
  const kinematics::Wrench6& feedback_A(std::size_t arm) const noexcept { return feedback_A_[arm]; }
  // The twist the newest tick moved the target with (after the controller).
  const haptics::tdpa::ArmTwist& tracked_twist(std::size_t arm) const noexcept { return tracked_[arm]; }
  bool direct(std::size_t arm) const noexcept { return direct_[arm]; }
  haptics::tdpa::PcMode pc_mode() const noexcept { return o_.pc_mode; }
  // A new session: both ends' energies start from zero.
  void reset_passivity() noexcept;

  // The state to stream (stamp, arms, grippers, safety, sequence, refusals).
  void state(wire::ArmsState* out) const;
  void snapshot(TwoArmSnapshot* out) const noexcept;  // allocation-free

  bool armed() const noexcept { return gate_.armed; }
  bool following() const noexcept { return following_; }  // the commanded targets, not a hold
  uint32_t safety() const noexcept { return safety_; }
  const TwoArmRobotCounters& counters() const noexcept { return counters_; }
  // Per-tick compute of both arms' controllers (twoarm_control), ns.
  const rt::LogHistogram& control_compute() const noexcept { return compute_; }
  const TwoArmTargets& active_targets() const noexcept { return active_; }
  const TwoArmOutput& control_output() const noexcept { return out_; }
  WorkbenchSim& sim() noexcept { return sim_; }
  const WorkbenchSim& sim() const noexcept { return sim_; }

 private:
  std::array<ArmReading, kArms> readings() const noexcept;

  TwoArmRobotOptions o_;
  WorkbenchSim sim_;
  TwoArmTargets commanded_;  // the newest accepted command's (all parts)
  TwoArmTargets active_;     // what the controllers work to now
  TwoArmOutput out_;
  bool deadman_ = false;
  bool operator_in_control_ = false, link_up_ = false, estop_ = false;
  bool following_ = false;
  uint32_t safety_ = 0;
  robot::Watchdog watchdog_;
  robot::MotionGate gate_;
  TwoArmRobotCounters counters_;
  rt::LogHistogram compute_;
  int64_t origin_ns_ = 0;
  // Direct mode.
  std::array<bool, kArms> direct_{};
  std::array<haptics::tdpa::ArmTwist, kArms> twist_{};    // the newest applied
  std::array<haptics::tdpa::ArmTwist, kArms> tracked_{};  // after the controller, the newest tick
  std::array<int64_t, kArms> twist_sent_ns_{};
  std::array<haptics::tdpa::ArmSide, kArms> port_{};
  std::array<kinematics::Wrench6, kArms> feedback_A_{kinematics::Wrench6::Zero(), kinematics::Wrench6::Zero()};
  PeerEnergyRecord energy_record_;  // command()'s own decreasing check
};

}  // namespace hemm::twoarm
