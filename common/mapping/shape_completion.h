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
//  - Rectangles (square and oblong pillars, boxes, crates). A laser sees
//    at most two faces of a box; shadow edges close the rest 0.6 m deep, so
//    a probe behind a turned pillar feels a solid far behind its back. Two
//    fitted faces of one cluster meeting at a right angle (within
//    rect_max_angle) at a convex corner seen from outside (each face's
//    normal points away from the other face), each no longer than
//    rect_max_side, close into a rectangle; so do one face and a strongly
//    seen perpendicular end (rect_min_end_points over rect_min_end_length,
//    too few for a line fit of its own: a face seen at a grazing angle). The two faces are made exactly
//    perpendicular (their directions averaged, weighted by points x length^2)
//    and placed by least squares. Each side's extent: at least what was seen
//    of it, and never into space a recent laser scan saw free (a beam whose
//    free part, up to its return less the ray-clearing tolerance, crosses
//    the face's line beyond the seen end or passes through the rectangle).
//    A face's true end lies between its last return and where the first
//    beam that passed it crosses its line, an interval as long as the beams'
//    spacing along the face (long for a face seen at a grazing angle). The
//    side known more tightly ends midway; the other is assumed as long (a
//    square) when that lies in its own interval, else ends midway too. A
//    side nothing bounds (its end occluded or behind dropouts) is assumed
//    square to the longer seen side, still clipped by free space. An oblong
//    seen nearly face-on on its long side therefore gets a square's depth
//    until a scan from elsewhere bounds it; an end seen on fewer than
//    rect_min_end_points is not closed. Accepted only when the outline explains min_inlier_ratio of the
//    cluster with RMS under max_rms. The outline replaces the raw segments
//    and shadow edges on it, and is kept while the points stay on it, as a
//    circle is. A wall (longer than rect_max_side), a room's concave corner
//    seen from inside, and a thin board (no end to see) are not rectangles.
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
  // Rectangles (see above). Sides up to 1 m: pillars, boxes, crates; walls are longer.
  bool rectangles = true;
  double rect_max_angle = 0.15;     // rad (8.6 deg) from a right angle between the two faces
  double rect_max_side = 1.0;       // m, longest seen face (and assumed side) of a rectangle
  double rect_min_side = 0.04;      // m, shortest seen face that counts
  double rect_corner_gap = 0.06;    // m: a face's near end at most this far from the corner
  // A perpendicular end seen on at least this many points (the corner among
  // them: two more returns, as a face seen at a grazing angle gives) ...
  std::size_t rect_min_end_points = 3;
  double rect_min_end_length = 0.05;    // m, ... spread over at least this length
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

// corner + s u + t v, s in [0, size_u], t in [0, size_v] (u, v orthonormal):
// the corner is the one between the two seen faces, the faces run along +u
// and +v from it, the solid lies on their inner sides.
struct FittedRectangle {
  Eigen::Vector2d corner = Eigen::Vector2d::Zero();  // W [m]
  Eigen::Vector2d u = Eigen::Vector2d::UnitX();
  Eigen::Vector2d v = Eigen::Vector2d::UnitY();
  double size_u = 0.0, size_v = 0.0;  // m, the sides drawn
  double seen_u = 0.0, seen_v = 0.0;  // m, the extent of the points on each face
  bool bounded_u = false, bounded_v = false;  // a side's end bounded by free space (else assumed)
  bool from_end = false;               // one face and a perpendicular end (not two fitted faces)
  double rms = 0.0;        // m, of the inliers' distances to the outline
  std::uint32_t inliers = 0;
  std::uint32_t points = 0;  // of its cluster
  Eigen::Vector2d centre() const { return corner + 0.5 * size_u * u + 0.5 * size_v * v; }
};

struct ShapeModel {
  std::vector<FittedCircle> circles;
  std::vector<FittedRectangle> rectangles;
  std::vector<FittedLine> lines;
  std::size_t bridges = 0;        // gaps between wall pieces closed
  std::size_t kept = 0;           // circles of the previous completion kept (temporal coherence)
  std::size_t kept_rectangles = 0;  // rectangles of the previous completion kept
  std::size_t raw_replaced = 0;   // raw segments (and shadow edges) a primitive stands for, left out
  std::size_t clusters = 0;       // clusters considered
  // What the snapshot is built from: the map's segments minus raw_replaced,
  // plus the circles' and rectangles' outlines and the walls' lines (pieces marked fitted).
  std::vector<Segment2> segments;
};

// Fits and renders; out is overwritten (its capacity reused). Temporal
// coherence: a circle (or rectangle) in out from the previous call is kept while it still
// explains its object's points (at least 3, min_inlier_ratio of the cluster,
// seen from outside) even where this map alone would not pass the tests, so
// the outline does not flicker with lost or noisy scans; pass a fresh
// ShapeModel to fit from scratch. A disabled or invalid ShapeParams leaves
// the map's segments as they are.
void complete_shapes(const ShapeParams& p, const MapParams& mp, const LocalMap& map, ShapeModel& out);

}  // namespace hemm::mapping
