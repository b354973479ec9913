#include "operator/station/arm_refusals.h"

namespace hemm::op {

const char* short_name(wire::ArmRefusalReason r) {
  switch (r) {
    case wire::ARM_REFUSAL_UNSPECIFIED: return "none";
    case wire::ARM_REFUSAL_FLOOR: return "floor";
    case wire::ARM_REFUSAL_BASE: return "base";
    case wire::ARM_REFUSAL_SCENE: return "scene";
    default: break;
  }
  return "?";
}

std::optional<ArmRefusalEvent> observe_arm_refusals(ArmRefusalMonitor& m, const wire::RobotState& s,
                                                    std::string* error) {
  const auto bad = [&](const char* why) -> std::optional<ArmRefusalEvent> {
    ++m.summary.errors;
    if (error != nullptr) *error = why;
    return std::nullopt;
  };
  const int reason = static_cast<int>(s.last_arm_refusal());
  if (!wire::ArmRefusalReason_IsValid(reason) || reason == wire::ARM_REFUSAL_UNSPECIFIED) {
    if (s.arm_refusals() == 0 && reason == wire::ARM_REFUSAL_UNSPECIFIED) {
      // None in this epoch (or an older robot that does not say).
      if (s.frame_epoch() != m.frame_epoch) {
        m.frame_epoch = s.frame_epoch();
        m.count = 0;
      }
      return std::nullopt;
    }
    return bad(wire::ArmRefusalReason_IsValid(reason) ? "arm refusal count without a reason"
                                                      : "unknown arm refusal reason");
  }
  if (s.arm_refusals() == 0) return bad("arm refusal reason without a count");
  if (s.frame_epoch() != m.frame_epoch) {
    m.frame_epoch = s.frame_epoch();
    m.count = 0;
  }
  if (s.arm_refusals() <= m.count) return std::nullopt;  // seen, or an older state
  ArmRefusalEvent e;
  e.reason = static_cast<wire::ArmRefusalReason>(reason);
  e.seq = s.last_refused_seq();
  e.new_refusals = s.arm_refusals() - m.count;
  e.total = s.arm_refusals();
  m.count = s.arm_refusals();
  ArmRefusalSummary& sum = m.summary;
  sum.refused += e.new_refusals;
  ++sum.events;
  ++(e.reason == wire::ARM_REFUSAL_FLOOR ? sum.floor : e.reason == wire::ARM_REFUSAL_BASE ? sum.base : sum.scene);
  sum.last_reason = e.reason;
  sum.last_seq = e.seq;
  return e;
}

}  // namespace hemm::op
