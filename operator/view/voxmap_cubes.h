// A voxmap as the live views draw it: its surface voxels (layer 0), merged
// into coarser cubes until a geom budget holds them. Shared by the device
// view (the VPS scene's static voxmap) and the station view (the live voxmap
// built from the robot's depth clouds). View thread only: it allocates.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace hemm::vps {
struct Voxmap;
}

namespace hemm::op {

// Cubes of edge 2 * half, centres in the voxmap's frame; inferred[i]: most
// of cube i's surface voxels are vps::kFlagInferred (a surface nobody saw,
// drawn in another colour).
struct VoxmapCubes {
  std::vector<Eigen::Vector3d> centres;
  std::vector<std::uint8_t> inferred;
  double half = 0.0;
  std::size_t surface_voxels = 0;  // before merging
};

// The surface voxels of `vm`, merged into cubes of 2^k voxels (the smallest
// k) until at most `budget` remain.
VoxmapCubes surface_cubes(const vps::Voxmap& vm, std::size_t budget);

}  // namespace hemm::op
