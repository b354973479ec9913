#include "common/mapping/shape_completion.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_circle.h>
#include <pcl/sample_consensus/sac_model_line.h>

#include "common/mapping/sample_consensus_fit.h"
#include "common/math/geometry2.h"

namespace hemm::mapping {

using Eigen::Vector2d;

std::string validate(const ShapeParams& p) {
  const double v[] = {p.cluster_gap, p.inlier_distance, p.max_rms, p.min_inlier_ratio, p.min_radius,
                      p.max_radius,  p.min_arc,         p.line_preference, p.line_max_gap, p.line_max_angle,
                      p.gap_test_step};
  for (double x : v)
    if (!std::isfinite(x) || x < 0.0) return "shape completion: parameters must be finite and >= 0";
  if (!(p.cluster_gap > 0.0) || !(p.inlier_distance > 0.0) || !(p.gap_test_step > 0.0))
    return "shape completion: cluster_gap, inlier_distance, gap_test_step must be > 0";
  if (p.min_points < 3) return "shape completion: min_points must be >= 3";
  if (p.max_clusters < 1 || p.max_clusters > 100000) return "shape completion: max_clusters in [1, 100000]";
  if (p.max_iterations < 1 || p.max_iterations > 100000) return "shape completion: max_iterations in [1, 100000]";
  if (p.min_inlier_ratio > 1.0 || p.line_preference > 1.0) return "shape completion: ratios must be <= 1";
  if (!(p.max_radius > p.min_radius)) return "shape completion: need min_radius < max_radius";
  if (p.circle_pieces < 8 || p.circle_pieces > 1024) return "shape completion: circle_pieces in [8, 1024]";
  if (p.max_lines_per_cluster < 0 || p.max_lines_per_cluster > 64) return "shape completion: max_lines_per_cluster in [0, 64]";
  if (p.line_max_angle > 0.5) return "shape completion: line_max_angle must be <= 0.5 rad";
  const double r[] = {p.rect_max_angle, p.rect_max_side, p.rect_min_side, p.rect_corner_gap, p.rect_min_end_length};
  for (double x : r)
    if (!std::isfinite(x) || x < 0.0) return "shape completion: rect_ parameters must be finite and >= 0";
  if (p.rect_max_angle > 0.5) return "shape completion: rect_max_angle must be <= 0.5 rad";
  if (!(p.rect_max_side > p.rect_min_side) || p.rect_max_side > 5.0)
    return "shape completion: need rect_min_side < rect_max_side <= 5 m";
  if (p.rect_min_end_points < 3) return "shape completion: rect_min_end_points must be >= 3";
  return {};
}

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

// Normals within ~25 deg: the same face of a wall.
constexpr double kSameFace = 0.9;

bool measured_laser(const Segment2& s) {
  return s.kind == SensorKind::kLaser && !s.interpolated && !s.shadow && !s.fitted;
}

// Union-find over point indices.
struct Disjoint {
  std::vector<std::uint32_t> parent;
  explicit Disjoint(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void join(std::uint32_t a, std::uint32_t b) { parent[find(a)] = find(b); }
};

struct Point {
  Vector2d p;
  std::uint32_t seg;  // index into map.segments
  bool after_a = false;  // the b end of seg, whose a end is the point before (shared with the previous segment)
};

// The measured laser points (segment endpoints; a shared endpoint once),
// clustered: points closer than cluster_gap, and the two ends of a segment,
// are one object. Clusters largest first.
std::vector<std::vector<std::uint32_t>> cluster_points(const ShapeParams& p, const std::vector<Segment2>& segs,
                                                       std::vector<Point>& pts) {
  pts.clear();
  for (std::uint32_t i = 0; i < segs.size(); ++i) {
    const Segment2& s = segs[i];
    if (!measured_laser(s)) continue;
    if (pts.empty() || (pts.back().p - s.a).squaredNorm() > 1e-12) pts.push_back({s.a, i});
    pts.push_back({s.b, i, true});
  }
  const std::size_t n = pts.size();
  Disjoint sets(n);
  // The two ends of a segment (its a end may be the previous segment's b):
  // a polyline is one object however sparse its returns (a face seen at a
  // grazing angle has them farther apart than cluster_gap).
  for (std::size_t k = 1; k < n; ++k)
    if (pts[k].after_a) sets.join(static_cast<std::uint32_t>(k), static_cast<std::uint32_t>(k - 1));
  // Proximity through a sorted grid of cluster_gap cells.
  auto key = [&](int ix, int iy) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(ix)) << 32) | static_cast<std::uint32_t>(iy);
  };
  auto cell = [&](double x) { return static_cast<int>(std::floor(x / p.cluster_gap)); };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> grid(n);
  for (std::uint32_t k = 0; k < n; ++k) grid[k] = {key(cell(pts[k].p.x()), cell(pts[k].p.y())), k};
  std::sort(grid.begin(), grid.end());
  const double gap2 = p.cluster_gap * p.cluster_gap;
  for (std::uint32_t k = 0; k < n; ++k) {
    const int cx = cell(pts[k].p.x()), cy = cell(pts[k].p.y());
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        const std::uint64_t kk = key(cx + dx, cy + dy);
        auto it = std::lower_bound(grid.begin(), grid.end(), std::make_pair(kk, 0u));
        for (; it != grid.end() && it->first == kk; ++it)
          if (it->second > k && (pts[it->second].p - pts[k].p).squaredNorm() <= gap2) sets.join(k, it->second);
      }
  }
  std::vector<std::uint32_t> root_slot(n, UINT32_MAX);
  std::vector<std::vector<std::uint32_t>> clusters;
  for (std::uint32_t k = 0; k < n; ++k) {
    const std::uint32_t r = sets.find(k);
    if (root_slot[r] == UINT32_MAX) {
      root_slot[r] = static_cast<std::uint32_t>(clusters.size());
      clusters.emplace_back();
    }
    clusters[root_slot[r]].push_back(k);
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const auto& a, const auto& b) { return a.size() > b.size(); });
  return clusters;
}

Cloud::Ptr to_cloud(const std::vector<Point>& pts, const std::vector<std::uint32_t>& idx) {
  Cloud::Ptr c(new Cloud);
  c->reserve(idx.size());
  for (std::uint32_t k : idx)
    c->push_back(pcl::PointXYZ(static_cast<float>(pts[k].p.x()), static_cast<float>(pts[k].p.y()), 0.0f));
  return c;
}

struct LineFit {
  Vector2d point, dir;  // unit dir
  std::vector<std::uint32_t> inliers;  // point indices (global)
};

// One line through the given points (global indices): RANSAC + refinement,
// inliers recomputed against the refined line.
bool fit_line(const ShapeParams& p, const std::vector<Point>& pts, const std::vector<std::uint32_t>& idx,
              LineFit& out) {
  if (idx.size() < std::max<std::size_t>(p.min_points, 3)) return false;
  Cloud::Ptr cloud = to_cloud(pts, idx);
  pcl::SampleConsensusModelLine<pcl::PointXYZ>::Ptr model(new pcl::SampleConsensusModelLine<pcl::PointXYZ>(cloud));
  Eigen::VectorXf c;
  if (!ransac_refined<pcl::SampleConsensusModelLine<pcl::PointXYZ>>(model, p.inlier_distance, p.max_iterations, c) ||
      c.size() < 6)
    return false;
  Vector2d d(c[3], c[4]);
  if (!(d.norm() > 1e-9)) return false;
  out.point = Vector2d(c[0], c[1]);
  out.dir = d.normalized();
  out.inliers.clear();
  const Vector2d n = math::perp(out.dir);
  for (std::uint32_t k : idx)
    if (std::abs(n.dot(pts[k].p - out.point)) <= p.inlier_distance) out.inliers.push_back(k);
  return out.inliers.size() >= p.min_points;
}

struct CircleFit {
  Vector2d centre;
  double radius = 0.0, rms = 0.0, arc = 0.0;
  std::size_t inliers = 0;
};

bool fit_circle(const ShapeParams& p, const std::vector<Point>& pts, const std::vector<std::uint32_t>& idx,
                CircleFit& out) {
  // No radius limits inside RANSAC (every sample then yields a model, and
  // PCL reports none found loudly); the radius is judged after the fit.
  Cloud::Ptr cloud = to_cloud(pts, idx);
  pcl::SampleConsensusModelCircle2D<pcl::PointXYZ>::Ptr model(
      new pcl::SampleConsensusModelCircle2D<pcl::PointXYZ>(cloud));
  Eigen::VectorXf c;
  if (!ransac_refined<pcl::SampleConsensusModelCircle2D<pcl::PointXYZ>>(model, p.inlier_distance, p.max_iterations,
                                                                       c) ||
      c.size() < 3)
    return false;
  out.centre = Vector2d(c[0], c[1]);
  out.radius = std::abs(static_cast<double>(c[2]));
  double ss = 0.0;
  std::vector<double> ang;
  for (std::uint32_t k : idx) {
    const Vector2d v = pts[k].p - out.centre;
    const double d = v.norm() - out.radius;
    if (std::abs(d) > p.inlier_distance) continue;
    ss += d * d;
    ang.push_back(std::atan2(v.y(), v.x()));
  }
  out.inliers = ang.size();
  out.rms = out.inliers ? std::sqrt(ss / static_cast<double>(out.inliers)) : 0.0;
  out.arc = arc_spanned(ang);
  return out.inliers > 0;
}

// A circle about `centre` fits the outside of a convex object: the cluster's
// surface normals (toward the sensor) point away from the centre, for at
// least 90 % of its points (not the inside of a curved wall).
bool seen_from_outside(const std::vector<Segment2>& segs, const std::vector<Point>& pts,
                       const std::vector<std::uint32_t>& cluster, const Vector2d& centre) {
  std::size_t outward = 0;
  for (std::uint32_t k : cluster) {
    const Segment2& s = segs[pts[k].seg];
    if (s.normal.dot(0.5 * (s.a + s.b) - centre) > 0.0) ++outward;
  }
  return outward * 10 >= cluster.size() * 9;
}

Segment2 fitted_piece(const Vector2d& a, const Vector2d& b, const Vector2d& normal, std::int64_t stamp) {
  Segment2 s;
  s.a = a;
  s.b = b;
  s.normal = normal;
  s.stamp_ns = stamp;
  s.kind = SensorKind::kLaser;
  s.interpolated = true;
  s.fitted = true;
  return s;
}

// ---- Rectangles ---------------------------------------------------------

// A face of a candidate rectangle: its points (global indices), direction
// and normal toward the free side.
struct Face {
  std::vector<std::uint32_t> pts;
  Vector2d dir = Vector2d::UnitX();
  Vector2d normal = Vector2d::UnitY();
};

// The free part of one recent laser beam (W): from the sensor to its return
// less the ray-clearing tolerance (to range_max for "nothing up to range"),
// so that a beam ending on a surface never counts as passing it.
struct FreeRay {
  Vector2d o, w;  // origin, unit direction
  double len = 0.0;
};

std::vector<FreeRay> free_rays(const MapParams& mp, const LocalMap& map) {
  std::vector<FreeRay> rays;
  for (const RangeScan2D& s : map.recent_laser) {
    if (s.kind != SensorKind::kLaser || !validate(s).empty()) continue;
    const math::Pose2 T_W_S = math::compose(s.T_W_R, s.T_R_S);
    for (std::size_t i = 0; i < s.ranges.size(); ++i) {
      const double limit = beam_limit(s, i);
      if (limit < 0.0) continue;  // a dropout says nothing
      const double len = limit - mp.clear_tolerance;
      if (!(len > 0.0)) continue;
      const double a = T_W_S.theta + beam_angle(s, i);
      rays.push_back({math::translation(T_W_S), Vector2d(std::cos(a), std::sin(a)), len});
    }
  }
  return rays;
}

// How far a solid c + s u + t v (t in [t_lo, t_hi]) may reach along u beyond
// s0 before it meets space a beam saw free: the least s > s0 of the beams'
// free parts inside the band (s0 when one passes through at s0), +inf if none.
double free_extent(const std::vector<FreeRay>& rays, const Vector2d& c, const Vector2d& u, const Vector2d& v,
                   double s0, double t_lo, double t_hi) {
  double bound = INFINITY;
  for (const FreeRay& r : rays) {
    const Vector2d o = r.o - c;
    const double so = u.dot(o), to = v.dot(o), ds = u.dot(r.w), dt = v.dot(r.w);
    double lo = 0.0, hi = r.len;
    if (std::abs(dt) < 1e-12) {
      if (to < t_lo || to > t_hi) continue;
    } else {
      double a = (t_lo - to) / dt, b = (t_hi - to) / dt;
      if (a > b) std::swap(a, b);
      lo = std::max(lo, a);
      hi = std::min(hi, b);
    }
    if (!(hi > lo)) continue;
    const double sa = so + ds * lo, sb = so + ds * hi;
    if (std::max(sa, sb) <= s0) continue;
    bound = std::min(bound, std::max(std::min(sa, sb), s0));
  }
  return bound;
}

// Depth a beam must reach inside a side's band before it bounds the side:
// a beam ending on the seen face stops its clearing tolerance (5 cm along
// the beam) short of it, outside the band at any incidence.
constexpr double kFreeDepth = 0.005;  // m

double to_outline(const FittedRectangle& r, const Vector2d& q) {
  const Vector2d d = q - r.corner;
  const double s = r.u.dot(d), t = r.v.dot(d);
  const double ds = std::max({-s, 0.0, s - r.size_u}), dt = std::max({-t, 0.0, t - r.size_v});
  if (ds > 0.0 || dt > 0.0) return std::hypot(ds, dt);
  return std::min({s, r.size_u - s, t, r.size_v - t});
}

// The rectangle of faces A and B of one cluster (see the header), or false.
// B an end (end_face): its few points pin its direction poorly, so instead
// of the angle test each must lie on the side perpendicular to A.
bool make_rectangle(const ShapeParams& p, const std::vector<Point>& pts, const std::vector<std::uint32_t>& cluster,
                    const Face& A, const Face& B, bool b_is_end, const std::vector<FreeRay>& rays, FittedRectangle& out) {
  if (A.pts.size() < 2 || B.pts.size() < 2) return false;
  if (!b_is_end && std::abs(A.dir.dot(B.dir)) > std::sin(p.rect_max_angle)) return false;
  // Inward axes: v behind A (against A's normal), u behind B.
  Vector2d v0 = math::perp(A.dir), u0 = math::perp(B.dir);
  if (v0.dot(A.normal) > 0.0) v0 = -v0;
  if (u0.dot(B.normal) > 0.0) u0 = -u0;
  const double h = math::cross2(u0, v0) >= 0.0 ? 1.0 : -1.0;  // v = h perp(u)
  // Exactly perpendicular: the directions averaged, each weighted by how
  // well it is pinned (points x length^2).
  auto span = [&](const Face& f) {
    double lo = INFINITY, hi = -INFINITY;
    for (std::uint32_t k : f.pts) {
      const double t = f.dir.dot(pts[k].p);
      lo = std::min(lo, t);
      hi = std::max(hi, t);
    }
    return hi - lo;
  };
  const double la = span(A), lb = span(B);
  const double wa = static_cast<double>(A.pts.size()) * la * la, wb = static_cast<double>(B.pts.size()) * lb * lb;
  const Vector2d u_of_a = -h * math::perp(v0);  // u as face A alone gives it (u0: as B gives it)
  Vector2d u = wa * u_of_a + wb * u0;
  if (!(u.norm() > 1e-9)) return false;
  u.normalize();
  const Vector2d v = h * math::perp(u);
  // Least squares: each face's offset is the mean of its points'.
  double ta = 0.0, sb = 0.0;
  for (std::uint32_t k : A.pts) ta += v.dot(pts[k].p);
  for (std::uint32_t k : B.pts) sb += u.dot(pts[k].p);
  ta /= static_cast<double>(A.pts.size());
  sb /= static_cast<double>(B.pts.size());
  if (b_is_end)
    for (std::uint32_t k : B.pts)
      if (std::abs(u.dot(pts[k].p) - sb) > p.inlier_distance) return false;
  FittedRectangle r;
  r.u = u;
  r.v = v;
  r.corner = sb * u + ta * v;
  // Each face runs from the corner into the other's inner side: a convex
  // corner seen from outside (a room's corner seen from inside runs the
  // other way).
  double a_lo = INFINITY, a_hi = -INFINITY, b_lo = INFINITY, b_hi = -INFINITY;
  for (std::uint32_t k : A.pts) {
    const double s = u.dot(pts[k].p - r.corner);
    a_lo = std::min(a_lo, s);
    a_hi = std::max(a_hi, s);
  }
  for (std::uint32_t k : B.pts) {
    const double t = v.dot(pts[k].p - r.corner);
    b_lo = std::min(b_lo, t);
    b_hi = std::max(b_hi, t);
  }
  if (a_lo < -p.rect_corner_gap || b_lo < -p.rect_corner_gap) return false;
  if (a_lo > p.rect_corner_gap && b_lo > p.rect_corner_gap) return false;  // no corner between them
  if (a_hi < p.rect_min_side || b_hi < p.rect_min_side || a_hi > p.rect_max_side || b_hi > p.rect_max_side)
    return false;
  r.seen_u = a_hi;
  r.seen_v = b_hi;
  // The unseen extents (see the header). A face ends between its last
  // return (seen) and where the first beam that passed it crosses its line
  // (bound; +inf when none did). The side known more tightly ends midway
  // (or, bounded by nothing, as long as the longer seen side: a square);
  // the other, where the first's length is within its own interval (to the
  // inlier distance), is as long (a square), else midway, else (bounded by
  // nothing) as seen.
  const double bu = free_extent(rays, r.corner, u, v, r.seen_u, kFreeDepth, r.seen_v);
  const double bv = free_extent(rays, r.corner, v, u, r.seen_v, kFreeDepth, r.seen_u);
  r.bounded_u = std::isfinite(bu);
  r.bounded_v = std::isfinite(bv);
  const bool u_tighter = bu - r.seen_u <= bv - r.seen_v;
  const double seen1 = u_tighter ? r.seen_u : r.seen_v, bound1 = u_tighter ? bu : bv;
  const double seen2 = u_tighter ? r.seen_v : r.seen_u, bound2 = u_tighter ? bv : bu;
  const double side1 = std::isfinite(bound1) ? seen1 + 0.5 * (bound1 - seen1) : std::max(seen1, seen2);
  double side2 = seen2;
  if (side1 >= seen2 - p.inlier_distance && side1 <= bound2) side2 = std::max(side1, seen2);
  else if (std::isfinite(bound2)) side2 = seen2 + 0.5 * (bound2 - seen2);
  r.size_u = std::min(u_tighter ? side1 : side2, p.rect_max_side);
  r.size_v = std::min(u_tighter ? side2 : side1, p.rect_max_side);
  // Now that both sides reach farther, free space over the whole of each.
  const double cut_u = free_extent(rays, r.corner, u, v, r.seen_u, kFreeDepth, r.size_v);
  const double cut_v = free_extent(rays, r.corner, v, u, r.seen_v, kFreeDepth, r.size_u);
  r.size_u = std::min(r.size_u, cut_u);
  r.size_v = std::min(r.size_v, cut_v);
  // The outline must explain the cluster tightly.
  double ss = 0.0;
  std::size_t on = 0;
  for (std::uint32_t k : cluster) {
    const double d = to_outline(r, pts[k].p);
    if (d > p.inlier_distance) continue;
    ss += d * d;
    ++on;
  }
  r.inliers = static_cast<std::uint32_t>(on);
  r.points = static_cast<std::uint32_t>(cluster.size());
  r.rms = on ? std::sqrt(ss / static_cast<double>(on)) : 0.0;
  if (on < p.min_points || static_cast<double>(on) < p.min_inlier_ratio * static_cast<double>(cluster.size()) ||
      r.rms > p.max_rms)
    return false;
  out = r;
  return true;
}

// One face and a perpendicular end too short for a line fit of its own: the
// cluster's points not on any fitted face that lie behind one end of A,
// along a line perpendicular to it, seen on rect_min_end_points over
// rect_min_end_length at least.
bool end_face(const ShapeParams& p, const std::vector<Segment2>& segs, const std::vector<Point>& pts,
              const std::vector<std::uint32_t>& leftover, const Face& A, bool far_end, Face& B) {
  double lo = INFINITY, hi = -INFINITY;
  std::uint32_t k_lo = A.pts.front(), k_hi = A.pts.front();
  for (std::uint32_t k : A.pts) {
    const double t = A.dir.dot(pts[k].p);
    if (t < lo) lo = t, k_lo = k;
    if (t > hi) hi = t, k_hi = k;
  }
  const double t_end = far_end ? hi : lo;
  const Vector2d out_dir = far_end ? A.dir : Vector2d(-A.dir);
  // The corner (A's last point there) is on the end too.
  B.pts.assign(1, far_end ? k_hi : k_lo);
  for (std::uint32_t k : leftover) {
    const Vector2d& q = pts[k].p;
    const double along = A.dir.dot(q) - t_end, depth = -A.normal.dot(q - pts[A.pts.front()].p);
    if (std::abs(along) <= p.rect_corner_gap && depth > p.inlier_distance && depth <= p.rect_max_side)
      B.pts.push_back(k);
  }
  if (B.pts.size() < p.rect_min_end_points) return false;
  // PCA line through them.
  Vector2d mean = Vector2d::Zero();
  for (std::uint32_t k : B.pts) mean += pts[k].p;
  mean /= static_cast<double>(B.pts.size());
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  Vector2d nsum = Vector2d::Zero();
  for (std::uint32_t k : B.pts) {
    const Vector2d q = pts[k].p - mean;
    sxx += q.x() * q.x();
    sxy += q.x() * q.y();
    syy += q.y() * q.y();
    nsum += segs[pts[k].seg].normal;
  }
  const double phi = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
  B.dir = Vector2d(std::cos(phi), std::sin(phi));
  double blo = INFINITY, bhi = -INFINITY, ss = 0.0;
  const Vector2d bn = math::perp(B.dir);
  for (std::uint32_t k : B.pts) {
    const double t = B.dir.dot(pts[k].p), d = bn.dot(pts[k].p - mean);
    blo = std::min(blo, t);
    bhi = std::max(bhi, t);
    ss += d * d;
  }
  if (bhi - blo < p.rect_min_end_length || std::sqrt(ss / static_cast<double>(B.pts.size())) > p.max_rms) return false;
  // Its outward normal: away from A's body, and the way its segments face.
  B.normal = bn.dot(out_dir) >= 0.0 ? bn : Vector2d(-bn);
  return nsum.dot(B.normal) > 0.0;
}

// Replaces (marks) the raw laser segments on an outline (both ends and the
// midpoint within 2 tol) and the shadow edges that start on it.
template <typename Dist>
void replace_on_outline(const std::vector<Segment2>& segs, double tol, Dist dist, std::vector<std::uint8_t>& replaced,
                        std::size_t& count) {
  for (std::size_t i = 0; i < segs.size(); ++i) {
    const Segment2& s = segs[i];
    if (replaced[i] || s.kind != SensorKind::kLaser || s.fitted) continue;
    const bool raw = !s.interpolated && !s.shadow && dist(s.a) <= 2.0 * tol && dist(s.b) <= 2.0 * tol &&
                     dist(Vector2d(0.5 * (s.a + s.b))) <= 2.0 * tol;
    const bool shadow = s.shadow && dist(s.a) <= 2.0 * tol;
    if (raw || shadow) {
      replaced[i] = 1;
      ++count;
    }
  }
}

}  // namespace

void complete_shapes(const ShapeParams& p, const MapParams& mp, const LocalMap& map, ShapeModel& out) {
  // The previous completion's circles: temporal coherence (below).
  std::vector<FittedCircle> previous;
  previous.swap(out.circles);
  std::vector<FittedRectangle> previous_rects;
  previous_rects.swap(out.rectangles);
  out.lines.clear();
  out.bridges = 0;
  out.kept = 0;
  out.kept_rectangles = 0;
  out.raw_replaced = 0;
  out.clusters = 0;
  out.segments.clear();
  const std::vector<Segment2>& segs = map.segments;
  if (!p.enabled || !validate(p).empty() || !validate(mp).empty()) {
    out.segments = segs;
    return;
  }
  std::vector<Point> pts;
  std::vector<std::vector<std::uint32_t>> clusters = cluster_points(p, segs, pts);
  std::vector<std::uint8_t> replaced(segs.size(), 0);
  struct LineRec {
    LineFit fit;
    Vector2d normal;
    std::vector<std::uint32_t> segs;  // measured segments on the line (both ends inliers)
    std::int64_t stamp = 0;
  };
  std::vector<LineRec> lines;
  std::vector<std::uint8_t> seg_on_line(segs.size(), 0);
  std::vector<std::uint8_t> is_in(pts.size(), 0);  // marks of one line's inliers, cleared after use
  const double tol = p.inlier_distance;
  std::vector<FreeRay> rays;  // the recent scans' free space, gathered when a rectangle is first tried
  bool have_rays = false;

  for (const std::vector<std::uint32_t>& cl : clusters) {
    if (cl.size() < 3 || out.clusters == p.max_clusters) break;  // largest first
    ++out.clusters;
    // A wall first: a line that explains the cluster settles it.
    LineFit first;
    const bool have_line = fit_line(p, pts, cl, first);
    const bool enough = cl.size() >= p.min_points;
    const double line_share = have_line ? static_cast<double>(first.inliers.size()) / static_cast<double>(cl.size()) : 0.0;
    bool circle = false;
    if (enough && line_share < p.line_preference) {
      CircleFit cf;
      if (fit_circle(p, pts, cl, cf) && cf.radius >= p.min_radius && cf.radius <= p.max_radius &&
          cf.rms <= p.max_rms && cf.arc >= p.min_arc &&
          static_cast<double>(cf.inliers) >= p.min_inlier_ratio * static_cast<double>(cl.size()) &&
          static_cast<double>(have_line ? first.inliers.size() : 0) < p.line_preference * static_cast<double>(cf.inliers)) {
        circle = seen_from_outside(segs, pts, cl, cf.centre);
        if (circle) {
          FittedCircle fc;
          fc.centre = cf.centre;
          fc.radius = cf.radius;
          fc.rms = cf.rms;
          fc.arc = cf.arc;
          fc.inliers = static_cast<std::uint32_t>(cf.inliers);
          fc.points = static_cast<std::uint32_t>(cl.size());
          out.circles.push_back(fc);
        }
      }
    }
    if (!circle && !previous.empty()) {
      // Temporal coherence: a circle of the previous completion that still
      // explains this cluster is kept, although this map alone did not pass
      // the acceptance tests (a scan chunk lost on the link, a few points
      // fewer, the arc cut by an occluder). Without it the outline would
      // flicker with the data, and a probe resting on the object's back
      // would fall in while the circle is away.
      for (const FittedCircle& pc : previous) {
        std::size_t on = 0;
        for (std::uint32_t k : cl)
          if (std::abs((pts[k].p - pc.centre).norm() - pc.radius) <= 1.5 * p.inlier_distance) ++on;
        if (on >= 3 && static_cast<double>(on) >= p.min_inlier_ratio * static_cast<double>(cl.size()) &&
            seen_from_outside(segs, pts, cl, pc.centre)) {
          out.circles.push_back(pc);
          ++out.kept;
          circle = true;
          break;
        }
      }
    }
    if (circle) continue;
    // Walls and corners: sequential line fits on what is left.
    std::vector<std::uint32_t> rest = cl;
    LineFit lf = first;
    bool ok = have_line;
    const std::size_t lines_before = lines.size();
    std::vector<Face> faces;  // this cluster's fitted faces
    for (int n = 0; n < p.max_lines_per_cluster && ok; ++n) {
      LineRec rec;
      rec.fit = lf;
      for (std::uint32_t k : lf.inliers) is_in[k] = 1;
      Vector2d nsum = Vector2d::Zero();
      const Vector2d perp = math::perp(lf.dir);
      std::vector<std::uint32_t> cand;
      for (std::uint32_t k : lf.inliers) {
        const std::uint32_t si = pts[k].seg;
        const Segment2& s = segs[si];
        if (seg_on_line[si] || std::abs(perp.dot(s.a - lf.point)) > tol || std::abs(perp.dot(s.b - lf.point)) > tol)
          continue;
        if (!cand.empty() && cand.back() == si) continue;  // both ends of one segment
        cand.push_back(si);
        nsum += s.normal;
      }
      if (!cand.empty() && nsum.norm() > 1e-9) {
        rec.normal = perp.dot(nsum) >= 0.0 ? perp : Vector2d(-perp);
        // Only the face the line's normal looks out of: the far face of a
        // board thinner than the inlier band stays its own (raw) surface.
        for (std::uint32_t si : cand) {
          if (segs[si].normal.dot(rec.normal) < kSameFace) continue;
          seg_on_line[si] = 1;
          rec.segs.push_back(si);
          rec.stamp = std::max(rec.stamp, segs[si].stamp_ns);
        }
        if (!rec.segs.empty()) {
          faces.push_back({lf.inliers, lf.dir, rec.normal});
          lines.push_back(std::move(rec));
        }
      }
      std::vector<std::uint32_t> next;
      for (std::uint32_t k : rest)
        if (!is_in[k]) next.push_back(k);
      for (std::uint32_t k : lf.inliers) is_in[k] = 0;
      rest.swap(next);
      ok = fit_line(p, pts, rest, lf);
    }
    if (!p.rectangles) continue;
    // Rectangles: two faces at a right angle, else one face and a
    // perpendicular end among the points no face took (rest).
    if (!have_rays) {
      rays = free_rays(mp, map);
      have_rays = true;
    }
    FittedRectangle best;
    bool found = false;
    if (!enough) faces.clear();  // too few points to fit: only a rectangle kept from before
    for (std::size_t i = 0; i < faces.size(); ++i)
      for (std::size_t j = i + 1; j < faces.size(); ++j) {
        FittedRectangle r;
        if (make_rectangle(p, pts, cl, faces[i], faces[j], false, rays, r) && (!found || r.inliers > best.inliers)) {
          best = r;
          found = true;
        }
      }
    if (!found) {
      for (const Face& a : faces)
        for (bool far_end : {true, false}) {
          Face b;
          FittedRectangle r;
          if (end_face(p, segs, pts, rest, a, far_end, b) && make_rectangle(p, pts, cl, a, b, true, rays, r) &&
              (!found || r.inliers > best.inliers)) {
            best = r;
            best.from_end = true;
            found = true;
          }
        }
    }
    if (!found) {
      // Temporal coherence, as for circles.
      for (const FittedRectangle& pr : previous_rects) {
        std::size_t on = 0;
        for (std::uint32_t k : cl)
          if (to_outline(pr, pts[k].p) <= 1.5 * p.inlier_distance) ++on;
        if (on >= 3 && static_cast<double>(on) >= p.min_inlier_ratio * static_cast<double>(cl.size()) &&
            seen_from_outside(segs, pts, cl, pr.centre())) {
          best = pr;
          found = true;
          ++out.kept_rectangles;
          break;
        }
      }
    } else {
      found = seen_from_outside(segs, pts, cl, best.centre());
    }
    if (found) {
      out.rectangles.push_back(best);
      lines.resize(lines_before);  // its faces are drawn by its outline, not as walls
    }
  }

  // Circles replace the raw segments they explain and the shadow edges that
  // start on their outline (the circle's back closes the object instead).
  for (const FittedCircle& c : out.circles)
    replace_on_outline(segs, tol, [&](const Vector2d& x) { return std::abs((x - c.centre).norm() - c.radius); },
                       replaced, out.raw_replaced);
  for (const FittedRectangle& r : out.rectangles)
    replace_on_outline(segs, tol, [&](const Vector2d& x) { return to_outline(r, x); }, replaced, out.raw_replaced);

  // Lines: their extents; then collinear pieces facing the same way (one
  // wall) are drawn on their common line over what was seen (the union of
  // their segments' spans: a doorway stays open), in place of the raw
  // segments, whose scan noise would otherwise reach the hand as kinks; and
  // bridged across gaps nothing has seen through.
  std::vector<Segment2> line_pieces;
  for (const LineRec& r : lines) {
    double lo = INFINITY, hi = -INFINITY, ss = 0.0;
    const Vector2d perp = math::perp(r.fit.dir);
    for (std::uint32_t k : r.fit.inliers) {
      const double t = r.fit.dir.dot(pts[k].p - r.fit.point), d = perp.dot(pts[k].p - r.fit.point);
      lo = std::min(lo, t);
      hi = std::max(hi, t);
      ss += d * d;
    }
    FittedLine fl;
    fl.a = r.fit.point + lo * r.fit.dir;
    fl.b = r.fit.point + hi * r.fit.dir;
    fl.normal = r.normal;
    fl.inliers = static_cast<std::uint32_t>(r.fit.inliers.size());
    fl.rms = std::sqrt(ss / static_cast<double>(std::max<std::size_t>(1, r.fit.inliers.size())));
    out.lines.push_back(fl);
  }
  if (!lines.empty()) {
    Disjoint walls(lines.size());
    const double cos_max = std::cos(p.line_max_angle);
    for (std::uint32_t i = 0; i < lines.size(); ++i)
      for (std::uint32_t j = i + 1; j < lines.size(); ++j) {
        if (lines[i].normal.dot(lines[j].normal) < cos_max) continue;
        const FittedLine& fa = out.lines[i];
        const FittedLine& fb = out.lines[j];
        const Vector2d& n = lines[i].normal;
        if (std::abs(n.dot(fb.a - fa.a)) > 2.0 * tol || std::abs(n.dot(fb.b - fa.a)) > 2.0 * tol) continue;
        walls.join(i, j);
      }
    std::vector<std::vector<std::uint32_t>> groups(lines.size());
    for (std::uint32_t i = 0; i < lines.size(); ++i) groups[walls.find(i)].push_back(i);
    std::vector<std::pair<double, double>> cover;
    for (const std::vector<std::uint32_t>& g : groups) {
      if (g.empty()) continue;
      // The group's reference line: its best supported member.
      std::uint32_t ref = g[0];
      for (std::uint32_t i : g)
        if (lines[i].fit.inliers.size() > lines[ref].fit.inliers.size()) ref = i;
      const Vector2d o = lines[ref].fit.point, d = lines[ref].fit.dir, nrm = lines[ref].normal;
      cover.clear();
      std::int64_t stamp = 0;
      for (std::uint32_t i : g)
        for (std::uint32_t si : lines[i].segs) {
          const double ta = d.dot(segs[si].a - o), tb = d.dot(segs[si].b - o);
          cover.emplace_back(std::min(ta, tb), std::max(ta, tb));
          stamp = std::max(stamp, segs[si].stamp_ns);
          if (p.render_lines && !replaced[si]) {
            replaced[si] = 1;
            ++out.raw_replaced;
          }
        }
      std::sort(cover.begin(), cover.end());
      double from = cover.front().first, reach = cover.front().second;
      auto flush = [&](double to) {
        if (p.render_lines && to > from) line_pieces.push_back(fitted_piece(o + from * d, o + to * d, nrm, stamp));
      };
      for (std::size_t k = 1; k < cover.size(); ++k) {
        const double gap = cover[k].first - reach;
        if (gap > 1e-6) {
          bool bridge = false;
          if (p.line_max_gap > 0.0 && gap <= p.line_max_gap) {
            // Bridge unless a recent scan saw through the gap.
            bool seen = false;
            const int steps = std::max(2, static_cast<int>(std::ceil(gap / p.gap_test_step)));
            for (int st = 1; st < steps && !seen; ++st) {
              const Vector2d q = o + (reach + gap * st / steps) * d;
              for (const RangeScan2D& scan : map.recent_laser)
                if (scan_sees_through(mp, scan, q)) {
                  seen = true;
                  break;
                }
            }
            bridge = !seen;
          }
          if (bridge) {
            ++out.bridges;
            if (!p.render_lines) line_pieces.push_back(fitted_piece(o + reach * d, o + cover[k].first * d, nrm, stamp));
          } else {
            flush(reach);
            from = cover[k].first;
          }
        }
        reach = std::max(reach, cover[k].second);
      }
      flush(reach);
    }
  }

  std::int64_t newest = 0;
  for (std::size_t i = 0; i < segs.size(); ++i) {
    newest = std::max(newest, segs[i].stamp_ns);
    if (!replaced[i]) out.segments.push_back(segs[i]);
  }
  for (const FittedCircle& c : out.circles) {
    const int n = p.circle_pieces;
    for (int k = 0; k < n; ++k) {
      const double t0 = 2.0 * std::numbers::pi * k / n, t1 = 2.0 * std::numbers::pi * (k + 1) / n;
      const double tm = 0.5 * (t0 + t1);
      out.segments.push_back(fitted_piece(c.centre + c.radius * Vector2d(std::cos(t0), std::sin(t0)),
                                          c.centre + c.radius * Vector2d(std::cos(t1), std::sin(t1)),
                                          Vector2d(std::cos(tm), std::sin(tm)), newest));
    }
  }
  for (const FittedRectangle& r : out.rectangles) {
    const Vector2d c0 = r.corner, c1 = c0 + r.size_u * r.u, c2 = c1 + r.size_v * r.v, c3 = c0 + r.size_v * r.v;
    out.segments.push_back(fitted_piece(c0, c1, -r.v, newest));
    out.segments.push_back(fitted_piece(c1, c2, r.u, newest));
    out.segments.push_back(fitted_piece(c2, c3, r.v, newest));
    out.segments.push_back(fitted_piece(c3, c0, -r.u, newest));
  }
  out.segments.insert(out.segments.end(), line_pieces.begin(), line_pieces.end());
}

}  // namespace hemm::mapping
