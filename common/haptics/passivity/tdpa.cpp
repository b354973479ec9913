#include "common/haptics/passivity/tdpa.h"

namespace hemm::haptics::tdpa {

const char* to_string(Receive r) noexcept {
  switch (r) {
    case Receive::kAccepted: return "accepted";
    case Receive::kOld: return "older than the newest taken";
    case Receive::kNonFinite: return "non-finite energy";
    case Receive::kNegative: return "negative energy";
    case Receive::kDecreasing: return "energy below an older message's";
  }
  return "?";
}

const char* to_string(FeedbackMode m) noexcept {
  return m == FeedbackMode::kDirect ? "direct" : "model-mediated";
}

FeedbackMode suggest_mode(double round_trip_s, double loss, FeedbackMode current, const ModeThresholds& t) noexcept {
  if (!std::isfinite(round_trip_s) || !std::isfinite(loss) || round_trip_s < 0.0 || loss < 0.0 || loss > 1.0) {
    return FeedbackMode::kModelMediated;
  }
  // Leaving direct at the thresholds, entering it only clearly below them.
  const double share = current == FeedbackMode::kDirect ? 1.0 : 1.0 - t.hysteresis;
  const bool fits = round_trip_s <= share * t.max_direct_rtt_s && loss <= share * t.max_direct_loss;
  return fits ? FeedbackMode::kDirect : FeedbackMode::kModelMediated;
}

}  // namespace hemm::haptics::tdpa
