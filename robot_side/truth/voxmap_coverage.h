#pragma once
// SIMULATION ONLY. How much of what the depth camera can see the live voxmap
// has modelled (issue 13: "how it falls as the robot sees more").
//
// The true visible surface: points sampled uniformly (a fixed-seed random
// sample, `density` points per square metre) on the faces of the scene's
// true meshes (robot::load_scene_meshes), kept when the camera can see them:
// inside its image and range limits, on a face turned toward it, and the
// first thing the ray from the camera meets (no true face nearer along it,
// within `tolerance`). Coverage: the fraction of those samples that lie
// within `reach` voxels (Chebyshev) of a surface voxel (layer 0) of the
// voxmap: for the live voxmap's snapshot, of a rendered cell.
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_image.h"
#include "common/mesh/triangle_mesh.h"

namespace hemm::robot {

struct VisibleSurfaceParams {
  double density = 40000.0;     // samples per m^2 (5 mm apart on average)
  double tolerance = 0.001;     // m along the ray: a face this near the sample does not hide it
  std::uint64_t seed = 1;
  Eigen::AlignedBox3d region = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1e9), Eigen::Vector3d::Constant(1e9));
};

// Samples of `meshes` (frame W) that the camera K at T_W_S sees, within params.region.
std::vector<Eigen::Vector3d> visible_surface_samples(const std::vector<const mesh::TriangleMesh*>& meshes,
                                                     const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_W_S,
                                                     const VisibleSurfaceParams& params);

// Samples of `meshes` (frame W) a camera whose optical centre is o_W could
// see in any direction (a pan-tilt head's reach: faces turned toward o_W,
// unoccluded, within the range limits), within params.region.
std::vector<Eigen::Vector3d> surface_samples_seen_from(const std::vector<const mesh::TriangleMesh*>& meshes,
                                                       const Eigen::Vector3d& o_W, double range_min, double range_max,
                                                       const VisibleSurfaceParams& params);

// Fraction of samples (frame of vm) within `reach` voxels of a surface voxel
// of vm; 0 for no samples.
double surface_coverage(const vps::Voxmap& vm, const std::vector<Eigen::Vector3d>& samples, int reach = 1);

}  // namespace hemm::robot
