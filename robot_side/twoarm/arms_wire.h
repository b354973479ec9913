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
