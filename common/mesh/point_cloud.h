// Point clouds (range data) through PCL: read a PCD file into plain points,
// validated, as input for vps::build_voxmap_from_points (surface voxels only,
// no inside/outside). PCL stays inside point_cloud.cpp.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "common/mesh/triangle_mesh.h"

namespace hemm::mesh {

struct PointCloudLimits {
  std::size_t max_points = 50'000'000;
  double max_extent = 1000.0;  // metres
};

// Loads x, y, z of a PCD file (ASCII or binary). NaN points (PCL's "no
// return") are dropped and counted in `*dropped`; an infinite coordinate, an
// empty cloud or an absurd extent is an error. On error `*out` is untouched.
std::optional<MeshError> load_point_cloud_pcd(const std::string& path, const PointCloudLimits& limits,
                                              std::vector<Eigen::Vector3d>* out, std::size_t* dropped);

}  // namespace hemm::mesh
