#include "robot_side/control/collision_guard.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "common/math/frames.h"

namespace hemm::robot {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kSectorWidth = 2.0 * std::numbers::pi / kGuardSectors;

int sector_of(double bearing) {
  const int k = static_cast<int>(std::floor((bearing + std::numbers::pi) / kSectorWidth));
  return std::clamp(k, 0, kGuardSectors - 1);
}

// Raises the sectors of the arc [a, a + span] (span >= 0, radians) to at least rho.
void mark_arc(double a, double span, double rho, KnownFree& out) {
  if (!(rho > 0.0) || !std::isfinite(a) || !std::isfinite(span)) return;
  const int first = sector_of(math::wrap_angle(a));
  const int count = std::min(kGuardSectors, static_cast<int>(std::ceil(span / kSectorWidth)) + 1);
  for (int i = 0; i < count; ++i) {
    double& s = out[static_cast<std::size_t>((first + i) % kGuardSectors)];
    s = std::max(s, rho);
  }
}

struct Box2 {
  double x0, x1, h;  // [x0, x1] x [-h, h]
  bool contains(const Eigen::Vector2d& p) const { return p.x() >= x0 && p.x() <= x1 && std::abs(p.y()) <= h; }
  double max_radius() const { return std::hypot(std::max(std::abs(x0), std::abs(x1)), h); }
  // How far inside (> 0) the point is: its distance to the nearest edge.
  double depth(const Eigen::Vector2d& p) const { return std::min({p.x() - x0, x1 - p.x(), h - std::abs(p.y())}); }
};

// A point as seen from the footprint after it turned by a (ccw > 0): rotated by -a.
Eigen::Vector2d rotated(const Eigen::Vector2d& p, double a) {
  const double c = std::cos(a), s = std::sin(a);
  return {c * p.x() - s * p.y(), s * p.x() + c * p.y()};
}
constexpr double kProbeTurn = 1e-3;  // rad: which way a turn moves a point within the margin

// The angles at which the circle of radius r crosses the box's boundary.
int circle_crossings(const Box2& b, double r, double* out) {
  int n = 0;
  for (double X : {b.x0, b.x1}) {
    if (r < std::abs(X)) continue;
    const double y = std::sqrt(r * r - X * X);
    for (double s : {-1.0, 1.0})
      if (y <= b.h) out[n++] = std::atan2(s * y, X);
  }
  for (double Y : {-b.h, b.h}) {
    if (r < std::abs(Y)) continue;
    const double x = std::sqrt(r * r - Y * Y);
    for (double s : {-1.0, 1.0})
      if (s * x >= b.x0 && s * x <= b.x1) out[n++] = std::atan2(Y, s * x);
  }
  return n;
}

// An angle in (0, 2 pi].
double positive_turn(double a) {
  a = std::fmod(a, 2.0 * std::numbers::pi);
  if (a <= 0.0) a += 2.0 * std::numbers::pi;
  return a;
}

// How far (m) the corridor x >= X (ahead, sign = +1) or x <= -X (behind,
// sign = -1), |y| <= h, is known free: the first corridor point along any
// sector's bearing that lies beyond what that sector saw free.
double known_corridor_length(const KnownFree& known, double X, double h, double sign) {
  double L = kInf;
  for (int k = 0; k < kGuardSectors; ++k) {
    const double rho = known[static_cast<std::size_t>(k)];
    const double a0 = -std::numbers::pi + k * kSectorWidth;
    for (double a : {a0, a0 + 0.5 * kSectorWidth, a0 + kSectorWidth}) {
      const double c = sign * std::cos(a), s = std::abs(std::sin(a));
      if (c <= 0.0 || X * s > h * c) continue;  // the bearing never enters the corridor
      const double t_in = X / c, t_out = s > 0.0 ? h / s : kInf;
      const double t_unknown = std::max(t_in, rho);
      if (t_unknown < t_out) L = std::min(L, t_unknown * c - X);
    }
  }
  return std::max(0.0, L);
}

}  // namespace

double stoppable_speed(double d, double a, double t_r) {
  if (!(d > 0) || !(a > 0)) return 0.0;
  if (std::isinf(d)) return std::numeric_limits<double>::infinity();
  t_r = std::max(0.0, t_r);
  // v t_r + v^2 / (2a) = d  =>  v = -a t_r + sqrt(a^2 t_r^2 + 2 a d)
  return -a * t_r + std::sqrt(a * a * t_r * t_r + 2 * a * d);
}

GuardLimit collision_guard(const CollisionGuardParams& p, std::span<const Eigen::Vector2d> points,
                           const KnownFree* known) {
  GuardLimit g;
  g.free_ahead = g.free_behind = kInf;
  g.free_turn_ccw = g.free_turn_cw = kInf;
  const double tol = p.inside_tolerance;
  const Box2 body{p.body_rear_x + tol, p.body_front_x - tol, p.body_half_width - tol};
  const Box2 swept{p.rear_x, p.front_x, p.half_width};
  const Box2 grown{p.rear_x - p.turn_margin, p.front_x + p.turn_margin, p.half_width + p.turn_margin};
  const double reach = grown.max_radius();
  for (const Eigen::Vector2d& pt : points) {
    if (!pt.allFinite()) continue;
    if (body.contains(pt)) {
      g.inside = true;
      continue;
    }
    if (std::abs(pt.y()) <= p.half_width) {
      if (pt.x() >= p.front_x) g.free_ahead = std::min(g.free_ahead, pt.x() - p.front_x);
      if (pt.x() <= p.rear_x) g.free_behind = std::min(g.free_behind, p.rear_x - pt.x());
    }
    // Turning: the point's bearing in the turning footprint's frame moves by
    // -dtheta; the first crossing into the grown footprint bounds the turn.
    const double r = pt.norm();
    if (r > reach) continue;
    const Box2* box = &grown;
    if (grown.contains(pt)) {
      if (swept.contains(pt)) {
        g.free_turn_ccw = g.free_turn_cw = 0.0;
        continue;
      }
      box = &swept;  // already within the margin: the footprint itself bounds the turn
    }
    double cross[8];
    const int n = circle_crossings(*box, r, cross);
    const double phi = std::atan2(pt.y(), pt.x());
    // Within the margin, turning deeper into it is not allowed; turning out
    // is, up to where the footprint itself would meet the point.
    bool ccw_ok = true, cw_ok = true;
    if (box == &swept) {
      const double d0 = grown.depth(pt);
      ccw_ok = grown.depth(rotated(pt, -kProbeTurn)) < d0;
      cw_ok = grown.depth(rotated(pt, kProbeTurn)) < d0;
    }
    if (!ccw_ok) g.free_turn_ccw = 0.0;
    if (!cw_ok) g.free_turn_cw = 0.0;
    for (int i = 0; i < n; ++i) {
      if (ccw_ok) g.free_turn_ccw = std::min(g.free_turn_ccw, positive_turn(phi - cross[i]));
      if (cw_ok) g.free_turn_cw = std::min(g.free_turn_cw, positive_turn(cross[i] - phi));
    }
  }
  g.max_forward = stoppable_speed(g.free_ahead - p.margin, p.max_decel, p.reaction_time);
  g.max_backward = stoppable_speed(g.free_behind - p.margin, p.max_decel, p.reaction_time);
  g.known_ahead = g.known_behind = kInf;
  if (known != nullptr) {
    g.known_ahead = known_corridor_length(*known, p.front_x, p.half_width, 1.0);
    g.known_behind = known_corridor_length(*known, -p.rear_x, p.half_width, -1.0);
    const double seen_fwd = stoppable_speed(g.known_ahead - p.margin, p.max_decel, p.reaction_time);
    const double seen_bwd = stoppable_speed(g.known_behind - p.margin, p.max_decel, p.reaction_time);
    g.max_forward = std::min(g.max_forward, std::max(seen_fwd, p.unknown_speed));
    g.max_backward = std::min(g.max_backward, std::max(seen_bwd, p.unknown_speed));
  }
  g.max_yaw_ccw = stoppable_speed(g.free_turn_ccw, p.max_yaw_decel, p.reaction_time);
  g.max_yaw_cw = stoppable_speed(g.free_turn_cw, p.max_yaw_decel, p.reaction_time);
  if (g.inside) g.max_forward = g.max_backward = g.max_yaw_ccw = g.max_yaw_cw = 0.0;
  return g;
}

void known_beam_ranges(std::span<const float> ranges, std::span<const uint8_t> valid, int max_run, bool ring,
                       std::span<float> out) {
  const auto n = static_cast<std::ptrdiff_t>(std::min({ranges.size(), valid.size(), out.size()}));
  // Beam j as an index into the scan (wrapping on a ring), or -1 past an end.
  auto at = [&](std::ptrdiff_t j) -> std::ptrdiff_t {
    if (ring) return ((j % n) + n) % n;
    return j >= 0 && j < n ? j : -1;
  };
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    out[k] = valid[k] ? ranges[k] : -1.0f;
    if (valid[k]) continue;
    // Grow the run of invalid beams round i to its valid neighbours.
    std::ptrdiff_t lo = i, hi = i, left = -1, right = -1;
    while (hi - lo < max_run) {
      left = at(lo - 1);
      if (left < 0 || valid[static_cast<std::size_t>(left)]) break;
      --lo;
    }
    while (hi - lo < max_run) {
      right = at(hi + 1);
      if (right < 0 || valid[static_cast<std::size_t>(right)]) break;
      ++hi;
    }
    if (hi - lo + 1 > max_run || left < 0 || right < 0 || !valid[static_cast<std::size_t>(left)] ||
        !valid[static_cast<std::size_t>(right)])
      continue;
    out[k] = std::min(ranges[static_cast<std::size_t>(left)], ranges[static_cast<std::size_t>(right)]);
  }
}

void add_known_free(std::span<const Eigen::Vector2d> ends, std::span<const uint8_t> known, double cone_half_angle,
                    bool ring, KnownFree& out) {
  const std::size_t n = std::min(ends.size(), known.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!known[i]) continue;
    const double a = std::atan2(ends[i].y(), ends[i].x()), rho = ends[i].norm();
    if (cone_half_angle > 0.0) mark_arc(a - cone_half_angle, 2.0 * cone_half_angle, rho, out);
    const std::size_t j = i + 1 < n ? i + 1 : (ring ? 0 : n);
    if (j >= n || j == i || !known[j]) continue;
    const double b = std::atan2(ends[j].y(), ends[j].x());
    const double d = math::wrap_angle(b - a);
    if (std::abs(d) >= 0.5 * std::numbers::pi) continue;  // not neighbours as seen from the centre
    mark_arc(d >= 0.0 ? a : b, std::abs(d), std::min(rho, ends[j].norm()), out);
  }
}

}  // namespace hemm::robot
