// Operator-side conversions from the wire: RangeScan (one scan or one
// self-contained chunk of one) -> mapping::RangeScan2D, and RobotState -> the
// few numbers the model needs. Time stamps are mapped from the robot's clock
// into ours with the link's clock offset (robot minus local). Everything from
// the wire is hostile: a bad message returns a reason and leaves *out as it was.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/mapping/range_scan.h"
#include "common/math/frames.h"
#include "wire.pb.h"

namespace hemm::op {

inline constexpr std::uint32_t kMaxBeamsPerScan = 100000;

// A chunk becomes a scan of its own beams: angle_min is moved to the chunk's
// first beam. T_R_S must be a rotation about z (a 2D sensor mounted level).
std::optional<std::string> scan_from_wire(const wire::RangeScan& m, std::int64_t clock_offset_ns,
                                          mapping::RangeScan2D* out);

struct RobotStateSample {
  std::int64_t stamp_local_ns = 0;
  math::Pose2 T_W_R_odom;
  math::Pose2 T_W_R_truth;  // SIMULATION ONLY (evaluation); zero if the robot does not send it
  bool has_truth = false;
  double v = 0.0;
  double omega = 0.0;
  std::uint32_t safety = 0;
  std::uint32_t mode = 0;
};

std::optional<std::string> state_from_wire(const wire::RobotState& m, std::int64_t clock_offset_ns,
                                           RobotStateSample* out);

}  // namespace hemm::op
