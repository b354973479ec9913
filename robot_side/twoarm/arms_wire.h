// The two-arm station's wire messages (proto/wire.proto ArmsCommand,
// ArmsState): what the robot accepts and what it reports. Everything from the
// wire is hostile: a command with a non-finite number, an arm or gripper the
// robot does not have (or one named twice), a pose that is not a rigid
// transform, a grasp pose no joint angles within the limits reach, or a
// gripper target outside the gripper's range is refused whole, with a reason
// and the index it names, and the targets stay as they were.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/haptics/passivity/tdpa_arm.h"
#include "robot_side/twoarm/twoarm_control.h"
#include "wire.pb.h"

namespace hemm::twoarm {

struct ArmsRefusal {
  wire::ArmsRefusalReason reason = wire::ARMS_REFUSAL_UNSPECIFIED;
  uint32_t index = 0;  // the arm or gripper it names
  std::string detail;
};

struct ArmsCommandLimits {
  // A target farther than this from where G is now is refused (out of
  // reach in one step: the operator's indexing is broken, or it is hostile).
  double max_target_jump_m = 0.5;
  // A target the joint limits leave G this close to (or closer) is taken:
  // the impedance pulls G as near as the limits let it, with at most the
  // stiffness times this. Farther, it is refused as out of reach. 0 takes
  // only targets the inverse kinematics reaches (1 mm, 0.01 rad).
  double reach_margin_m = 0.02;
  double reach_margin_rad = 0.1;
};

// The targets `cmd` asks for on top of `current` (arms and grippers it does
// not name keep theirs), or the refusal. `readings` seed the reachability
// check (inverse kinematics from where each arm is; not for the 1 kHz loop:
// tens of microseconds per named arm, milliseconds when the first seed fails).
struct ArmsCommandResult {
  std::optional<TwoArmTargets> targets;
  ArmsRefusal refusal;
};
ArmsCommandResult apply_arms_command(const TwoArmModel& model, const ArmsCommandLimits& limits,
                                     const wire::ArmsCommand& cmd, const TwoArmTargets& current,
                                     const std::array<ArmReading, kArms>& readings);

// The same check split in two, so that the station validates on its network
// thread (inverse kinematics is too slow for the 1 kHz loop) and the control
// thread only merges: validate_arms_command checks `cmd` whole against the
// readings and keeps the parts it names (plain values: it goes through a
// mailbox); merge_arms_command puts them on top of the current targets.
// apply_arms_command is exactly validate, then merge: the same refusals, in
// the same order, and a refused command changes nothing.
// The direct mode's parts (ArmsCommand twist, passivity): an arm named with
// a DirectTwist follows it (integrated into its target on the control
// thread) instead of a pose; one arm may not have both. A PassivityPort's six
// input energies must be finite and >= 0; not below the last ones taken is
// the caller's check (check_energy_not_decreasing: it needs the history).
struct ValidatedArmsCommand {
  std::array<bool, kArms> has_arm{}, has_gripper{};
  TwoArmTargets named;  // the named parts' targets (the others unused)
  std::array<bool, kArms> has_twist{}, has_energy{};
  std::array<haptics::tdpa::ArmTwist, kArms> twist{};
  std::array<haptics::tdpa::Vec6, kArms> peer_energy_in_J{haptics::tdpa::Vec6::Zero(), haptics::tdpa::Vec6::Zero()};
  bool deadman = false;
  wire::Mode mode = wire::MODE_UNSPECIFIED;
  // Per arm: its target was taken within the reach margin, not reached by
  // any joint angles within the limits (how far: the errors).
  std::array<bool, kArms> at_reach_edge{};
  std::array<double, kArms> reach_error_m{}, reach_error_rad{};
};
std::optional<ArmsRefusal> validate_arms_command(const TwoArmModel& model, const ArmsCommandLimits& limits,
                                                 const wire::ArmsCommand& cmd,
                                                 const std::array<ArmReading, kArms>& readings,
                                                 ValidatedArmsCommand* out);
TwoArmTargets merge_arms_command(const TwoArmTargets& current, const ValidatedArmsCommand& v) noexcept;

// The operator's input energies last taken per arm, to refuse a command whose
// energy went down (a peer that lies or restarted without a new session).
struct PeerEnergyRecord {
  std::array<bool, kArms> have{};
  std::array<haptics::tdpa::Vec6, kArms> energy_in_J{haptics::tdpa::Vec6::Zero(), haptics::tdpa::Vec6::Zero()};
};
std::optional<ArmsRefusal> check_energy_not_decreasing(const ValidatedArmsCommand& v, const PeerEnergyRecord& r);
void note_energy(const ValidatedArmsCommand& v, PeerEnergyRecord* r) noexcept;

// The command for the given targets (the operator's side, and the tests').
void to_wire(const TwoArmTargets& targets, bool deadman, wire::ArmsCommand* out);

// What the robot reports (besides the safety, mode, sequence and refusal
// fields, which the station fills).
void to_wire(const TwoArmModel& model, const std::array<ArmReading, kArms>& readings, const TwoArmTargets& targets,
             const TwoArmOutput& control, int64_t stamp_ns, wire::ArmsState* out);

// The state back (the operator's side and the tests'): false with a reason
// when it is malformed (wrong counts, non-finite values, bad poses).
std::optional<std::string> check_arms_state(const wire::ArmsState& s);

}  // namespace hemm::twoarm
