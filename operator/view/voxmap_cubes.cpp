#include "operator/view/voxmap_cubes.h"

#include <set>
#include <tuple>

#include "common/haptics/vps/voxmap.h"

namespace hemm::op {

VoxmapCubes surface_cubes(const vps::Voxmap& vm, std::size_t budget) {
  VoxmapCubes out;
  std::vector<Eigen::Vector3i> surface;
  const Eigen::Vector3i bd = vm.block_dims;
  for (int bz = 0; bz < bd.z(); ++bz)
    for (int by = 0; by < bd.y(); ++by)
      for (int bx = 0; bx < bd.x(); ++bx) {
        const Eigen::Vector3i b(bx, by, bz);
        const std::int32_t bi = vm.top[vps::block_linear(vm, b)];
        if (bi < 0) continue;  // empty or uniformly inside: no surface
        const vps::VoxelBlock& blk = vm.blocks[static_cast<std::size_t>(bi)];
        for (int z = 0; z < vps::kBlockDim; ++z)
          for (int y = 0; y < vps::kBlockDim; ++y)
            for (int x = 0; x < vps::kBlockDim; ++x) {
              const Eigen::Vector3i v = b * vps::kBlockDim + Eigen::Vector3i(x, y, z);
              if (blk.v[static_cast<std::size_t>(vps::voxel_in_block(v))].layer == 0) surface.push_back(v);
            }
      }
  out.surface_voxels = surface.size();
  if (surface.empty() || budget == 0) return out;
  // Merge into cells of 2^k voxels until they fit.
  for (int k = 0; k < 16; ++k) {
    std::set<std::tuple<int, int, int>> cells;
    for (const Eigen::Vector3i& v : surface) cells.emplace(v.x() >> k, v.y() >> k, v.z() >> k);
    if (cells.size() > budget) continue;
    const double edge = vm.voxel_size * static_cast<double>(1 << k);
    out.half = 0.5 * edge;
    out.centres.reserve(cells.size());
    for (const auto& [x, y, z] : cells)
      out.centres.push_back(vm.origin + edge * (Eigen::Vector3d(x, y, z) + Eigen::Vector3d::Constant(0.5)));
    return out;
  }
  return out;
}

}  // namespace hemm::op
