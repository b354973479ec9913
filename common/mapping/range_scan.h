#pragma once
// A 2D range scan as the mapping code sees it: a plain value type, independent
// of the wire format (the operator's model thread converts wire RangeScan
// messages into this after validating them).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "common/math/frames.h"

namespace hemm::mapping {

enum class SensorKind : std::uint8_t { kLaser = 1, kSonar = 2 };

struct RangeScan2D {
  std::int64_t stamp_ns = 0;       // acquisition time (steady clock, ns)
  math::Pose2 T_W_R;               // robot pose at acquisition (odometry)
  math::Pose2 T_R_S;               // sensor mount on the base (x, y, yaw)
  SensorKind kind = SensorKind::kLaser;
  double angle_min = 0.0;          // rad, in S; beam i at angle_min + i * angle_step
  double angle_step = 0.0;         // rad, > 0
  std::vector<float> ranges;       // m
  std::vector<std::uint8_t> valid; // 1 = a return; 0 = dropout / no return (never an obstacle)
  std::vector<float> beam_angles;  // optional, rad, ascending; overrides angle_min/step (sonar rings)
  double range_min = 0.0;          // m
  double range_max = 0.0;          // m
  double beam_width = 0.0;         // rad, full cone angle (sonar); 0 for a laser
};

// Beam i's axis in S.
inline double beam_angle(const RangeScan2D& s, std::size_t i) {
  return s.beam_angles.empty() ? s.angle_min + static_cast<double>(i) * s.angle_step
                               : static_cast<double>(s.beam_angles[i]);
}

// A beam carries an obstacle only when flagged valid, finite, and strictly
// inside (range_min, range_max): a reading at range_max is "nothing seen".
inline bool beam_is_return(const RangeScan2D& s, std::size_t i) {
  const float r = s.ranges[i];
  return s.valid[i] != 0 && std::isfinite(r) && r >= s.range_min && r < s.range_max;
}

// What beam i says about free space along its axis: the measured range, the
// range_max for a valid "no return" (at or beyond range_max, +inf), or < 0
// when it says nothing (not valid, NaN, below range_min).
inline double beam_limit(const RangeScan2D& s, std::size_t i) {
  if (s.valid[i] == 0) return -1.0;
  const double r = static_cast<double>(s.ranges[i]);
  if (std::isnan(r) || r < s.range_min) return -1.0;
  return std::min(r, s.range_max);
}

// Empty when the scan is structurally sound; otherwise the first problem.
// Individual bad ranges (NaN, out of limits) are not errors: those beams are
// simply not returns.
std::string validate(const RangeScan2D& s);

}  // namespace hemm::mapping
