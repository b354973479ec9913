#pragma once
// Shape completion of the local model (model thread): primitives fitted to
// the map's laser points with PCL's sample consensus, rendered where their
// support is good, raw segments kept everywhere else.
//
//  - Circles (SACMODEL_CIRCLE2D: columns, bins, table legs, a ball cut at
//    the laser plane). A laser sees at most the near half of a round object;
//    the unseen back is closed by shadow edges, which are straight and 0.6 m
//    deep (MapParams::shadow_depth), so a probe sliding round the back feels
//    the wrong outline. A circle fitted to the seen arc gives the back its
//    true shape and ends the solid at the object's fitted extent. Accepted
//    only when the arc explains the cluster (inlier share, RMS), subtends
//    enough angle about the centre to pin the radius, a straight line does
//    not explain it nearly as well (a short flat piece is a wall, not part of
//    a big circle), and the seen surface faces away from the centre (the
//    outside of a convex object, not the inside of a curved wall).
//    The circle's outline replaces the raw segments it explains and the
//    shadow edges that start on it. A circle once accepted is kept while the
//    object's points stay on it (see complete_shapes).
//  - Lines (SACMODEL_LINE, sequentially per cluster: a corner gives two).
//    Fitted wall pieces on one line and facing the same way are one wall,
//    drawn on the fitted line over the span its segments cover (a doorway
//    stays open) in place of those segments: 1 cm scan noise on 2 cm
//    segments makes kinks of tens of degrees, felt as sideways force. Gaps
//    of at most line_max_gap between its pieces are bridged unless a recent
//    laser scan saw through the gap: dropouts (no information) do not open
//    a wall; an opening seen as free space (a return beyond it, or nothing
//    up to the laser's range) stays open. Only the face the line looks out
//    of is replaced: the far face of a thin board stays its own surface.
//
// Points: the endpoints of the map's measured laser segments (not sonar
// arcs, not shadow edges, not earlier fits), clustered by proximity
// (cluster_gap) so one fit sees one object.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/mapping/local_map.h"

namespace hemm::mapping {

struct ShapeParams {
  bool enabled = true;
  double cluster_gap = 0.06;        // m: points closer than this are one object
  std::size_t min_points = 6;       // a cluster with fewer keeps its raw segments
  std::size_t max_clusters = 256;   // the largest clusters are fitted first
  int max_iterations = 200;         // RANSAC iterations per model
  // ~3 sigma of the 1 cm laser range noise after the temporal filter.
  double inlier_distance = 0.015;   // m
  double max_rms = 0.008;           // m: worse fits are not rendered
  double min_inlier_ratio = 0.85;   // share of a cluster's points a circle must explain
  // Radii in scope: table legs (12 mm) to columns and bins (0.3 m), with margin.
  double min_radius = 0.01;         // m
  double max_radius = 0.60;         // m
  double min_arc = 1.05;            // rad (60 deg) of the circle the inliers span
  double line_preference = 0.9;     // a line explaining this share of the circle's inliers wins
  int circle_pieces = 32;           // outline pieces (sagitta r (1 - cos(pi / 32)) = 0.5 % of r: 0.7 mm at 0.15 m)
  int max_lines_per_cluster = 4;
  // Walls drawn on their fitted line over the span seen (in place of the raw
  // segments, whose noise makes kinks the hand feels); false: raw walls, bridges only.
  bool render_lines = true;
  double line_max_gap = 0.30;       // m: longest gap bridged between collinear wall pieces
  double line_max_angle = 0.05;     // rad: "the same line"
  double gap_test_step = 0.02;      // m: spacing of the points tested for "seen through"
};

// Empty when usable; otherwise what is wrong.
std::string validate(const ShapeParams& p);

struct FittedCircle {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // W [m]
  double radius = 0.0;
  double rms = 0.0;        // m, of the inliers' distances to the circle
  double arc = 0.0;        // rad the inliers span about the centre
  std::uint32_t inliers = 0;
  std::uint32_t points = 0;  // of its cluster
};

struct FittedLine {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();  // extent of the inliers on the line, W [m]
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();  // toward the free side
  double rms = 0.0;
  std::uint32_t inliers = 0;
};

struct ShapeModel {
  std::vector<FittedCircle> circles;
  std::vector<FittedLine> lines;
  std::size_t bridges = 0;        // gaps between wall pieces closed
  std::size_t kept = 0;           // circles of the previous completion kept (temporal coherence)
  std::size_t raw_replaced = 0;   // raw segments (and shadow edges) a primitive stands for, left out
  std::size_t clusters = 0;       // clusters considered
  // What the snapshot is built from: the map's segments minus raw_replaced,
  // plus the circles' outlines and the walls' lines (pieces marked fitted).
  std::vector<Segment2> segments;
};

// Fits and renders; out is overwritten (its capacity reused). Temporal
// coherence: a circle in out from the previous call is kept while it still
// explains its object's points (at least 3, min_inlier_ratio of the cluster,
// seen from outside) even where this map alone would not pass the tests, so
// the outline does not flicker with lost or noisy scans; pass a fresh
// ShapeModel to fit from scratch. A disabled or invalid ShapeParams leaves
// the map's segments as they are.
void complete_shapes(const ShapeParams& p, const MapParams& mp, const LocalMap& map, ShapeModel& out);

}  // namespace hemm::mapping
