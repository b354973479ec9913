// The Voxmap of the Voxmap-PointShell algorithm: a voxelized volume of a
// static (or voxmap-side) object with signed distance layers, stored sparsely.
//
// Layout: a two-level grid. The top level is a dense array over 8^3-voxel
// blocks (5 bytes per block: block index + coarse distance); only blocks near
// the surface (within the distance layers) hold voxel data (sdf, layer, flags:
// 3 KB). Blocks deep inside a closed object are marked "uniform inside"
// without voxel data; everything else is "far outside".
//
// Per voxel: the layer (0 surface, +k outside, -k inside, k = Chebyshev voxel
// distance to the nearest surface voxel, +-127 beyond the stored layers) and
// the signed distance from the voxel centre to the mesh (exact for surface
// voxels, closest-triangle propagation for the layers; positive outside).
// Open or non-manifold meshes and point clouds get an unsigned field
// (documented fallback: no inside, every surface voxel is a thin shell).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/mesh/triangle_mesh.h"

namespace hemm::vps {

inline constexpr int kBlockShift = 3;
inline constexpr int kBlockDim = 1 << kBlockShift;  // 8 voxels per block edge
inline constexpr int kBlockVoxels = kBlockDim * kBlockDim * kBlockDim;
inline constexpr std::int8_t kLayerFarOutside = 127;
inline constexpr std::int8_t kLayerFarInside = -127;
inline constexpr std::int32_t kBlockEmpty = -1;          // far outside
inline constexpr std::int32_t kBlockUniformInside = -2;  // deep inside a closed object
inline constexpr std::uint8_t kFlagThin = 1;  // surface voxel with no inside voxel within 2 voxels (thin wall / open mesh)
inline constexpr std::int64_t kMaxBlocks = 64ll * 1024 * 1024;
inline constexpr double kMaxVoxelizationWork = 2e9;  // triangle-voxel pairs tested by the SAT pass

struct VpsError {
  std::string message;
};

struct VoxelBlock {
  std::array<float, kBlockVoxels> sdf;         // metres, positive outside
  std::array<std::int8_t, kBlockVoxels> layer;
  std::array<std::uint8_t, kBlockVoxels> flags;
};

struct VoxmapParams {
  double voxel_size = 0.004;                     // metres
  std::optional<Eigen::AlignedBox3d> roi;        // region of interest in the mesh frame
  int layers_out = 3;                            // outward distance layers kept (1..100)
  int layers_in = 3;                             // inward distance layers kept (1..100)
  bool force_unsigned = false;                   // treat even a closed mesh as a shell
  mesh::MeshLimits limits;
};

struct Voxmap {
  double voxel_size = 0.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // corner of voxel (0,0,0)
  Eigen::Vector3i block_dims = Eigen::Vector3i::Zero();
  bool signed_field = false;
  int layers_out = 0;
  int layers_in = 0;
  std::vector<std::int32_t> top;     // per block: block index, kBlockEmpty or kBlockUniformInside
  std::vector<std::uint8_t> coarse;  // per block: Chebyshev block distance to a block with surface voxels (<=255)
  std::vector<VoxelBlock> blocks;
  std::size_t surface_voxels = 0;

  Eigen::Vector3i dims() const { return block_dims * kBlockDim; }
  std::size_t memory_bytes() const {
    return top.size() * sizeof(std::int32_t) + coarse.size() + blocks.size() * sizeof(VoxelBlock);
  }
  float far_outside_sdf() const { return static_cast<float>((layers_out + 1) * voxel_size); }
  float far_inside_sdf() const { return static_cast<float>(-(layers_in + 1) * voxel_size); }
};

// What a build saw, for reports and for the pointshell generator.
struct VoxmapBuildInfo {
  mesh::MeshReport mesh_report;
  std::size_t triangles = 0;
  std::size_t surface_voxels = 0;
  std::size_t allocated_blocks = 0;
  std::size_t uniform_inside_blocks = 0;
  std::size_t components = 0;  // connected free-space regions (signed field only)
  // Surface voxels (global voxel index) and the nearest triangle of each
  // (indices into the validated mesh `mesh`).
  std::vector<Eigen::Vector3i> surface_index;
  std::vector<std::int32_t> surface_triangle;
  mesh::TriangleMesh mesh;  // the validated mesh the voxmap was built from
};

// Builds the voxmap of `mesh` (validated first; see validate_mesh). On error
// `*out` is untouched. `info` may be null.
std::optional<VpsError> build_voxmap(const mesh::TriangleMesh& mesh, const VoxmapParams& params, Voxmap* out,
                                     VoxmapBuildInfo* info);

// Voxmap of a point cloud (range data): surface voxels where points fall,
// unsigned distance to the nearest point in the outward layers, no inside.
std::optional<VpsError> build_voxmap_from_points(const std::vector<Eigen::Vector3d>& points,
                                                 const VoxmapParams& params, Voxmap* out);

// ---- queries (inline: they run per point per tick) ---------------------------

struct VoxelSample {
  float sdf;
  std::int8_t layer;
  std::uint8_t flags;
};

// Every query below is total: a non-finite or huge coordinate is never cast
// to int (undefined behaviour); it lands at +-kGridFar voxels, outside every
// grid (grids have at most 2^23 voxels per axis), so it samples as far outside,
// has a large clearance and never makes contact.
inline constexpr int kGridFar = 1 << 28;

// floor(g) as an int, with NaN mapped to -kGridFar and the result clamped to
// [-kGridFar, kGridFar].
inline int grid_floor(double g) {
  if (!(g > -static_cast<double>(kGridFar))) return -kGridFar;  // also NaN
  if (g >= static_cast<double>(kGridFar)) return kGridFar;
  return static_cast<int>(std::floor(g));
}

inline Eigen::Vector3i voxel_of(const Voxmap& vm, const Eigen::Vector3d& x_V) {
  const Eigen::Vector3d g = (x_V - vm.origin) / vm.voxel_size;
  return Eigen::Vector3i(grid_floor(g.x()), grid_floor(g.y()), grid_floor(g.z()));
}

inline Eigen::Vector3d voxel_centre(const Voxmap& vm, const Eigen::Vector3i& v) {
  return vm.origin + (v.cast<double>() + Eigen::Vector3d::Constant(0.5)) * vm.voxel_size;
}

inline bool in_grid(const Voxmap& vm, const Eigen::Vector3i& v) {
  const Eigen::Vector3i d = vm.dims();
  return v.x() >= 0 && v.y() >= 0 && v.z() >= 0 && v.x() < d.x() && v.y() < d.y() && v.z() < d.z();
}

inline std::size_t block_linear(const Voxmap& vm, const Eigen::Vector3i& b) {
  return (static_cast<std::size_t>(b.z()) * vm.block_dims.y() + b.y()) * vm.block_dims.x() + b.x();
}

inline int voxel_in_block(const Eigen::Vector3i& v) {
  return ((v.z() & (kBlockDim - 1)) << (2 * kBlockShift)) | ((v.y() & (kBlockDim - 1)) << kBlockShift) |
         (v.x() & (kBlockDim - 1));
}

inline VoxelSample sample_voxel(const Voxmap& vm, const Eigen::Vector3i& v) {
  if (!in_grid(vm, v)) return {vm.far_outside_sdf(), kLayerFarOutside, 0};
  const Eigen::Vector3i b(v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift);
  const std::int32_t bi = vm.top[block_linear(vm, b)];
  if (bi == kBlockEmpty) return {vm.far_outside_sdf(), kLayerFarOutside, 0};
  if (bi == kBlockUniformInside) return {vm.far_inside_sdf(), kLayerFarInside, 0};
  const VoxelBlock& blk = vm.blocks[static_cast<std::size_t>(bi)];
  const int i = voxel_in_block(v);
  return {blk.sdf[i], blk.layer[i], blk.flags[i]};
}

// Lower bound on the Chebyshev voxel distance from voxel v to the nearest
// surface voxel (0 for surface or inside voxels). Used for culling.
inline int clearance_voxels(const Voxmap& vm, const Eigen::Vector3i& v) {
  const Eigen::Vector3i d = vm.dims();
  if (!in_grid(vm, v)) {
    int out = 0;
    for (int k = 0; k < 3; ++k) out = std::max(out, std::max(-v[k], v[k] - (d[k] - 1)));
    // The grid is padded by at least layers_out + 1 voxels around the surface.
    return out + vm.layers_out + 1;
  }
  const Eigen::Vector3i b(v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift);
  const std::size_t bl = block_linear(vm, b);
  const std::int32_t bi = vm.top[bl];
  if (bi == kBlockUniformInside) return 0;
  const int coarse = vm.coarse[bl];
  const int from_coarse = coarse >= 1 ? (coarse - 1) * kBlockDim + 1 : 0;
  if (bi == kBlockEmpty) return std::max(vm.layers_out + 1, from_coarse);
  const int layer = vm.blocks[static_cast<std::size_t>(bi)].layer[voxel_in_block(v)];
  if (layer <= 0) return 0;
  if (layer == kLayerFarOutside) return std::max(vm.layers_out + 1, from_coarse);
  return layer;
}

// Signed distance at x by trilinear interpolation of the voxel-centre values
// (continuous across voxel boundaries).
inline double sdf_trilinear(const Voxmap& vm, const Eigen::Vector3d& x_V) {
  const Eigen::Vector3d g = (x_V - vm.origin) / vm.voxel_size - Eigen::Vector3d::Constant(0.5);
  // Outside the grid (or not finite) the field is the far-outside value.
  if (!(g.array() > -1.0).all() || !(g.array() < vm.dims().cast<double>().array()).all())
    return vm.far_outside_sdf();
  const Eigen::Vector3i i0(grid_floor(g.x()), grid_floor(g.y()), grid_floor(g.z()));
  const Eigen::Vector3d t = g - i0.cast<double>();
  double s[8];
  for (int c = 0; c < 8; ++c) {
    s[c] = sample_voxel(vm, i0 + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1)).sdf;
  }
  const double x00 = s[0] + t.x() * (s[1] - s[0]), x10 = s[2] + t.x() * (s[3] - s[2]);
  const double x01 = s[4] + t.x() * (s[5] - s[4]), x11 = s[6] + t.x() * (s[7] - s[6]);
  const double y0 = x00 + t.y() * (x10 - x00), y1 = x01 + t.y() * (x11 - x01);
  return y0 + t.z() * (y1 - y0);
}

// Gradient of the trilinear field by central differences (half a voxel).
inline Eigen::Vector3d sdf_gradient(const Voxmap& vm, const Eigen::Vector3d& x_V) {
  const double h = 0.5 * vm.voxel_size;
  Eigen::Vector3d g;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e[k] = h;
    g[k] = (sdf_trilinear(vm, x_V + e) - sdf_trilinear(vm, x_V - e)) / (2 * h);
  }
  return g;
}

}  // namespace hemm::vps
