#pragma once
// The local model (HEMM Sec. 3.2): a 2D map in the world frame W built from
// range scans. Each scan is placed by the robot pose stamped in it
// (T_W_S = T_W_R(acquisition) * T_R_S), so latency does not smear it.
//
// Surfaces: consecutive returns are joined into polyline segments; windowing
// breaks the polyline at range discontinuities (range jump, or a segment seen
// edge-on by the beam), so a near object is never joined to the wall behind
// it; invalid beams are never obstacles. Sparse sonar data are interpolated:
// an arc across each sonar cone at the measured range (nothing is closer
// inside the cone), and a bridging segment between neighbouring cones whose
// ranges agree. Every segment carries a unit normal pointing to its free side
// (toward the sensor that saw it).
//
// Sonar and laser together: an arc spans the whole cone (0.5 m wide at 2 m
// for a 15 deg cone) although the echo came from one spot, so where the laser
// also looks the arc is a false wall in front of the true surface (the proxy
// rests on it, or is caught between it and the laser polyline). A sonar echo
// the newest laser scan explains -- a laser return inside the cone no farther
// than the echo plus sonar_laser_tolerance, within sonar_laser_max_age_s --
// is therefore left to the laser; echoes the laser does not explain (outside
// its field of view, or an obstacle below its plane) are still drawn.
//
// The newest scan supersedes what it re-observes (ray clearing). Before a
// scan's segments are added, older segments of the SAME sensor kind whose
// points the scan has seen through are removed: a point is re-observed when
// it lies in the scan's field of view, no farther from the sensor than the
// range measured at its bearing plus clear_tolerance. Why: a 30 Hz laser
// looking at one surface for window_age_s would otherwise leave ~90 noisy
// overlapping copies of it -- a fuzzy band of tiny concave kinks the proxy
// snags on; an object that moved away would stay until it aged out; and the
// map would cost memory and time for nothing. With clearing the map holds one
// copy of what is currently seen, and a moved object vanishes at the next scan.
// What is kept: what is out of view, occluded (behind the measured range),
// behind a dropout, or in doubt at a range discontinuity -- a point whose
// nearest beam slipped past an object's edge (its neighbour toward the point
// is nearer) may lie on that object, so the object's edge is not cleared by
// the wall beam next to it.
//   Laser: each test point (both endpoints and the midpoint: a long chord,
// e.g. across bridged dropouts, can pass behind a new object with both ends
// visible) takes the beam nearest its bearing; the limit is that beam's range
// (range_max for a valid "no return"), interpolated toward the neighbour on
// the point's side when the two agree (by the windowing jump test). A chunk
// of a dense scan judges only points whose nearest beam is its own; marks
// accumulate on the segment (Segment2::reobserved), so a segment across two
// chunks is cleared when both have seen it, like the whole scan would.
//   Sonar: the echo at r says nothing is nearer anywhere in the cone: old
// sonar segments in the cone (widened by half an arc piece: arcs are an
// inference across the cone) closer than r + tolerance go; in the gap between
// neighbouring cones (<= sonar_max_gap) the two echoes are the limit
// (interpolated across the gap when they agree, as the bridge is; else the nearer).
// Laser never clears sonar and sonar never clears laser: they see at different
// heights, and the sonar must keep obstacles below the laser plane.
//
// PCL is deliberately not used here: measured on a 10k-point scan
// (tests/bench/proxy/bench_map_pcl), a k-d tree radius search costs ~7x the
// midpoint-grid query and allocates; VoxelGrid loses the beam order the
// polylines need; PCA normal estimation is 100-1000x slower than the polyline
// fit for a few degrees less error. Down-sampling is min_point_spacing.
//
// Threads: add_scan / slide_window / build_snapshot run on the model thread
// and allocate; the servo thread only reads an immutable MapSnapshot through
// query_segments, which never allocates.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/mapping/range_scan.h"

namespace hemm::mapping {

struct Segment2 {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();       // endpoints in W [m]
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX(); // unit, toward the free side
  std::int64_t stamp_ns = 0;                         // scan acquisition time
  SensorKind kind = SensorKind::kLaser;
  bool interpolated = false;  // sonar arc / bridge: inferred, not a measured point pair
  // A piece of a fitted primitive (shape completion: a circle's outline, a
  // wall's line continued through a dropout), not a measured point pair.
  bool fitted = false;
  // Shadow edge (laser): the side of the unseen space behind a visible face,
  // drawn from the face's silhouette point along the grazing beam, normal
  // toward the beam that passed it (see MapParams::shadow_depth).
  bool shadow = false;
  // Snapshot pieces only: how deep behind this piece's line the solid may
  // reach before another surface facing the other way (the object's far
  // side, e.g. the back of a thin board) begins. +inf: nothing behind.
  float depth_limit = std::numeric_limits<float>::infinity();
  // Ray clearing (model thread only): bits 1 = a, 2 = midpoint, 4 = b seen
  // through by a newer scan (or chunk) of the same kind; all three: removed.
  std::uint8_t reobserved = 0;
};

struct MapParams {
  // Windowing (laser polylines). Consecutive returns i, j are NOT joined when
  //   |r_i - r_j| > jump_ratio * min(r_i, r_j) + jump_abs, or
  //   the segment makes less than min_view_angle with the beam (seen edge-on)
  //     while |r_i - r_j| > range_noise, or
  //   more than max_bridged_dropouts invalid beams lie between them, or
  //   the segment is longer than max_segment_length.
  double jump_ratio = 0.15;
  double jump_abs = 0.05;         // m
  double min_view_angle = 0.14;   // rad (~8 deg)
  int max_bridged_dropouts = 1;
  double range_noise = 0.03;      // m, ~3 sigma of the range noise
  double max_segment_length = 1.0;  // m
  // Down-sampling of dense laser scans: a return closer than this to the last
  // kept return of the same polyline is skipped (0 = keep all). Also keeps
  // the windowing's edge-on test meaningful: on points closer together than
  // the range noise every segment looks edge-on.
  double min_point_spacing = 0.02;  // m
  // Laser segment normals: PCA line fit over the polyline's points within this
  // window around each segment (noise-robust on dense scans; 0 = each
  // segment's own perpendicular).
  double normal_window = 0.20;     // m
  // Sonar interpolation.
  int sonar_arc_pieces = 4;        // straight pieces per cone arc
  double sonar_merge_ratio = 0.10; // neighbours joined when |r_i - r_j| <= ratio * min + abs
  double sonar_merge_abs = 0.10;   // m
  double sonar_max_gap = 0.45;     // rad: largest angular gap between cone edges to bridge
  // A sonar echo explained by a laser return (see above) is not drawn; 0 age: never.
  double sonar_laser_tolerance = 0.15;  // m beyond the echo's range
  double sonar_laser_max_age_s = 0.5;   // |sonar stamp - laser stamp|
  // Ray clearing (see above): an older segment point counts as re-observed
  // when it lies no farther than the range measured at its bearing plus this
  // (~3 sigma of laser range noise + a margin for odometry between scans).
  bool clear_reobserved = true;
  double clear_tolerance = 0.05;   // m
  // Unseen space behind a visible surface is not free. Where a laser
  // polyline ends at a silhouette (the next beam passes it: a farther return
  // or nothing up to range_max), a shadow edge closes the unseen region
  // behind the face: a segment from the silhouette point along the grazing
  // beam, this long, or only to the passing beam's range when that is
  // nearer (it ends at the surface behind). A later scan that sees through
  // part of it (free space) clips it there, and the clipped rest goes when
  // its first point is seen through. The proxy therefore slides along the
  // visible face and on along the shadow edge instead of falling into the
  // object round its silhouette. Why 0.6 m: deeper than the diameter of the
  // round objects in scope (columns, bins, legs up to r = 0.3 m), so the
  // whole object lies inside the closed shadow, and than the device's deepest
  // push at the exploration scale (3.3 N / 300 N/m * 50 = 0.55 m): a probe
  // pressed into the shadow is held by its edge, not released past its end.
  // 0: no shadow edges.
  double shadow_depth = 0.6;       // m
  double shadow_clip_step = 0.05;  // m, spacing of the points tested when clipping a shadow edge
  // Temporal filter of laser surfaces (scan noise must not reach the hand as
  // force spikes on a resting contact). Each return whose beam meets the
  // map's current laser surface within temporal_gate of it is drawn at
  //   r_old + temporal_gain * (r - r_old)
  // (an exponential average along the beam, per surface point: at gain g the
  // steady noise is sqrt(g / (2 - g)) of the raw, 0.33 at 0.2). A return
  // farther than the gate from the old surface is taken as it is: a real
  // move of more than the gate per scan (3 cm at 30 Hz = 0.9 m/s) is
  // followed at once; below that the lag of a steady move v is
  // v T (1 - g) / g (13 mm at 0.1 m/s, at 30 Hz). Registration keeps the
  // static scene still in the map frame, so only moving objects lag. 1 = off.
  double temporal_gain = 0.2;
  double temporal_gate = 0.03;     // m, ~3 sigma of the laser's range noise
  // Sliding window: keep only what the probe can reach.
  double window_age_s = 3.0;       // drop segments older than this
  double window_radius = 6.0;      // m, drop segments farther than this from the centre
  std::size_t max_segments = 20000;  // hard bound; the oldest go first
  // Snapshot index (uniform grid on segment midpoints).
  double cell_size = 0.25;         // m; longer segments are split into pieces <= this
  std::size_t max_cells = 1u << 18;
};

// Empty when usable; otherwise what is wrong.
std::string validate(const MapParams& p);

// Laser returns in W from the last sonar_laser_max_age_s: what the laser
// explains. Kept per return, not per scan, because a dense scan travels in
// chunks (each its own RangeScan2D).
struct LaserReturn {
  Eigen::Vector2d p_W = Eigen::Vector2d::Zero();
  std::int64_t stamp_ns = 0;
};
struct LaserCoverage {
  std::vector<LaserReturn> returns;  // oldest first
};
// Appends the laser scan's returns; drops those older than max_age_s before it.
void update_laser_coverage(LaserCoverage& c, const RangeScan2D& laser_scan, double max_age_s);

// Model-thread state: segments in arrival order (oldest first).
struct LocalMap {
  std::vector<Segment2> segments;
  std::int64_t newest_stamp_ns = std::numeric_limits<std::int64_t>::min();
  LaserCoverage laser;  // recent laser returns (see MapParams::sonar_laser_max_age_s)
  // The newest laser scans (or chunks of one), newest last, at most
  // kRecentLaserScans: what shape completion asks "was this gap seen through?".
  static constexpr std::size_t kRecentLaserScans = 8;
  std::vector<RangeScan2D> recent_laser;
};

// Has this laser scan seen through point q_W (free space up to it and
// beyond, by ray clearing's rule and tolerance)? A dropout, a nearer return,
// q outside the field of view or a sonar scan: false.
bool scan_sees_through(const MapParams& p, const RangeScan2D& scan, const Eigen::Vector2d& q_W);

// Surfaces of one scan, appended to out. A bad scan returns an error and
// leaves out untouched. laser (optional): sonar echoes it explains are not drawn.
std::string extract_segments(const MapParams& p, const RangeScan2D& scan, std::vector<Segment2>& out,
                             const LaserCoverage* laser = nullptr);

// The temporal filter (MapParams::temporal_gain) alone: the laser scan's
// returns moved toward the map's current surface along their beams. Returns
// how many returns were filtered; a sonar scan or gain 1 changes nothing.
std::size_t filter_scan_against_map(const MapParams& p, const LocalMap& map, RangeScan2D& scan);

// Filters a laser scan against the map (temporal_gain), clears what the scan
// re-observes (clear_reobserved), then extract_segments
// into the map (sonar against map.laser; a laser scan also updates
// map.laser); on error the map is unchanged.
std::string add_scan(const MapParams& p, LocalMap& map, const RangeScan2D& scan);

// Ray clearing alone: marks the points of map segments older than the scan
// and of its kind that the scan sees through, and removes the segments whose
// three points are all marked. Returns how many were removed; a bad scan
// removes nothing.
std::size_t clear_reobserved_segments(const MapParams& p, LocalMap& map, const RangeScan2D& scan);

// Drops segments older than window_age_s before now_ns, or farther than
// window_radius from centre_W, then the oldest beyond max_segments.
void slide_window(const MapParams& p, LocalMap& map, std::int64_t now_ns, const Eigen::Vector2d& centre_W);

// Immutable snapshot read by the servo thread.
struct MapSnapshot {
  std::vector<Segment2> segments;    // pieces, each no longer than max_piece_length
  std::vector<std::uint32_t> cell_start;  // CSR: items of cell c are items[cell_start[c] .. cell_start[c+1])
  std::vector<std::uint32_t> items;       // segment indices, bucketed by midpoint cell
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  double cell = 1.0;
  int nx = 0;
  int ny = 0;
  double max_half_length = 0.0;
  std::int64_t stamp_ns = 0;  // newest scan in it
};

MapSnapshot build_snapshot(const MapParams& p, const LocalMap& map);
// The same over any segment list (e.g. shape completion's): stamp_ns = newest scan in it.
MapSnapshot build_snapshot(const MapParams& p, const std::vector<Segment2>& segments, std::int64_t stamp_ns);

// Indices of all snapshot segments within distance r of p (exact test), written
// to out[0 .. min(count, cap)). Returns the count, or cap + 1 as soon as more
// than cap are found (the result is truncated: the caller must shrink its
// query); so its cost is bounded by the items of the cells visited. Never
// allocates.
std::size_t query_segments(const MapSnapshot& s, const Eigen::Vector2d& p, double r, std::uint32_t* out,
                           std::size_t cap);

}  // namespace hemm::mapping
