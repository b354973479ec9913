// The robot's arm-target refusals as the operator station sees them: each
// RobotState carries the robot's refusal count (this frame epoch), the
// newest refusal's reason and the refused command's sequence number
// (wire.proto RobotState). The station reports each new refusal once (a log
// line on the network thread, never the servo thread) and counts them.
// Pure: the caller logs.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "wire.pb.h"

namespace hemm::op {

struct ArmRefusalSummary {
  std::uint64_t refused = 0;  // the robot's refusals seen (sum of the count's increases)
  std::uint64_t events = 0;   // new refusals reported (one per state that showed an increase)
  std::uint64_t floor = 0, base = 0, scene = 0;  // events by the newest refusal's reason
  wire::ArmRefusalReason last_reason = wire::ARM_REFUSAL_UNSPECIFIED;
  std::uint64_t last_seq = 0;  // the newest refused command's sequence number
  std::uint64_t errors = 0;    // states with bad refusal fields (ignored)
};

struct ArmRefusalMonitor {
  std::uint64_t frame_epoch = 0;  // of the count below
  std::uint64_t count = 0;        // the robot's count as last seen
  ArmRefusalSummary summary;
};

struct ArmRefusalEvent {
  wire::ArmRefusalReason reason = wire::ARM_REFUSAL_UNSPECIFIED;
  std::uint64_t seq = 0;
  std::uint64_t new_refusals = 0;  // since the last state that showed one (> 1: several between states)
  std::uint64_t total = 0;         // the robot's count
};

// "floor", "base", "scene" ("none" for unspecified, "?" otherwise).
const char* short_name(wire::ArmRefusalReason r);

// Takes one RobotState. A count above the one seen (in the same frame
// epoch; a new epoch -- a restarted robot -- starts from 0) is a new
// refusal: counted and returned. A count below it is an older state
// (reordered): ignored. Bad fields (an unknown reason, a count without a
// reason or a reason without a count) set *error, count in errors and
// change nothing else.
std::optional<ArmRefusalEvent> observe_arm_refusals(ArmRefusalMonitor& m, const wire::RobotState& s,
                                                    std::string* error);

}  // namespace hemm::op
