// The PointShell of the Voxmap-PointShell algorithm: points on the surface of
// a moving object (surface-voxel centres projected onto the nearest triangle),
// each with an inward unit normal and an area weight, organised in a tree of
// bounding spheres for culling.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/triangle_mesh.h"

namespace hemm::vps {

struct SphereNode {
  Eigen::Vector3d centre;
  double radius;
  std::int32_t first;  // range of points [first, first + count)
  std::int32_t count;
  std::int32_t left;   // child node indices, -1 for a leaf
  std::int32_t right;
};

struct PointShell {
  double voxel_size = 0.0;
  std::vector<Eigen::Vector3d> points;   // object frame P
  std::vector<Eigen::Vector3d> normals;  // unit, pointing into the object
  std::vector<double> weights;           // surface area each point stands for (m^2), or 1
  std::vector<SphereNode> nodes;         // nodes[0] is the root
  Eigen::Vector3d reference_point = Eigen::Vector3d::Zero();  // torques are about this point (the centre of mass)
  double total_weight = 0.0;
  int depth = 0;
  std::size_t memory_bytes() const {
    return points.size() * (2 * sizeof(Eigen::Vector3d) + sizeof(double)) + nodes.size() * sizeof(SphereNode);
  }
};

struct PointShellParams {
  double voxel_size = 0.002;   // pointshell resolution (one point per surface voxel)
  bool area_weights = true;    // weight = mesh area inside the point's voxel; else 1 per point (paper's F_k = p n)
  int leaf_size = 8;           // points per leaf of the sphere tree
  mesh::MeshLimits limits;
};

// Builds the pointshell of `mesh` (validated inside). The normals are the
// nearest triangle's inward normal, cross-checked against the gradient of the
// object's own voxmap field (flipped where they disagree, closed meshes only).
// `reference_point` is where torques are taken (use the centre of mass).
std::optional<VpsError> build_pointshell(const mesh::TriangleMesh& mesh, const PointShellParams& params,
                                         const Eigen::Vector3d& reference_point, PointShell* out);

// Rebuilds the sphere tree of `ps` (points are reordered leaf by leaf).
void build_sphere_tree(PointShell* ps, int leaf_size);

}  // namespace hemm::vps
