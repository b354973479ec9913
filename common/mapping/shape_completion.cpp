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
    pts.push_back({s.b, i});
  }
  const std::size_t n = pts.size();
  Disjoint sets(n);
  // Consecutive points of one segment.
  for (std::size_t k = 1; k < n; ++k)
    if (pts[k].seg == pts[k - 1].seg) sets.join(static_cast<std::uint32_t>(k), static_cast<std::uint32_t>(k - 1));
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

}  // namespace

void complete_shapes(const ShapeParams& p, const MapParams& mp, const LocalMap& map, ShapeModel& out) {
  // The previous completion's circles: temporal coherence (below).
  std::vector<FittedCircle> previous;
  previous.swap(out.circles);
  out.lines.clear();
  out.bridges = 0;
  out.kept = 0;
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
        if (!rec.segs.empty()) lines.push_back(std::move(rec));
      }
      std::vector<std::uint32_t> next;
      for (std::uint32_t k : rest)
        if (!is_in[k]) next.push_back(k);
      for (std::uint32_t k : lf.inliers) is_in[k] = 0;
      rest.swap(next);
      ok = fit_line(p, pts, rest, lf);
    }
  }

  // Circles replace the raw segments they explain and the shadow edges that
  // start on their outline (the circle's back closes the object instead).
  for (const FittedCircle& c : out.circles) {
    auto on = [&](const Vector2d& x, double t) { return std::abs((x - c.centre).norm() - c.radius) <= t; };
    for (std::size_t i = 0; i < segs.size(); ++i) {
      const Segment2& s = segs[i];
      if (replaced[i] || s.kind != SensorKind::kLaser || s.fitted) continue;
      const bool raw = !s.interpolated && !s.shadow && on(s.a, 2.0 * tol) && on(s.b, 2.0 * tol) &&
                       on(0.5 * (s.a + s.b), 2.0 * tol);
      const bool shadow = s.shadow && on(s.a, 2.0 * tol);
      if (raw || shadow) {
        replaced[i] = 1;
        ++out.raw_replaced;
      }
    }
  }

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
  out.segments.insert(out.segments.end(), line_pieces.begin(), line_pieces.end());
}

}  // namespace hemm::mapping
