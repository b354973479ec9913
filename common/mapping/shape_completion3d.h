#pragma once
// Shape completion of the live voxmap in 3D (issue 24): primitives fitted
// with PCL's sample consensus to the surface the depth camera saw, so an
// object's unseen sides get their likely shape; the 3D sibling of
// shape_completion.h (2D circles and lines). Pure: cell surface points and
// normals in, primitives out; the live voxmap's snapshot (model thread)
// calls it and writes the primitives' closed-form signed distances into the
// voxmap near them (live_voxmap.h). No PCL in this header.
//
// Input: the rendered cells of the live voxmap: each cell's surface point
// (the hit-weighted centroid of its neighbourhood), its PCL normal oriented
// toward where it was seen from, and the unit direction toward the sensor.
//
//  1. The support: the largest plane (SACMODEL_NORMAL_PLANE) when it holds
//     at least min_support_share of the cells (the table); its cells are not
//     fitted further, and boxes standing on it are extended down to it.
//  2. Objects: the other cells clustered by proximity (cluster_tolerance),
//     their normals estimated afresh over fit_normal_radius for the curved
//     primitives.
//  3. Per object, in this order, the first that is accepted:
//     - a sphere (SACMODEL_SPHERE): inliers explain min_inlier_ratio of the
//       object, RMS under max_rms, radius in range, seen from outside, and
//       the inliers' normals spread over min_sphere_spread (a cap, not a
//       flat patch);
//     - a cylinder (SACMODEL_CYLINDER with normals): the side's inliers and
//       the cells on a cap explain min_inlier_ratio of the object, RMS under
//       max_rms, radius in range, seen from outside, an arc of at least
//       min_arc about the axis (a flat face has none); an axis within
//       right_angle_tolerance of the support's normal (standing) or of its
//       plane (lying) is taken as exactly so, and the centre and radius
//       refitted on it (least squares circle); its height spans the
//       inliers along the axis (down to the support when it stands on it),
//       capped where its top is;
//     - a box: two or three planes (SACMODEL_NORMAL_PLANE, fitted in turn)
//       at right angles within right_angle_tolerance, each behind the
//       other's plane (a convex corner, not a box's face and the table),
//       together explaining min_inlier_ratio of the object; or one face
//       parallel to the support at least min_box_height above it (a slab
//       seen from above: the book). Axes from the faces' normals (a slab's
//       in-plane axes from the smallest rectangle round its top), extents
//       from the cells on the faces' planes: beyond what was seen only down
//       to the support, and on a side with no face of its own by half the
//       camera's sample spacing there (the last sample before an edge lies
//       on average half a spacing short of it: 1 cm on a top seen at 30
//       degrees from 0.8 m), at most max_edge_extension.
//     Every primitive is refused when more than max_free_share of the
//     volume it adds was seen free by the camera (seen_free below): the
//     fitted shape may close what was not seen, never what was seen empty;
//     and when more than max_inside_share of seen cells lie inside it
//     beyond inlier_distance: it may not stand in front of a seen surface.
//  4. Temporal coherence: a primitive of the previous completion is kept
//     for an object whose cells still lie on it (min_inlier_ratio of them
//     within inlier_distance) when this map alone does not pass, and when
//     it passes this map's free-space and inside tests (the camera may have
//     seen since that it was wrong).
//  A primitive stands for its object's and the support's cells within 2
//  inlier_distance of its surface or inside it (Shape3dModel::owner).
//
// Thresholds and why are at the parameters. RANSAC is seeded (PCL's fixed
// seed): one map gives one model.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hemm::mapping {

struct Shape3dParams {
  bool enabled = true;
  // Cell surface points of 1 cm cells scatter ~2 mm about the true surface
  // (the centroid of a 5 cm neighbourhood, camera noise 2.5 mm at 1 m); 6 mm
  // is about 3 sigma.
  double inlier_distance = 0.006;
  double normal_angle = 0.45;        // rad (26 deg): inliers' normals agree with the model's (5 cm PCL normals)
  double max_rms = 0.004;            // m: a fit worse than this is not rendered
  double cluster_tolerance = 0.025;  // m: cells closer than this are one object (2.5 cells)
  // Spheres and cylinders take normals estimated afresh (PCL) over this
  // radius: the live voxmap's 5 cm (two image rows on a grazed table) blurs
  // a 4 cm mug's side; 2.5 cm holds ~20 cells on a surface. Boxes keep the
  // given ones: a top seen at 11 degrees has rows 2.8 cm apart, and one row
  // leaves the normal anywhere across it. 0 keeps the given normals.
  double fit_normal_radius = 0.025;
  std::size_t min_points = 12;       // an object with fewer cells keeps its raw voxels
  std::size_t max_objects = 32;      // the largest objects first
  int max_iterations = 400;          // RANSAC iterations per model
  double min_support_share = 0.25;   // the support plane holds at least this share of the cells
  // Share of an object's cells the primitive must explain: below, the
  // object is something else (or several things) and keeps its raw voxels.
  double min_inlier_ratio = 0.8;
  double min_radius = 0.015, max_radius = 0.25;  // m, cylinders and spheres (cans and mugs to bins)
  double min_arc = 1.2;              // rad (70 deg) about a cylinder's axis its inliers must span
  double min_sphere_spread = 0.6;    // rad (34 deg): the largest angle of an inlier normal from their mean
  double right_angle_tolerance = 0.17;  // rad (10 deg)
  std::size_t min_face_points = 6;   // cells on a box face
  double min_box_height = 0.012;     // m: a slab thinner than a voxel and a bit is a plane, not a box
  double max_box_size = 0.6;         // m: larger faces are walls or tables, not boxes
  double support_snap = 0.04;        // m: a box whose bottom is this near the support stands on it
  double max_edge_extension = 0.015; // m: the most an unseen edge is moved out for the sample spacing
  double max_free_share = 0.05;      // of the added volume's samples that may have been seen free
  // Seen surface cells (any object's or the support's) more than
  // inlier_distance inside a primitive, as a share of its object's cells:
  // beyond this the primitive covers what the camera saw as a surface
  // (its surface stands proud of the seen one) and is refused.
  double max_inside_share = 0.05;
  double free_sample_step = 0.01;    // m between the samples of that test
};

// Empty when usable; otherwise what is wrong.
std::string validate(const Shape3dParams& p);

struct CellSample3 {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();     // surface point, W
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();    // unit normal toward the sensor
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ(); // unit direction toward the sensor
  // The camera's pixel pitch at the cell's range (range / focal length, m):
  // samples on the surface lie this over sqrt(1 - (u . view)^2) apart along
  // a direction u in it. 0: unknown.
  double range_pitch = 0.0;
};

enum class PrimitiveKind : std::uint8_t { kBox, kCylinder, kSphere };

struct Primitive3 {
  PrimitiveKind kind = PrimitiveKind::kBox;
  // Frame P in W: box centre and axes; cylinder centre, z along the axis; sphere centre.
  Eigen::Isometry3d T_W_P = Eigen::Isometry3d::Identity();
  // Box: half extents; cylinder: (radius, radius, half height); sphere: radius thrice.
  Eigen::Vector3d half = Eigen::Vector3d::Zero();
  double rms = 0.0;          // m, of its inliers' distances
  std::uint32_t inliers = 0;
  std::uint32_t points = 0;  // of its object
  int faces = 0;             // box: planes it was built from (1: a slab on the support)
  double arc = 0.0;          // cylinder: rad its inliers span about the axis
  bool kept = false;         // from the previous completion (temporal coherence)
};

// Closed-form signed distance of the primitive's solid at x (W), positive
// outside, and its unit gradient; *kink true where the gradient jumps within
// `kink_band` of x (inside near a box's or a cylinder's medial surface, at
// an axis or a centre): interpolate without gradients there.
double primitive_sdf(const Primitive3& q, const Eigen::Vector3d& x_W, Eigen::Vector3d* grad_W, bool* kink,
                     double kink_band);
// The axis-aligned box (W) around the primitive.
Eigen::AlignedBox3d primitive_bounds(const Primitive3& q);

struct Shape3dModel {
  std::vector<Primitive3> primitives;
  // Per input cell: the primitive it lies on or inside (index into
  // primitives), or -1. Those cells' raw voxels are left out: the primitive
  // stands for them.
  std::vector<std::int32_t> owner;
  bool have_support = false;
  Eigen::Vector4d support = Eigen::Vector4d::Zero();  // plane n.x + d = 0, n toward the sensor
  std::size_t support_cells = 0;
  std::size_t objects = 0;     // objects considered
  std::size_t kept = 0;        // primitives held from the previous completion
  std::size_t refused_free = 0;  // fits refused because the camera saw their volume free
  std::size_t refused_inside = 0;  // fits refused for standing in front of seen cells
};

// x (W) was seen as free space by the camera (a ray passed through it).
using SeenFree = std::function<bool(const Eigen::Vector3d&)>;

// Fits; out is overwritten, except that its primitives are the previous
// completion for temporal coherence (pass a fresh model to fit from
// scratch). A disabled or invalid Shape3dParams gives no primitives.
// seen_free may be empty (nothing known to be free).
void complete_shapes_3d(const Shape3dParams& p, const std::vector<CellSample3>& cells, const SeenFree& seen_free,
                        Shape3dModel& out);

// The shape log (issue 24: why a primitive was accepted). One CSV line per
// accepted primitive: kind, centre (W), the frame's z and x axes, half
// extents, rms, inliers, object points, faces, arc, kept. No newline.
std::string primitive_csv_header();
std::string primitive_csv_row(const Primitive3& q);
// A completion's input cells as little-endian float32, 10 per cell (p, n,
// view, range_pitch), so a logged rebuild can be fitted again offline.
std::string cells_to_bytes(const std::vector<CellSample3>& cells);
// Empty when the bytes are not a whole number of finite cells with unit
// normals and views; *out is untouched then.
std::string cells_from_bytes(const std::string& bytes, std::vector<CellSample3>* out);

}  // namespace hemm::mapping
