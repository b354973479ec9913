// The surface voxels (layer 0) of a voxmap, visited in storage order (blocks
// z, y, x; voxels within a block z, y, x): the one loop the writers, the
// view and the depth registration share. Its own header so that voxmap.h,
// included nearly everywhere, does not grow for a few callers.
#pragma once

#include "common/haptics/vps/voxmap.h"

namespace hemm::vps {

// f(v, voxel) for every surface voxel, v its index in the voxmap's grid.
template <class F>
void for_each_surface_voxel(const Voxmap& vm, F&& f) {
  const Eigen::Vector3i bd = vm.block_dims;
  for (int bz = 0; bz < bd.z(); ++bz)
    for (int by = 0; by < bd.y(); ++by)
      for (int bx = 0; bx < bd.x(); ++bx) {
        const Eigen::Vector3i b(bx, by, bz);
        const std::int32_t bi = vm.top[block_linear(vm, b)];
        if (bi < 0) continue;  // empty or uniformly inside: no surface
        const VoxelBlock& blk = vm.blocks[static_cast<std::size_t>(bi)];
        for (int z = 0; z < kBlockDim; ++z)
          for (int y = 0; y < kBlockDim; ++y)
            for (int x = 0; x < kBlockDim; ++x) {
              const Eigen::Vector3i v = b * kBlockDim + Eigen::Vector3i(x, y, z);
              const Voxel& vx = blk.v[static_cast<std::size_t>(voxel_in_block(v))];
              if (vx.layer == 0) f(v, vx);
            }
      }
}

}  // namespace hemm::vps
