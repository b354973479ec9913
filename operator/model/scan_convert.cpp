#include "operator/model/scan_convert.h"

#include <cmath>

namespace hemm::op {
namespace {

std::optional<std::string> pose_from_wire(const proto::Pose2& p, math::Pose2* out) {
  const math::Pose2 q{p.x(), p.y(), p.theta()};
  if (!math::is_finite(q)) return std::string("non-finite pose");
  if (std::abs(q.x) > 1e6 || std::abs(q.y) > 1e6) return std::string("pose out of range");
  *out = math::Pose2{q.x, q.y, math::wrap_angle(q.theta)};
  return std::nullopt;
}

}  // namespace

std::optional<std::string> scan_from_wire(const wire::RangeScan& m, std::int64_t clock_offset_ns,
                                          mapping::RangeScan2D* out) {
  mapping::RangeScan2D s;
  if (m.stamp_ns() <= 0) return std::string("scan: bad stamp");
  s.stamp_ns = m.stamp_ns() - clock_offset_ns;
  if (!m.has_t_w_r()) return std::string("scan: no T_W_R");
  if (auto e = pose_from_wire(m.t_w_r(), &s.T_W_R)) return "scan T_W_R: " + *e;
  // T_R_S: the sensor mount; only planar mounts make sense for a 2D scan.
  if (m.has_t_r_s()) {
    const auto& p = m.t_r_s().position();
    const auto& q = m.t_r_s().orientation();
    const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
    const double n = std::sqrt(w * w + x * x + y * y + z * z);
    if (!std::isfinite(n) || std::abs(n - 1.0) > 1e-3) return std::string("scan: T_R_S quaternion not unit");
    if (std::abs(x) / n > 1e-3 || std::abs(y) / n > 1e-3) return std::string("scan: T_R_S not a rotation about z");
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || std::abs(p.x()) > 100 || std::abs(p.y()) > 100)
      return std::string("scan: bad T_R_S position");
    s.T_R_S = math::Pose2{p.x(), p.y(), math::wrap_angle(2.0 * std::atan2(z, w))};
  }
  switch (m.sensor()) {
    case wire::RANGE_SENSOR_LASER: s.kind = mapping::SensorKind::kLaser; break;
    case wire::RANGE_SENSOR_SONAR: s.kind = mapping::SensorKind::kSonar; break;
    default: return std::string("scan: unknown sensor type");
  }
  const int n = m.ranges_size();
  if (n <= 0) return std::string("scan: no beams");
  if (m.beam_count() > kMaxBeamsPerScan || static_cast<std::uint64_t>(m.first_beam()) + n > m.beam_count())
    return std::string("scan: beams outside beam_count");
  if (m.valid_size() != n) return std::string("scan: valid[] size differs from ranges[]");
  if (m.no_return_size() != 0 && m.no_return_size() != n)
    return std::string("scan: no_return[] size differs from ranges[]");
  if (m.beam_angles_size() != 0 && m.beam_angles_size() != n)
    return std::string("scan: beam_angles[] size differs from ranges[]");
  if (!std::isfinite(m.angle_min()) || !std::isfinite(m.angle_step())) return std::string("scan: bad angles");
  s.angle_step = m.angle_step();
  s.angle_min = m.angle_min() + static_cast<double>(m.first_beam()) * m.angle_step();
  s.range_min = m.range_min();
  s.range_max = m.range_max();
  s.beam_width = m.beam_width();
  s.ranges.assign(m.ranges().begin(), m.ranges().end());
  s.valid.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) s.valid[static_cast<std::size_t>(i)] = m.valid(i) ? 1 : 0;
  // "Nothing up to range_max" becomes a valid beam at range_max: not a
  // return (beam_is_return), but free space the map clears through.
  if (m.no_return_size() != 0) {
    for (int i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (m.no_return(i) && !m.valid(i)) {
        s.valid[k] = 1;
        s.ranges[k] = static_cast<float>(s.range_max);
      }
    }
  }
  if (m.beam_angles_size() != 0) s.beam_angles.assign(m.beam_angles().begin(), m.beam_angles().end());
  if (std::string e = mapping::validate(s); !e.empty()) return "scan: " + e;
  *out = std::move(s);
  return std::nullopt;
}

std::optional<std::string> state_from_wire(const wire::RobotState& m, std::int64_t clock_offset_ns,
                                           RobotStateSample* out) {
  RobotStateSample s;
  if (m.stamp_ns() <= 0) return std::string("state: bad stamp");
  s.stamp_local_ns = m.stamp_ns() - clock_offset_ns;
  if (!m.has_t_w_r_odom()) return std::string("state: no T_W_R_odom");
  if (auto e = pose_from_wire(m.t_w_r_odom(), &s.T_W_R_odom)) return "state T_W_R_odom: " + *e;
  if (m.has_t_w_r_truth()) {
    if (auto e = pose_from_wire(m.t_w_r_truth(), &s.T_W_R_truth)) return "state T_W_R_truth: " + *e;
    s.has_truth = true;
  }
  if (!std::isfinite(m.v()) || !std::isfinite(m.omega()) || std::abs(m.v()) > 100 || std::abs(m.omega()) > 100)
    return std::string("state: bad speed");
  s.v = m.v();
  s.omega = m.omega();
  s.safety = m.safety();
  s.mode = static_cast<std::uint32_t>(m.mode());
  *out = s;
  return std::nullopt;
}

}  // namespace hemm::op
