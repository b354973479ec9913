// The Voxmap of the Voxmap-PointShell algorithm: a voxelized volume of a
// static (or voxmap-side) object with signed distance layers, stored sparsely.
//
// Layout: a two-level grid. The top level is a dense array over 8^3-voxel
// blocks (5 bytes per block: block index + coarse distance); only blocks near
// the surface (within the distance layers) hold voxel data (12 bytes a voxel,
// 6 KB a block). Blocks deep inside a closed object are marked "uniform
// inside" without voxel data; everything else is "far outside".
//
// Per voxel (Voxel): the layer (0 surface, +k outside, -k inside, k =
// Chebyshev voxel distance to the nearest surface voxel, +-127 beyond the
// stored layers), the signed distance from the voxel centre to the mesh and
// its gradient there (exact for every stored voxel: distance to the nearest
// triangle, found for the surface by the SAT pass and for the layers by
// closest-triangle propagation; positive outside), and flags.
//
// The field between centres (sdf_hermite) is the mean of the trilinear
// interpolation of the values and the trilinear blend of the corners'
// first-order Taylor predictions: the two have opposite second-order errors,
// so the mean is exact for quadratics (a cubic-Hermite-like interpolant) and
// does not carry the trilinear interpolation's bias on curved surfaces. Where
// the gradient jumps (medial axis, sharp concave edges: kFlagNoGradient) it
// falls back to trilinear.
//
// Thin walls (walls thinner than about two voxels, and every surface of an
// open or non-manifold mesh) cannot be sampled at voxel centres: they carry a
// sheet: the plane of the wall's + face through the voxel (normal and signed
// distance of the centre) and the wall's thickness (0 for an open sheet),
// propagated into the outward layers around it (kFlagSheet). A contact query
// measures a point's depth from the face on the side the point came from
// (temporal coherence, see contact.h), so thin walls are neither tunnelled
// nor felt from the wrong side. Point clouds have no normals: their surface
// voxels are thin without a sheet (the layered fallback, kFlagThin only).
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
inline constexpr std::uint8_t kFlagThin = 1;        // surface voxel of a thin wall or an open surface
inline constexpr std::uint8_t kFlagSheet = 2;       // carries a sheet plane (see SheetBlock)
inline constexpr std::uint8_t kFlagNoGradient = 4;  // gradient unreliable here: interpolate trilinearly
// The surface this voxel's distance comes from was not observed: a fitted
// primitive's unseen side or the boundary of space no ray has seen (live
// voxmap, common/mapping/live_voxmap.h). Solid for safety; the contact
// reports the force it gives apart and may soften it (ContactParams).
inline constexpr std::uint8_t kFlagInferred = 8;
inline constexpr float kGradScale = 32767.0f;        // unit gradient components stored as int16
inline constexpr std::int64_t kMaxBlocks = 64ll * 1024 * 1024;
inline constexpr double kMaxVoxelizationWork = 2e9;  // triangle-voxel pairs tested by the SAT pass

struct VpsError {
  std::string message;
};

struct Voxel {
  float sdf;                // metres at the voxel centre, positive outside
  std::int16_t grad[3];     // unit gradient of the distance at the centre, times kGradScale
  std::int8_t layer;
  std::uint8_t flags;
};
static_assert(sizeof(Voxel) == 12);

struct VoxelBlock {
  std::array<Voxel, kBlockVoxels> v;
};

// Sheet planes of the kFlagSheet voxels of one block: the sheet's + face is
// the plane through the voxel with normal n (the voxel's grad) at signed
// distance phi from the centre (phi > 0: the centre is outside the + face);
// the - face lies `thickness` behind it.
struct SheetBlock {
  std::array<float, kBlockVoxels> phi;
  std::array<float, kBlockVoxels> thickness;
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
  std::vector<std::uint8_t> coarse;  // per block: lower bound on the Chebyshev voxel distance of its voxels to a surface voxel (<=255)
  std::vector<VoxelBlock> blocks;
  std::vector<std::int32_t> sheet_of_block;  // per allocated block: index into sheets, or -1
  std::vector<SheetBlock> sheets;
  std::size_t surface_voxels = 0;
  std::size_t sheet_voxels = 0;

  Eigen::Vector3i dims() const { return block_dims * kBlockDim; }
  std::size_t memory_bytes() const {
    return top.size() * sizeof(std::int32_t) + coarse.size() + blocks.size() * sizeof(VoxelBlock) +
           sheet_of_block.size() * sizeof(std::int32_t) + sheets.size() * sizeof(SheetBlock);
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

// The voxels outside every stored block.
inline Voxel far_outside_voxel(const Voxmap& vm) {
  return {vm.far_outside_sdf(), {0, 0, 0}, kLayerFarOutside, kFlagNoGradient};
}
inline Voxel far_inside_voxel(const Voxmap& vm) {
  return {vm.far_inside_sdf(), {0, 0, 0}, kLayerFarInside, kFlagNoGradient};
}

inline Voxel sample_voxel(const Voxmap& vm, const Eigen::Vector3i& v) {
  if (!in_grid(vm, v)) return far_outside_voxel(vm);
  const Eigen::Vector3i b(v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift);
  const std::int32_t bi = vm.top[block_linear(vm, b)];
  if (bi == kBlockEmpty) return far_outside_voxel(vm);
  if (bi == kBlockUniformInside) return far_inside_voxel(vm);
  return vm.blocks[static_cast<std::size_t>(bi)].v[static_cast<std::size_t>(voxel_in_block(v))];
}

inline Eigen::Vector3d voxel_gradient(const Voxel& vx) {
  return Eigen::Vector3d(vx.grad[0], vx.grad[1], vx.grad[2]) / static_cast<double>(kGradScale);
}

// Sheet plane of voxel v (kFlagSheet voxels only; false otherwise).
inline bool sheet_at(const Voxmap& vm, const Eigen::Vector3i& v, float* phi, float* thickness) {
  if (!in_grid(vm, v)) return false;
  const Eigen::Vector3i b(v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift);
  const std::int32_t bi = vm.top[block_linear(vm, b)];
  if (bi < 0) return false;
  const std::int32_t si = vm.sheet_of_block[static_cast<std::size_t>(bi)];
  const auto i = static_cast<std::size_t>(voxel_in_block(v));
  if (si < 0 || (vm.blocks[static_cast<std::size_t>(bi)].v[i].flags & kFlagSheet) == 0) return false;
  *phi = vm.sheets[static_cast<std::size_t>(si)].phi[i];
  *thickness = vm.sheets[static_cast<std::size_t>(si)].thickness[i];
  return true;
}

// Lower bound on the Chebyshev voxel distance from a voxel in the grid to
// the nearest surface voxel, from its block (linear index bl, top entry bi)
// and its index in the block.
inline int clearance_in_grid(const Voxmap& vm, std::size_t bl, std::int32_t bi, int local) {
  if (bi == kBlockUniformInside) return 0;
  const int from_coarse = vm.coarse[bl];
  if (bi == kBlockEmpty) return std::max(vm.layers_out + 1, from_coarse);
  const int layer = vm.blocks[static_cast<std::size_t>(bi)].v[static_cast<std::size_t>(local)].layer;
  if (layer <= 0) return 0;
  if (layer == kLayerFarOutside) return std::max(vm.layers_out + 1, from_coarse);
  return layer;
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
  return clearance_in_grid(vm, bl, vm.top[bl], voxel_in_block(v));
}

// The field between the eight voxel centres around a point: corner c (bit 0
// x, bit 1 y, bit 2 z) at offset o_c, t in [0,1]^3 the point's position in
// the cell (voxel units), s the voxel size. Trilinear: sum w_c d_c. Hermite
// (see above): sum w_c (d_c + s/2 g_c . (t - o_c)).
inline double cell_trilinear(const Voxel* const corner[8], const double t[3]) {
  const double x00 = corner[0]->sdf + t[0] * (corner[1]->sdf - corner[0]->sdf);
  const double x10 = corner[2]->sdf + t[0] * (corner[3]->sdf - corner[2]->sdf);
  const double x01 = corner[4]->sdf + t[0] * (corner[5]->sdf - corner[4]->sdf);
  const double x11 = corner[6]->sdf + t[0] * (corner[7]->sdf - corner[6]->sdf);
  const double y0 = x00 + t[1] * (x10 - x00), y1 = x01 + t[1] * (x11 - x01);
  return y0 + t[2] * (y1 - y0);
}

inline double cell_hermite(const Voxel* const corner[8], const double t[3], double s) {
  std::uint8_t any = 0;
  for (int c = 0; c < 8; ++c) any |= corner[c]->flags;
  if (any & kFlagNoGradient) return cell_trilinear(corner, t);
  // In float (values of a few voxels, relative precision 1e-7): the corners'
  // weights w_c and offsets t - o_c are t or -(1 - t) per axis.
  const float tx = static_cast<float>(t[0]), ty = static_cast<float>(t[1]), tz = static_cast<float>(t[2]);
  const float ux = 1.0f - tx, uy = 1.0f - ty, uz = 1.0f - tz;
  const float h = static_cast<float>(0.5 * s) / kGradScale;
  auto term = [&](const Voxel& v, float dx, float dy, float dz) {
    return v.sdf + h * (static_cast<float>(v.grad[0]) * dx + static_cast<float>(v.grad[1]) * dy +
                        static_cast<float>(v.grad[2]) * dz);
  };
  const float x00 = ux * term(*corner[0], tx, ty, tz) + tx * term(*corner[1], -ux, ty, tz);
  const float x10 = ux * term(*corner[2], tx, -uy, tz) + tx * term(*corner[3], -ux, -uy, tz);
  const float x01 = ux * term(*corner[4], tx, ty, -uz) + tx * term(*corner[5], -ux, ty, -uz);
  const float x11 = ux * term(*corner[6], tx, -uy, -uz) + tx * term(*corner[7], -ux, -uy, -uz);
  return static_cast<double>(uz * (uy * x00 + ty * x10) + tz * (uy * x01 + ty * x11));
}

// Gathers the eight corners around x (kept in `store`) and the cell position t.
// False when x is outside the grid or not finite: the field is far outside.
inline bool gather_cell(const Voxmap& vm, const Eigen::Vector3d& x_V, Voxel store[8], const Voxel* corner[8],
                        double t[3]) {
  const Eigen::Vector3d g = (x_V - vm.origin) / vm.voxel_size - Eigen::Vector3d::Constant(0.5);
  if (!(g.array() > -1.0).all() || !(g.array() < vm.dims().cast<double>().array()).all()) return false;
  const Eigen::Vector3i i0(grid_floor(g.x()), grid_floor(g.y()), grid_floor(g.z()));
  for (int k = 0; k < 3; ++k) t[k] = g[k] - i0[k];
  for (int c = 0; c < 8; ++c) {
    store[c] = sample_voxel(vm, i0 + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1));
    corner[c] = &store[c];
  }
  return true;
}

// Signed distance at x by trilinear interpolation of the voxel-centre values.
inline double sdf_trilinear(const Voxmap& vm, const Eigen::Vector3d& x_V) {
  Voxel store[8];
  const Voxel* corner[8];
  double t[3];
  if (!gather_cell(vm, x_V, store, corner, t)) return vm.far_outside_sdf();
  return cell_trilinear(corner, t);
}

// Signed distance at x by the Hermite-like interpolant (the contact field).
inline double sdf_hermite(const Voxmap& vm, const Eigen::Vector3d& x_V) {
  Voxel store[8];
  const Voxel* corner[8];
  double t[3];
  if (!gather_cell(vm, x_V, store, corner, t)) return vm.far_outside_sdf();
  return cell_hermite(corner, t, vm.voxel_size);
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

// Distance layers needed so the stored field reaches a penetration depth:
// a point `depth` inside interpolates between centres down to layer
// ceil(depth / s) + 1 (the far value beyond the layers would cap it).
inline int layers_for_depth(double depth, double voxel_size) {
  if (!(depth > 0) || !(voxel_size > 0)) return 1;
  return static_cast<int>(std::min(100.0, std::ceil(depth / voxel_size) + 1.0));
}

}  // namespace hemm::vps
