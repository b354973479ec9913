#include "common/mapping/local_map.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/math/geometry2.h"

namespace hemm::mapping {

using Eigen::Vector2d;

std::string validate(const RangeScan2D& s) {
  if (!math::is_finite(s.T_W_R)) return "scan: T_W_R not finite";
  if (!math::is_finite(s.T_R_S)) return "scan: T_R_S not finite";
  if (s.kind != SensorKind::kLaser && s.kind != SensorKind::kSonar) return "scan: unknown sensor kind";
  if (s.ranges.size() != s.valid.size()) return "scan: ranges and valid differ in length";
  if (s.ranges.size() > 100000) return "scan: more than 100000 beams";
  if (!std::isfinite(s.range_min) || !std::isfinite(s.range_max) || s.range_min < 0.0 ||
      !(s.range_max > s.range_min) || s.range_max > 1000.0)
    return "scan: need 0 <= range_min < range_max <= 1000 m";
  if (s.beam_angles.empty()) {
    if (!std::isfinite(s.angle_min) || !std::isfinite(s.angle_step) || !(s.angle_step > 0.0))
      return "scan: need finite angle_min and angle_step > 0";
    if (std::abs(s.angle_min) > 4.0 * std::numbers::pi ||
        static_cast<double>(s.ranges.size()) * s.angle_step > 2.0 * std::numbers::pi + 1e-6)
      return "scan: beams span more than one turn";
  } else {
    if (s.beam_angles.size() != s.ranges.size()) return "scan: beam_angles and ranges differ in length";
    for (std::size_t i = 0; i < s.beam_angles.size(); ++i) {
      if (!std::isfinite(s.beam_angles[i]) || std::abs(s.beam_angles[i]) > 4.0 * std::numbers::pi)
        return "scan: beam_angles not finite";
      if (i > 0 && !(s.beam_angles[i] > s.beam_angles[i - 1])) return "scan: beam_angles not ascending";
    }
    if (s.beam_angles.back() - s.beam_angles.front() >= 2.0 * std::numbers::pi) return "scan: beams span more than one turn";
  }
  if (s.kind == SensorKind::kSonar) {
    if (!std::isfinite(s.beam_width) || !(s.beam_width > 0.0) || s.beam_width > std::numbers::pi)
      return "scan: sonar needs 0 < beam_width <= pi";
  } else if (!std::isfinite(s.beam_width) || s.beam_width < 0.0) {
    return "scan: beam_width must be finite and >= 0";
  }
  return {};
}

std::string validate(const MapParams& p) {
  const double vals[] = {p.jump_ratio,  p.jump_abs,       p.min_view_angle,  p.max_segment_length,
                         p.min_point_spacing, p.normal_window, p.range_noise, p.sonar_merge_ratio, p.sonar_merge_abs, p.sonar_max_gap,
                         p.sonar_laser_tolerance, p.sonar_laser_max_age_s, p.clear_tolerance, p.window_age_s, p.window_radius, p.cell_size,
                         p.shadow_depth, p.shadow_clip_step, p.temporal_gain, p.temporal_gate};
  for (double v : vals)
    if (!std::isfinite(v) || v < 0.0) return "map params: values must be finite and >= 0";
  // Larger would clear surfaces well behind the one measured.
  if (p.clear_tolerance > 1.0) return "map params: clear_tolerance must be <= 1 m";
  if (p.max_segment_length <= 0.0 || p.cell_size <= 0.0 || p.window_radius <= 0.0)
    return "map params: max_segment_length, cell_size, window_radius must be > 0";
  if (p.max_bridged_dropouts < 0) return "map params: max_bridged_dropouts must be >= 0";
  if (p.sonar_arc_pieces < 1 || p.sonar_arc_pieces > 64) return "map params: sonar_arc_pieces in [1, 64]";
  if (p.max_segments == 0 || p.max_cells == 0) return "map params: max_segments and max_cells must be > 0";
  if (p.shadow_depth > 5.0) return "map params: shadow_depth must be <= 5 m";
  if (!(p.temporal_gain > 0.0) || p.temporal_gain > 1.0) return "map params: temporal_gain in (0, 1]";
  if (p.shadow_depth > 0.0 && p.shadow_clip_step < 0.005) return "map params: shadow_clip_step must be >= 5 mm";
  return {};
}

namespace {

// Segment with its normal turned toward the viewpoint (the sensor).
Segment2 make_segment(const Vector2d& a, const Vector2d& b, const Vector2d& view_W, std::int64_t stamp,
                      SensorKind kind, bool interpolated) {
  Segment2 s;
  s.a = a;
  s.b = b;
  Vector2d n = math::perp(b - a);
  const double len = n.norm();
  n = len > 0.0 ? Vector2d(n / len) : Vector2d((view_W - a).normalized());
  const Vector2d mid = 0.5 * (a + b);
  if (n.dot(view_W - mid) < 0.0) n = -n;
  s.normal = n;
  s.stamp_ns = stamp;
  s.kind = kind;
  s.interpolated = interpolated;
  return s;
}

// Emits the segments of one polyline. Each segment's normal is the normal of
// the least-squares line (PCA) through the polyline's points within
// normal_window / 2 of the segment's midpoint: a single noisy pair of points
// gives a poor normal when the points are dense.
void emit_polyline(const MapParams& p, const std::vector<Vector2d>& run, const Vector2d& o_W, std::int64_t stamp,
                   std::vector<Segment2>& out) {
  const std::size_t m = run.size();
  if (m < 2) return;
  const double half = 0.5 * p.normal_window;
  for (std::size_t k = 0; k + 1 < m; ++k) {
    Segment2 seg = make_segment(run[k], run[k + 1], o_W, stamp, SensorKind::kLaser, false);
    const Vector2d mid = 0.5 * (run[k] + run[k + 1]);
    std::size_t j0 = k, j1 = k + 1;
    while (j0 > 0 && (run[j0 - 1] - mid).norm() <= half) --j0;
    while (j1 + 1 < m && (run[j1 + 1] - mid).norm() <= half) ++j1;
    if (j1 - j0 >= 2) {
      Vector2d mean = Vector2d::Zero();
      for (std::size_t j = j0; j <= j1; ++j) mean += run[j];
      mean /= static_cast<double>(j1 - j0 + 1);
      double sxx = 0, sxy = 0, syy = 0;
      for (std::size_t j = j0; j <= j1; ++j) {
        const Vector2d q = run[j] - mean;
        sxx += q.x() * q.x();
        sxy += q.x() * q.y();
        syy += q.y() * q.y();
      }
      const double phi = 0.5 * std::atan2(2.0 * sxy, sxx - syy);  // principal direction
      Vector2d n(-std::sin(phi), std::cos(phi));
      if (n.dot(o_W - mid) < 0.0) n = -n;
      seg.normal = n;
    }
    out.push_back(seg);
  }
}

// The shadow edge at one end of a polyline: beam `edge` is the polyline's
// last return on that side, `dir` (+1 / -1) the way out of the polyline. The
// first informative beam beyond (dropouts skipped, a few at most) decides: it
// passed the face (farther, or nothing up to range_max) -> an edge along beam
// `edge`, normal toward the passing beam; nearer or alike -> none (a nearer
// object's own shadow covers it; a surface alike continues the face).
void emit_shadow_edge(const MapParams& p, const RangeScan2D& scan, const math::Pose2& T_W_S, std::size_t edge,
                      int dir, std::vector<Segment2>& out) {
  if (!(p.shadow_depth > 0.0)) return;
  const double r = scan.ranges[edge];
  const auto n = static_cast<std::ptrdiff_t>(scan.ranges.size());
  for (std::ptrdiff_t j = static_cast<std::ptrdiff_t>(edge) + dir, hops = 0;
       j >= 0 && j < n && hops <= p.max_bridged_dropouts + 2; j += dir, ++hops) {
    const double lj = beam_limit(scan, static_cast<std::size_t>(j));
    if (lj < 0.0) continue;  // dropout: no information, look one further
    double len = 0.0;
    if (!beam_is_return(scan, static_cast<std::size_t>(j))) {
      len = p.shadow_depth;  // nothing up to range_max beside the face
    } else if (lj > r + (hops == 0 ? p.range_noise : p.jump_ratio * r + p.jump_abs)) {
      // Ends at the surface behind. Next to the face that may be the same
      // object seen edge-on (the windowing broke the polyline there): a
      // short edge, continued by the next run's own. Across dropouts only a
      // real range jump counts (a wall seen through dropouts continues).
      len = std::min(p.shadow_depth, lj - r);
    } else {
      return;
    }
    const double a = beam_angle(scan, edge);
    const Vector2d u = math::rotate(T_W_S, Vector2d(std::cos(a), std::sin(a)));
    Segment2 e;
    e.a = math::apply(T_W_S, Vector2d(r * std::cos(a), r * std::sin(a)));
    e.b = e.a + len * u;
    e.normal = (beam_angle(scan, static_cast<std::size_t>(j)) > a ? 1.0 : -1.0) * math::perp(u);
    e.stamp_ns = scan.stamp_ns;
    e.kind = SensorKind::kLaser;
    e.interpolated = true;
    e.shadow = true;
    out.push_back(e);
    return;
  }
}

void extract_laser(const MapParams& p, const RangeScan2D& scan, const math::Pose2& T_W_S,
                   std::vector<Segment2>& out) {
  const Vector2d o_W = math::translation(T_W_S);
  const double sin_min_view = std::sin(p.min_view_angle);
  bool have_prev = false;
  int dropped = 0;  // invalid beams since the last kept return
  double prev_r = 0.0;
  Vector2d prev_W = Vector2d::Zero();
  std::vector<Vector2d> run;  // the current polyline
  std::size_t run_first = 0, run_last = 0;  // its first and last beam (down-sampled ones included)
  auto finish_run = [&] {
    emit_polyline(p, run, o_W, scan.stamp_ns, out);
    // Also for a lone return (a thin leg, or the grazing end of a round
    // object that the windowing cut off): no face, but its shadow is unseen.
    if (!run.empty()) {
      emit_shadow_edge(p, scan, T_W_S, run_first, -1, out);
      emit_shadow_edge(p, scan, T_W_S, run_last, +1, out);
    }
  };
  for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!beam_is_return(scan, i)) {
      ++dropped;
      continue;
    }
    const double r = scan.ranges[i];
    const double a = beam_angle(scan, i);
    const Vector2d p_W = math::apply(T_W_S, Vector2d(r * std::cos(a), r * std::sin(a)));
    bool join = false;
    if (have_prev) {
      const Vector2d d = p_W - prev_W;
      const double len = d.norm();
      join = dropped <= p.max_bridged_dropouts;
      join = join && std::abs(r - prev_r) <= p.jump_ratio * std::min(r, prev_r) + p.jump_abs;
      join = join && len <= p.max_segment_length && len > 0.0;
      // The edge-on test only for range steps above the noise: between dense
      // noisy points every segment can look edge-on.
      if (join && std::abs(r - prev_r) > p.range_noise) {
        const Vector2d ray = 0.5 * (p_W + prev_W) - o_W;
        const double rn = ray.norm();
        // |sin| of the angle between segment and beam: small means edge-on.
        join = rn > 0.0 && std::abs(math::cross2(d, ray)) / (len * rn) >= sin_min_view;
      }
      if (join && len < p.min_point_spacing) {  // down-sample: keep prev, skip this one
        run_last = i;
        continue;
      }
    }
    if (!join) {  // windowing: the surface breaks here
      finish_run();
      run.clear();
      run_first = i;
    }
    run.push_back(p_W);
    run_last = i;
    have_prev = true;
    dropped = 0;
    prev_r = r;
    prev_W = p_W;
  }
  finish_run();
}

// Does a laser return lie inside cone (apex o_W, unit axis u_W, half angle)
// no farther than reach?
// Only returns within max_age_ns of the sonar scan count.
bool laser_explains(const LaserCoverage& laser, std::int64_t stamp_ns, double max_age_ns, const Vector2d& o_W,
                    const Vector2d& u_W, double half, double reach) {
  const double cos_half = std::cos(half);
  for (const LaserReturn& q : laser.returns) {
    if (std::abs(static_cast<double>(q.stamp_ns) - static_cast<double>(stamp_ns)) > max_age_ns) continue;
    const Vector2d d = q.p_W - o_W;
    const double dist = d.norm();
    if (dist > reach || dist <= 0.0) continue;
    if (d.dot(u_W) >= cos_half * dist) return true;
  }
  return false;
}

void extract_sonar(const MapParams& p, const RangeScan2D& scan, const math::Pose2& T_W_S,
                   const LaserCoverage* laser, std::vector<Segment2>& out) {
  const Vector2d o_W = math::translation(T_W_S);
  const double half = 0.5 * scan.beam_width;
  const int pieces = p.sonar_arc_pieces;
  auto at = [&](double r, double ang) { return math::apply(T_W_S, Vector2d(r * std::cos(ang), r * std::sin(ang))); };
  const std::size_t n = scan.ranges.size();
  const bool use_laser = laser != nullptr && !laser->returns.empty() && p.sonar_laser_max_age_s > 0.0;
  // drawn[i]: cone i is a return the laser does not explain.
  std::vector<std::uint8_t> drawn(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!beam_is_return(scan, i)) continue;
    if (use_laser) {
      const double a = beam_angle(scan, i) + T_W_S.theta;
      if (laser_explains(*laser, scan.stamp_ns, p.sonar_laser_max_age_s * 1e9, o_W, Vector2d(std::cos(a), std::sin(a)),
                         half, scan.ranges[i] + p.sonar_laser_tolerance))
        continue;
    }
    drawn[i] = 1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!drawn[i]) continue;
    const double r = scan.ranges[i];
    const double a = beam_angle(scan, i);
    Vector2d prev = at(r, a - half);
    for (int k = 1; k <= pieces; ++k) {
      const Vector2d q = at(r, a - half + scan.beam_width * k / pieces);
      out.push_back(make_segment(prev, q, o_W, scan.stamp_ns, SensorKind::kSonar, true));
      prev = q;
    }
  }
  // Bridges between neighbouring cones (by angle, wrapping for a full ring)
  // whose ranges agree: the surface most likely continues between them.
  for (std::size_t i = 0; i < n && n > 1; ++i) {
    const std::size_t j = (i + 1) % n;
    if (j == 0 && n < 3) break;
    if (!drawn[i] || !drawn[j]) continue;
    const double ri = scan.ranges[i], rj = scan.ranges[j];
    if (std::abs(ri - rj) > p.sonar_merge_ratio * std::min(ri, rj) + p.sonar_merge_abs) continue;
    const double ai = beam_angle(scan, i), aj = beam_angle(scan, j);
    const double gap = math::wrap_angle(aj - ai) - scan.beam_width;  // between cone edges
    if (math::wrap_angle(aj - ai) <= 0.0 || gap > p.sonar_max_gap || gap <= 0.0) continue;
    const Vector2d from = at(ri, ai + half), to = at(rj, aj - half);
    if ((to - from).norm() > p.max_segment_length) continue;
    out.push_back(make_segment(from, to, o_W, scan.stamp_ns, SensorKind::kSonar, true));
  }
}

// ---- Ray clearing -------------------------------------------------------

// The beam nearest bearing beta (rad, in S) among the scan's own beams, each
// standing for the angular cell halfway to its neighbours (so the chunks of a
// dense scan partition its field of view). off = beta - angle of beam k.
// False when beta lies outside every cell.
bool nearest_beam(const RangeScan2D& s, double beta, std::size_t& k, double& off) {
  const std::size_t n = s.ranges.size();
  if (n == 0) return false;
  const double a0 = beam_angle(s, 0);
  const bool regular = s.beam_angles.empty();
  const double h0 = regular ? 0.5 * s.angle_step : (n > 1 ? 0.5 * (beam_angle(s, 1) - a0) : 0.0);
  double rel = math::wrap_angle(beta - a0);  // (-pi, pi]
  if (rel < -h0) rel += 2.0 * std::numbers::pi;      // [-h0, 2 pi - h0)
  if (regular) {
    const double x = std::floor(rel / s.angle_step + 0.5);
    if (x < 0.0 || x > static_cast<double>(n - 1)) return false;
    k = static_cast<std::size_t>(x);
    off = rel - x * s.angle_step;
    return true;
  }
  // Irregular (ascending) beam angles: binary search for the first beam past rel.
  std::size_t lo = 0, hi = n;
  while (lo < hi) {
    const std::size_t mid = (lo + hi) / 2;
    if (beam_angle(s, mid) - a0 <= rel) lo = mid + 1; else hi = mid;
  }
  if (lo == 0) {
    k = 0;
  } else if (lo == n) {
    k = n - 1;
    const double h_last = n > 1 ? 0.5 * (beam_angle(s, n - 1) - beam_angle(s, n - 2)) : 0.0;
    if (rel - (beam_angle(s, n - 1) - a0) >= h_last && !(n == 1 && rel == 0.0)) return false;
  } else {
    const double before = rel - (beam_angle(s, lo - 1) - a0), after = (beam_angle(s, lo) - a0) - rel;
    k = before < after ? lo - 1 : lo;
  }
  off = rel - (beam_angle(s, k) - a0);
  return true;
}

// Has this laser scan seen through point q (range r_q, bearing beta in S)?
bool laser_sees_through(const MapParams& p, const RangeScan2D& s, double r_q, double beta) {
  std::size_t k = 0;
  double off = 0.0;
  if (r_q < s.range_min || !nearest_beam(s, beta, k, off)) return false;
  const double lk = beam_limit(s, k);
  if (lk < 0.0) return false;
  const std::size_t n = s.ranges.size();
  const double tol = p.clear_tolerance;
  auto agree = [&](double x, double y) { return std::abs(x - y) <= p.jump_ratio * std::min(x, y) + p.jump_abs; };
  const int side = off >= 0.0 ? 1 : -1;  // the neighbour across the gap q lies in
  const auto j = static_cast<std::ptrdiff_t>(k) + side, o = static_cast<std::ptrdiff_t>(k) - side;
  double limit = lk;
  if (j >= 0 && j < static_cast<std::ptrdiff_t>(n)) {
    // An invalid neighbour says nothing about the gap: beam k alone decides.
    // (Not "in doubt": the wire cannot tell a dropout from "nothing within
    // range", so every surface end next to open space would keep a copy per
    // scan; a real dropout beside an object's edge costs at most that one
    // scan's sliver of edge, redrawn by the next.)
    const double lj = beam_limit(s, static_cast<std::size_t>(j));
    if (lj < 0.0) {
      // limit stays lk
    } else if (agree(lk, lj)) {
      // One surface across the gap: its range at beta, linearly in angle.
      limit = lk + (lj - lk) * off / (beam_angle(s, static_cast<std::size_t>(j)) - beam_angle(s, k));
    } else if (lj < lk) {
      // Beam k slipped past the edge of a nearer object whose surface may
      // reach into the gap: only what lies in front of that object is seen.
      return r_q <= lj - tol;
    }
    // else: k is on the near surface and its neighbour sees past its edge.
  } else if (o >= 0 && o < static_cast<std::ptrdiff_t>(n)) {
    // q beyond the scan's (or chunk's) last beam: extrapolate the surface's slope.
    const double lo = beam_limit(s, static_cast<std::size_t>(o));
    if (lo >= 0.0 && agree(lk, lo))
      limit = lk + (lk - lo) * off / (beam_angle(s, k) - beam_angle(s, static_cast<std::size_t>(o)));
  }
  return r_q <= limit + tol;
}

// Has this sonar scan seen through point q? An echo at r: nothing nearer in
// the cone. Arcs are inferred across the whole cone, so the cone is widened by
// half an arc piece; between neighbouring cones close enough to bridge, the
// two echoes bound the free space (interpolated when they agree, else the
// nearer).
bool sonar_sees_through(const MapParams& p, const RangeScan2D& s, double r_q, double beta) {
  if (r_q < s.range_min) return false;
  const std::size_t n = s.ranges.size();
  const double half = 0.5 * s.beam_width, slack = 0.5 * s.beam_width / p.sonar_arc_pieces;
  const double tol = p.clear_tolerance;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::abs(math::wrap_angle(beta - beam_angle(s, i))) > half + slack) continue;
    const double li = beam_limit(s, i);
    if (li >= 0.0 && r_q <= li + tol) return true;
  }
  for (std::size_t i = 0; i < n && n > 1; ++i) {
    const std::size_t j = (i + 1) % n;
    if (j == 0 && n < 3) break;
    const double span = math::wrap_angle(beam_angle(s, j) - beam_angle(s, i));
    const double gap = span - s.beam_width;
    if (span <= 0.0 || gap <= 0.0 || gap > p.sonar_max_gap) continue;
    double d = math::wrap_angle(beta - beam_angle(s, i));
    if (d < 0.0) d += 2.0 * std::numbers::pi;
    if (d <= half || d >= span - half) continue;
    const double li = beam_limit(s, i), lj = beam_limit(s, j);
    if (li < 0.0 || lj < 0.0) continue;
    // Echoes that agree are bridged by extract_sonar: the bridge (a line,
    // whose range is convex in the bearing) lies within the linear
    // interpolation of the two; otherwise only the nearer echo bounds the gap.
    const bool agree = std::abs(li - lj) <= p.sonar_merge_ratio * std::min(li, lj) + p.sonar_merge_abs;
    const double f = (d - half) / (span - s.beam_width);
    const double limit = agree ? li + f * (lj - li) : std::min(li, lj);
    if (r_q <= limit + tol) return true;
  }
  return false;
}

}  // namespace

bool scan_sees_through(const MapParams& p, const RangeScan2D& scan, const Eigen::Vector2d& q_W) {
  if (scan.kind != SensorKind::kLaser || !validate(scan).empty() || !q_W.allFinite()) return false;
  const math::Pose2 T_W_S = math::compose(scan.T_W_R, scan.T_R_S);
  const Vector2d q_S = math::apply(math::inverse(T_W_S), q_W);
  return laser_sees_through(p, scan, q_S.norm(), std::atan2(q_S.y(), q_S.x()));
}

std::size_t clear_reobserved_segments(const MapParams& p, LocalMap& map, const RangeScan2D& scan) {
  if (!validate(p).empty() || !validate(scan).empty()) return 0;
  const math::Pose2 T_S_W = math::inverse(math::compose(scan.T_W_R, scan.T_R_S));
  const bool sonar = scan.kind == SensorKind::kSonar;
  // behind: the extra range a point needs in front of the measured surface
  // to count (0: re-observed at the surface is enough).
  auto seen = [&](const Vector2d& q_W, double behind = 0.0) {
    const Vector2d d = math::apply(T_S_W, q_W);
    const double r = d.norm() + behind, beta = std::atan2(d.y(), d.x());
    return sonar ? sonar_sees_through(p, scan, r, beta) : laser_sees_through(p, scan, r, beta);
  };
  for (Segment2& seg : map.segments) {
    // Only older segments: a late (reordered) scan never clears newer data,
    // and a chunk never clears its own scan's other chunks.
    if (seg.kind != scan.kind || seg.stamp_ns >= scan.stamp_ns) continue;
    if (seg.shadow) {
      // A shadow edge bounds unseen space: cut it where the scan saw free
      // space along it; gone when its base (the silhouette) is seen through.
      const double len = (seg.b - seg.a).norm();
      const int steps = std::max(1, static_cast<int>(std::ceil(len / p.shadow_clip_step)));
      for (int k = 0; k <= steps; ++k) {
        const Vector2d q = seg.a + (seg.b - seg.a) * (static_cast<double>(k) / steps);
        if (!seen(q)) continue;
        if (k == 0) {
          seg.reobserved = 7u;
        } else {
          seg.b = seg.a + (seg.b - seg.a) * (static_cast<double>(k - 1) / steps);
          if ((seg.b - seg.a).norm() < 1e-3) seg.reobserved = 7u;
        }
        break;
      }
      continue;
    }
    // A laser face turned away from this sensor cannot be re-observed from
    // here (it sees the other side: the far face of a thin board, the back
    // of a column passed): it goes only where the scan saw clearly past it.
    const Vector2d mid_S = math::apply(T_S_W, Vector2d(0.5 * (seg.a + seg.b)));
    const bool away = !sonar && math::rotate(T_S_W, seg.normal).dot(-mid_S) <= 0.0;
    const double behind = away ? 2.0 * p.clear_tolerance : 0.0;
    if (!(seg.reobserved & 1u) && seen(seg.a, behind)) seg.reobserved |= 1u;
    if (!(seg.reobserved & 2u) && seen(0.5 * (seg.a + seg.b), behind)) seg.reobserved |= 2u;
    if (!(seg.reobserved & 4u) && seen(seg.b, behind)) seg.reobserved |= 4u;
  }
  const std::size_t before = map.segments.size();
  map.segments.erase(std::remove_if(map.segments.begin(), map.segments.end(),
                                    [](const Segment2& s) { return s.reobserved == 7u; }),
                     map.segments.end());
  return before - map.segments.size();
}

void update_laser_coverage(LaserCoverage& c, const RangeScan2D& s, double max_age_s) {
  if (s.kind != SensorKind::kLaser || !validate(s).empty()) return;
  const double oldest = static_cast<double>(s.stamp_ns) - max_age_s * 1e9;
  c.returns.erase(std::remove_if(c.returns.begin(), c.returns.end(),
                                 [&](const LaserReturn& q) { return static_cast<double>(q.stamp_ns) < oldest; }),
                  c.returns.end());
  const math::Pose2 T_W_S = math::compose(s.T_W_R, s.T_R_S);
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    if (!beam_is_return(s, i)) continue;
    const double a = beam_angle(s, i), r = s.ranges[i];
    c.returns.push_back({math::apply(T_W_S, Vector2d(r * std::cos(a), r * std::sin(a))), s.stamp_ns});
  }
}

std::string extract_segments(const MapParams& p, const RangeScan2D& scan, std::vector<Segment2>& out,
                             const LaserCoverage* laser) {
  if (std::string e = validate(p); !e.empty()) return e;
  if (std::string e = validate(scan); !e.empty()) return e;
  const math::Pose2 T_W_S = math::compose(scan.T_W_R, scan.T_R_S);
  std::vector<Segment2> found;
  if (scan.kind == SensorKind::kSonar) {
    extract_sonar(p, scan, T_W_S, laser, found);
  } else {
    extract_laser(p, scan, T_W_S, found);
  }
  out.insert(out.end(), found.begin(), found.end());
  return {};
}

std::size_t filter_scan_against_map(const MapParams& p, const LocalMap& map, RangeScan2D& scan) {
  if (scan.kind != SensorKind::kLaser || !(p.temporal_gain < 1.0) || !scan.beam_angles.empty()) return 0;
  if (!validate(p).empty() || !validate(scan).empty() || scan.ranges.empty()) return 0;
  const math::Pose2 T_S_W = math::inverse(math::compose(scan.T_W_R, scan.T_R_S));
  const std::size_t n = scan.ranges.size();
  // Nearest current laser surface along each beam: each old face segment
  // (measured, older than the scan) is cast only against the beams between
  // its endpoints' bearings, so the cost is segments + beams.
  std::vector<double> old(n, std::numeric_limits<double>::infinity());
  for (const Segment2& seg : map.segments) {
    if (seg.kind != SensorKind::kLaser || seg.interpolated || seg.shadow || seg.stamp_ns >= scan.stamp_ns) continue;
    const Vector2d a = math::apply(T_S_W, seg.a), b = math::apply(T_S_W, seg.b);
    // Only a face this sensor looks at: the far face of a thin board seen
    // earlier from the other side is another surface, not this one's past.
    if (math::rotate(T_S_W, seg.normal).dot(-0.5 * (a + b)) <= 0.0) continue;
    double ta = std::atan2(a.y(), a.x()), tb = std::atan2(b.y(), b.x());
    if (ta > tb) std::swap(ta, tb);
    if (tb - ta > 0.5 * std::numbers::pi) continue;  // behind the sensor or spanning its back
    const double k0 = std::ceil((ta - scan.angle_min) / scan.angle_step);
    const double k1 = std::floor((tb - scan.angle_min) / scan.angle_step);
    if (k1 < 0.0 || k0 > static_cast<double>(n - 1)) continue;
    const Vector2d ab = b - a;
    for (auto k = static_cast<std::size_t>(std::max(0.0, k0)); k <= static_cast<std::size_t>(std::min(k1, static_cast<double>(n - 1))); ++k) {
      const double th = beam_angle(scan, k);
      const Vector2d u(std::cos(th), std::sin(th));
      // o + r u = a + s ab  ->  r = cross(a, ab) / cross(u, ab)
      const double den = math::cross2(u, ab);
      if (std::abs(den) < 1e-12) continue;
      const double r = math::cross2(a, ab) / den;
      if (r > 0.0 && r < old[k]) old[k] = r;
    }
  }
  std::size_t filtered = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (!beam_is_return(scan, k) || !std::isfinite(old[k])) continue;
    const double r = scan.ranges[k];
    if (std::abs(r - old[k]) > p.temporal_gate) continue;  // a real move (or another surface): as measured
    scan.ranges[k] = static_cast<float>(old[k] + p.temporal_gain * (r - old[k]));
    ++filtered;
  }
  return filtered;
}

std::string add_scan(const MapParams& p, LocalMap& map, const RangeScan2D& scan_in) {
  if (std::string e = validate(p); !e.empty()) return e;
  if (std::string e = validate(scan_in); !e.empty()) return e;
  const RangeScan2D* use = &scan_in;
  RangeScan2D filtered;
  if (scan_in.kind == SensorKind::kLaser && p.temporal_gain < 1.0) {
    filtered = scan_in;
    filter_scan_against_map(p, map, filtered);
    use = &filtered;
  }
  const RangeScan2D& scan = *use;
  if (p.clear_reobserved) clear_reobserved_segments(p, map, scan);
  std::string e = extract_segments(p, scan, map.segments, &map.laser);
  if (!e.empty()) return e;
  map.newest_stamp_ns = std::max(map.newest_stamp_ns, scan.stamp_ns);
  if (scan.kind == SensorKind::kLaser) {
    update_laser_coverage(map.laser, scan, p.sonar_laser_max_age_s);
    if (map.recent_laser.size() == LocalMap::kRecentLaserScans) map.recent_laser.erase(map.recent_laser.begin());
    map.recent_laser.push_back(scan);
  }
  return e;
}

void slide_window(const MapParams& p, LocalMap& map, std::int64_t now_ns, const Eigen::Vector2d& centre_W) {
  const double age_ns = p.window_age_s * 1e9;
  auto drop = [&](const Segment2& s) {
    const double age = static_cast<double>(now_ns) - static_cast<double>(s.stamp_ns);
    return age > age_ns || math::distance_to_segment(s.a, s.b, centre_W) > p.window_radius;
  };
  map.segments.erase(std::remove_if(map.segments.begin(), map.segments.end(), drop), map.segments.end());
  if (map.segments.size() > p.max_segments) {
    // Stable order means the front holds the oldest.
    map.segments.erase(map.segments.begin(),
                       map.segments.begin() + static_cast<std::ptrdiff_t>(map.segments.size() - p.max_segments));
  }
}

namespace {
// Where an object's far side was seen too (a thin board from both sides, a
// column from two viewpoints), the solid behind a face ends at it: a proxy
// resting on the far side must not count as inside the near face. The far
// side is any piece behind this piece's line, over it, and facing away from
// it (normals more than 90 deg apart).
constexpr double kDepthSearch = 0.25;  // m: deeper than the proxy's own push-out depth (one_sided_depth)

void set_depth_limits(const MapParams&, MapSnapshot& s) {
  std::vector<std::uint32_t> near(256);
  for (Segment2& seg : s.segments) {
    const Vector2d mid = 0.5 * (seg.a + seg.b);
    const double half = 0.5 * (seg.b - seg.a).norm();
    std::size_t n = query_segments(s, mid, half + kDepthSearch, near.data(), near.size());
    while (n > near.size()) {
      near.resize(2 * near.size());
      n = query_segments(s, mid, half + kDepthSearch, near.data(), near.size());
    }
    double limit = std::numeric_limits<double>::infinity();
    const Vector2d ab = seg.b - seg.a;
    const double L2 = ab.squaredNorm();
    for (std::size_t k = 0; k < n; ++k) {
      const Segment2& o = s.segments[near[k]];
      if (&o == &seg || o.normal.dot(seg.normal) >= 0.0) continue;
      for (const Vector2d& q : {o.a, Vector2d(0.5 * (o.a + o.b)), o.b}) {
        const double h = -seg.normal.dot(q - seg.a);  // depth behind seg's line
        const double t = L2 > 0.0 ? ab.dot(q - seg.a) / L2 : 0.0;
        if (h > 1e-4 && t >= 0.0 && t <= 1.0) limit = std::min(limit, h);
      }
    }
    seg.depth_limit = static_cast<float>(limit);
  }
}
}  // namespace

MapSnapshot build_snapshot(const MapParams& p, const LocalMap& map) {
  return build_snapshot(p, map.segments, map.newest_stamp_ns);
}

MapSnapshot build_snapshot(const MapParams& p, const std::vector<Segment2>& segments, std::int64_t stamp_ns) {
  MapSnapshot s;
  s.stamp_ns = stamp_ns == std::numeric_limits<std::int64_t>::min() ? 0 : stamp_ns;
  // Split long segments so that each piece lies within half a cell of its
  // midpoint: then bucketing by midpoint never misses one at query time.
  s.segments.reserve(segments.size());
  for (const Segment2& seg : segments) {
    const double len = (seg.b - seg.a).norm();
    const int pieces = std::max(1, static_cast<int>(std::ceil(len / p.cell_size)));
    for (int k = 0; k < pieces; ++k) {
      Segment2 piece = seg;
      piece.a = seg.a + (seg.b - seg.a) * (static_cast<double>(k) / pieces);
      piece.b = seg.a + (seg.b - seg.a) * (static_cast<double>(k + 1) / pieces);
      s.max_half_length = std::max(s.max_half_length, 0.5 * (piece.b - piece.a).norm());
      s.segments.push_back(piece);
    }
  }
  if (s.segments.empty()) {
    s.nx = s.ny = 0;
    s.cell_start.assign(1, 0);
    return s;
  }
  Vector2d lo = 0.5 * (s.segments[0].a + s.segments[0].b), hi = lo;
  for (const Segment2& seg : s.segments) {
    const Vector2d m = 0.5 * (seg.a + seg.b);
    lo = lo.cwiseMin(m);
    hi = hi.cwiseMax(m);
  }
  s.cell = p.cell_size;
  // Coarsen the grid if the area is too large for max_cells.
  for (;;) {
    const double fx = std::floor((hi.x() - lo.x()) / s.cell) + 1.0;
    const double fy = std::floor((hi.y() - lo.y()) / s.cell) + 1.0;
    if (fx * fy <= static_cast<double>(p.max_cells)) {
      s.nx = static_cast<int>(fx);
      s.ny = static_cast<int>(fy);
      break;
    }
    s.cell *= 2.0;
  }
  s.origin = lo;
  const std::size_t ncell = static_cast<std::size_t>(s.nx) * static_cast<std::size_t>(s.ny);
  auto cell_of = [&](const Segment2& seg) {
    const Vector2d m = 0.5 * (seg.a + seg.b);
    const int ix = std::clamp(static_cast<int>((m.x() - s.origin.x()) / s.cell), 0, s.nx - 1);
    const int iy = std::clamp(static_cast<int>((m.y() - s.origin.y()) / s.cell), 0, s.ny - 1);
    return static_cast<std::size_t>(iy) * static_cast<std::size_t>(s.nx) + static_cast<std::size_t>(ix);
  };
  s.cell_start.assign(ncell + 1, 0);
  for (const Segment2& seg : s.segments) ++s.cell_start[cell_of(seg) + 1];
  for (std::size_t c = 0; c < ncell; ++c) s.cell_start[c + 1] += s.cell_start[c];
  s.items.resize(s.segments.size());
  std::vector<std::uint32_t> fill(s.cell_start.begin(), s.cell_start.end() - 1);
  for (std::size_t i = 0; i < s.segments.size(); ++i) s.items[fill[cell_of(s.segments[i])]++] = static_cast<std::uint32_t>(i);
  set_depth_limits(p, s);
  return s;
}

std::size_t query_segments(const MapSnapshot& s, const Eigen::Vector2d& p, double r, std::uint32_t* out,
                           std::size_t cap) {
  if (s.nx <= 0 || s.ny <= 0 || !p.allFinite() || !std::isfinite(r) || r < 0.0) return 0;
  const double R = r + s.max_half_length;
  const double gx0 = (p.x() - R - s.origin.x()) / s.cell, gx1 = (p.x() + R - s.origin.x()) / s.cell;
  const double gy0 = (p.y() - R - s.origin.y()) / s.cell, gy1 = (p.y() + R - s.origin.y()) / s.cell;
  // Every midpoint lies inside the grid, so a disc off the grid finds nothing.
  if (gx1 < 0.0 || gy1 < 0.0 || gx0 >= s.nx || gy0 >= s.ny) return 0;
  const int ix0 = static_cast<int>(std::clamp(std::floor(gx0), 0.0, static_cast<double>(s.nx - 1)));
  const int ix1 = static_cast<int>(std::clamp(std::floor(gx1), 0.0, static_cast<double>(s.nx - 1)));
  const int iy0 = static_cast<int>(std::clamp(std::floor(gy0), 0.0, static_cast<double>(s.ny - 1)));
  const int iy1 = static_cast<int>(std::clamp(std::floor(gy1), 0.0, static_cast<double>(s.ny - 1)));
  const double r2 = r * r;
  std::size_t count = 0;
  for (int iy = iy0; iy <= iy1; ++iy) {
    for (int ix = ix0; ix <= ix1; ++ix) {
      const std::size_t c = static_cast<std::size_t>(iy) * static_cast<std::size_t>(s.nx) + static_cast<std::size_t>(ix);
      for (std::uint32_t k = s.cell_start[c]; k < s.cell_start[c + 1]; ++k) {
        const std::uint32_t idx = s.items[k];
        const Segment2& seg = s.segments[idx];
        if ((p - math::closest_point_on_segment(seg.a, seg.b, p)).squaredNorm() > r2) continue;
        if (count == cap) return cap + 1;  // truncated: the caller shrinks its query
        out[count++] = idx;
      }
    }
  }
  return count;
}

}  // namespace hemm::mapping
