#include "operator/view/voxmap_cubes.h"

#include <map>
#include <tuple>

#include "common/haptics/vps/voxmap.h"
#include "common/haptics/vps/voxmap_surface.h"

namespace hemm::op {

VoxmapCubes surface_cubes(const vps::Voxmap& vm, std::size_t budget) {
  VoxmapCubes out;
  std::vector<Eigen::Vector3i> surface;
  std::vector<std::uint8_t> inferred;
  vps::for_each_surface_voxel(vm, [&](const Eigen::Vector3i& v, const vps::Voxel& vx) {
    surface.push_back(v);
    inferred.push_back((vx.flags & vps::kFlagInferred) != 0 ? 1 : 0);
  });
  out.surface_voxels = surface.size();
  if (surface.empty() || budget == 0) return out;
  // Merge into cells of 2^k voxels until they fit.
  for (int k = 0; k < 16; ++k) {
    // Per merged cell: its surface voxels and how many are inferred.
    std::map<std::tuple<int, int, int>, std::pair<int, int>> cells;
    for (std::size_t i = 0; i < surface.size(); ++i) {
      const Eigen::Vector3i& v = surface[i];
      auto& c = cells[{v.x() >> k, v.y() >> k, v.z() >> k}];
      ++c.first;
      c.second += inferred[i];
    }
    if (cells.size() > budget) continue;
    const double edge = vm.voxel_size * static_cast<double>(1 << k);
    out.half = 0.5 * edge;
    out.centres.reserve(cells.size());
    out.inferred.reserve(cells.size());
    for (const auto& [xyz, n] : cells) {
      const auto& [x, y, z] = xyz;
      out.centres.push_back(vm.origin + edge * (Eigen::Vector3d(x, y, z) + Eigen::Vector3d::Constant(0.5)));
      out.inferred.push_back(2 * n.second > n.first ? 1 : 0);
    }
    return out;
  }
  return out;
}

}  // namespace hemm::op
