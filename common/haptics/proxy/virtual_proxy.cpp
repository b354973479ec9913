#include "common/haptics/proxy/virtual_proxy.h"

#include <cmath>

#include "common/haptics/proxy/proxy_core.h"

namespace hemm::haptics {

namespace {

// Scene adapter over the map snapshot: segments as capsules, one-sided. A
// map segment is a surface seen from the side its normal points to; behind
// it is unseen space, not solid. A proxy whose centre is behind a segment's
// line got there through unseen space (past the end of an object's visible
// face, or a surface appeared in front of it): that segment does not hold
// it, so it can come back out instead of being trapped behind the visible
// face with a force that stays after the hand has left.
struct SnapshotScene {
  const mapping::MapSnapshot& map;
  double behind_depth;  // ProxyModel::one_sided_depth

  std::size_t gather(const Eigen::Vector2d& c, double r, std::uint32_t* out, std::size_t cap) const {
    return mapping::query_segments(map, c, r, out, cap);
  }
  // In front of the line (h >= 0): the capsule. Behind it, over the segment
  // and no deeper than behind_depth: inside the surface, pushed out to the
  // front along its normal (negative distance). Anywhere else behind the
  // line (deeper, or beside the segment's ends): unseen space, no surface.
  detail::Surface closest(std::uint32_t id, const Eigen::Vector2d& x) const {
    const mapping::Segment2& s = map.segments[id];
    const double h = s.normal.dot(x - s.a);
    if (h >= 0.0) return detail::segment_surface(s.a, s.b, s.normal, x);
    const Eigen::Vector2d ab = s.b - s.a;
    const double t = ab.dot(x - s.a);
    // Not past the object's far side where that was seen (MapSnapshot depth_limit).
    const double depth = std::min(behind_depth, 0.5 * static_cast<double>(s.depth_limit));
    if (h < -depth) return detail::Surface{};  // unseen space: infinitely far
    if (t >= 0.0 && t <= ab.squaredNorm()) return detail::Surface{h, s.normal};
    // Beside an end, barely behind the line: the rounded end still holds.
    // Where a face meets its shadow edge (a convex corner of the outline)
    // this closes the sliver behind both lines that noise can put the
    // proxy in, which would otherwise be free.
    return detail::segment_surface(s.a, s.b, s.normal, x);
  }
  double sweep(std::uint32_t id, const Eigen::Vector2d& x, const Eigen::Vector2d& dx, double rho) const {
    const mapping::Segment2& s = map.segments[id];
    const double h = s.normal.dot(x - s.a);
    if (h >= 0.0) return detail::segment_sweep(s.a, s.b, x, dx, rho);
    // Behind the line: over the segment it is pushed out (closest()), and
    // deeper it is unseen space; beside an end within the depth only the
    // rounded end blocks.
    const Eigen::Vector2d ab = s.b - s.a;
    const double t = ab.dot(x - s.a);
    const double depth = std::min(behind_depth, 0.5 * static_cast<double>(s.depth_limit));
    if (h < -depth || (t >= 0.0 && t <= ab.squaredNorm())) return detail::kInf;
    return std::min(detail::ray_circle(x, dx, s.a, rho), detail::ray_circle(x, dx, s.b, rho));
  }
};

}  // namespace

std::string validate(const ProxyModel& m) {
  const double v[] = {m.probe_radius,          m.stiffness,           m.damping,
                      m.period,                m.force_peak,          m.force_continuous,
                      m.continuous_time_constant, m.device_max_stiffness, m.assumed_device_damping,
                      m.one_sided_depth};
  for (double x : v)
    if (!std::isfinite(x) || x < 0.0) return "proxy: parameters must be finite and >= 0";
  if (!(m.probe_radius > 0.0) || !(m.period > 0.0) || !(m.continuous_time_constant > 0.0))
    return "proxy: probe_radius, period, continuous_time_constant must be > 0";
  if (!(m.force_continuous > 0.0) || m.force_peak < m.force_continuous)
    return "proxy: need 0 < force_continuous <= force_peak";
  if (m.stiffness > m.device_max_stiffness) return "proxy: stiffness above the device's maximum";
  if (m.stiffness >= colgate_max_stiffness(m.assumed_device_damping, m.damping, m.period))
    return "proxy: stiffness violates Colgate's bound b > k T / 2 + |B|";
  if (m.max_candidates < 1 || m.max_candidates > (1u << 20)) return "proxy: max_candidates in [1, 2^20]";
  if (m.max_iterations < 1 || m.max_iterations > 64) return "proxy: max_iterations in [1, 64]";
  if (!std::isfinite(m.max_step) || !(m.max_step > 0.0)) return "proxy: max_step must be > 0";
  return {};
}

ProxyData make_proxy_data(const ProxyModel& m) {
  ProxyData d;
  d.candidates.assign(std::max<std::size_t>(1, m.max_candidates), 0u);
  return d;
}

void proxy_reset(ProxyData& d, const Eigen::Vector2d& at_W) {
  d.initialized = true;
  d.proxy_W = at_W;
  d.spring_prev.setZero();
  d.force_W.setZero();
  d.force_filtered = 0.0;
  d.contact_count = 0;
}

void proxy_tick(const ProxyModel& m, const mapping::MapSnapshot& map, ProxyData& d,
                const Eigen::Vector3d& device_W, double scale) {
  detail::god_object_tick(m, SnapshotScene{map, m.one_sided_depth}, d, device_W, scale);
}

}  // namespace hemm::haptics
