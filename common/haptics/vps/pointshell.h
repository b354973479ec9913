// The PointShell of the Voxmap-PointShell algorithm: points on the surface of
// a moving object (surface-voxel centres projected onto the nearest triangle),
// each with an inward unit normal and an area weight.
//
// Multi-resolution and nested (for the time-critical mode, after Barbic and
// James): level L (the finest) holds every point; level l < L keeps one point
// per cell of 2^(L-l) voxels and normal group, chosen among the points of
// level l+1, so every level is a subset of the next. A point's weight at
// level l is the area of all finest points its level-l cell group stands
// for. Point data is float structure-of-arrays (cache- and SIMD-friendly) in
// the leaf order of one tree of bounding spheres over all points.
//
//  * Full evaluation: that tree, every point with its finest weight.
//  * Time-critical evaluation: level 0, then level 1, ..., each level's
//    force from the points of all levels up to it with that level's weights,
//    until a work budget is spent; the deepest complete level is the answer.
//    Each level has its own tree over the points that first appear at it,
//    whose leaves index the point arrays (level_index).
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/triangle_mesh.h"

namespace hemm::vps {

inline constexpr int kMaxShellLevels = 6;

struct SphereNode {
  float cx, cy, cz, radius;  // object frame
  std::int32_t first;        // range of points [first, first + count)
  std::int32_t count;
  std::int32_t left;         // child node indices, -1 for a leaf
  std::int32_t right;
};
static_assert(sizeof(SphereNode) == 32);

struct ShellLevel {
  std::int32_t first = 0;       // its new points: level_index[first, first + count)
  std::int32_t count = 0;
  std::int32_t root = -1;       // their sphere tree (index into level_nodes), -1 if none
  std::int32_t node_count = 0;  // level_nodes [root, root + node_count)
  double spacing = 0.0;         // cell size of this level (m)
  double total_weight = 0.0;    // sum of the level's weights over all points up to it
};

struct PointShell {
  double voxel_size = 0.0;  // finest spacing
  Eigen::Vector3d reference_point = Eigen::Vector3d::Zero();  // torques are about this point (the centre of mass)
  double total_weight = 0.0;  // finest level
  int levels = 0;
  std::array<ShellLevel, kMaxShellLevels> level{};
  // Per point, object frame P (float: object extents are far below where
  // float spacing matters; the pose is applied in double).
  std::vector<float> px, py, pz;
  std::vector<float> nx, ny, nz;  // unit, pointing into the object
  std::vector<float> weight;      // finest-level weight (m^2, or 1 per point)
  // weight at each level: level_weight[i * kMaxShellLevels + l] (0 below the
  // point's own level).
  std::vector<float> level_weight;
  std::vector<std::int32_t> point_level;  // level where each point first appears
  std::vector<SphereNode> nodes;          // the tree over all points; nodes[0] is its root
  std::vector<std::int32_t> parent;       // per node, -1 for the root
  std::vector<std::int32_t> level_index;  // per level, its new points (indices into the point arrays)
  std::vector<SphereNode> level_nodes;    // the levels' trees (ranges index level_index)
  std::vector<std::int32_t> level_parent;

  std::size_t size() const { return px.size(); }
  Eigen::Vector3d point(std::size_t i) const { return {px[i], py[i], pz[i]}; }
  Eigen::Vector3d normal(std::size_t i) const { return {nx[i], ny[i], nz[i]}; }
  std::size_t memory_bytes() const {
    return size() * (7 * sizeof(float) + kMaxShellLevels * sizeof(float) + 2 * sizeof(std::int32_t)) +
           (nodes.size() + level_nodes.size()) * (sizeof(SphereNode) + sizeof(std::int32_t));
  }
};

struct PointShellParams {
  double voxel_size = 0.002;   // pointshell resolution (one point per surface voxel and normal group)
  bool area_weights = true;    // weight = mesh area inside the point's voxel; else 1 per point (paper's F_k = p n)
  int leaf_size = 8;           // points per leaf of the sphere trees
  int levels = 4;              // resolution levels (1..kMaxShellLevels); fewer if the object is small
  mesh::MeshLimits limits;
};

// Builds the pointshell of `mesh` (validated inside). The normals are the
// nearest triangle's inward normal, cross-checked against the gradient of the
// object's own voxmap field (flipped where they disagree, closed meshes only).
// `reference_point` is where torques are taken (use the centre of mass).
std::optional<VpsError> build_pointshell(const mesh::TriangleMesh& mesh, const PointShellParams& params,
                                         const Eigen::Vector3d& reference_point, PointShell* out);

// Builds a pointshell from finest-level points (object frame), inward unit
// normals and weights: levels, weights, trees. Fails on non-finite input,
// non-unit normals, negative weights or mismatched sizes.
std::optional<VpsError> build_pointshell_from_points(const std::vector<Eigen::Vector3d>& points,
                                                     const std::vector<Eigen::Vector3d>& normals,
                                                     const std::vector<double>& weights, double voxel_size,
                                                     int levels, int leaf_size,
                                                     const Eigen::Vector3d& reference_point, PointShell* out);

}  // namespace hemm::vps
