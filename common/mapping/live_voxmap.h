// A voxmap built live from depth clouds, in the world frame W: the third
// local model of the design (both papers together). Pure computation over
// explicit state; the operator's model thread owns one and publishes its
// snapshots to the servo thread like the 2D map.
//
// Per chunk: pixels -> points in W (each chunk's own sensor pose at
// acquisition), clipped to the region of interest; PCL voxel-grid
// down-sampling and statistical outlier removal; free space cleared along
// every ray (up to a margin before its hit, and along no-return rays to
// range_max); hits raise an occupancy log-odds and accumulate the cell's mean
// point and viewing direction. Only cells that were hit are stored (a hash
// map), so memory grows with the seen surface inside the region of interest,
// not with its volume.
//
// Snapshot: a signed vps::Voxmap (frame W) of the occupied cells: surface
// normals by PCL from the cells' mean points, oriented toward where they were
// seen from; every voxel within `layers` of a surface voxel gets the signed
// distance to the nearest cell's patch (a one-voxel disc in the local plane
// through its neighbourhood's centroid: exact for planes, so the continuous
// VPS contact renders a plane without voxel steps). Cells with too little
// support around them (stray returns) are not rendered. Space behind a
// seen surface is inside (unseen is not free) right behind a patch or in a
// patch's shadow (its line of sight toward where the patch was seen from
// crosses the patch's plane near it); behind a patch's plane but beyond its
// rim and beside every shadow
// (over a small top the camera saw edge-on, out of its image or in the row
// it dropped at the silhouette) it is outside. So is space a ray of one of
// the newest 3 frames passed through (to a return more than clear_margin
// beyond, or to range_max), whatever side of its nearest patch it lies on
// (near a convex edge whose top is seen edge-on that patch is often the
// front face's). Beyond the layers it is far outside, so the
// model is meant for penetrations below layers * voxel_size.
//
// Shape completion (params.shape_completion, shape_completion3d.h): at
// snapshot time boxes, cylinders and spheres are fitted to the rendered
// cells; the cells a primitive stands for are not rendered raw, and every
// voxel near it gets the union of the rest and the primitive's closed-form
// signed distance and gradient, flagged vps::kFlagInferred where the
// primitive's nearest surface point has no cell of its own within 1.5
// voxels (an unseen side). Primitives are kept across snapshots while their
// cells stay on them.
//
// Unknown is solid (params.unknown_solid): every ray also marks the voxels
// it passed through in a free-space record, one byte per voxel of the
// region of interest (a 0.6 m cube at 1 cm: 216 kB). A hit does not unmark
// its voxel: what is there now is a seen surface, and seen surfaces take
// precedence over the record anyway. In the snapshot, voxels whose value is not a seen surface within
// its rim nor a primitive (far outside, or the shadow rule's guess beyond a
// patch's rim) take the signed distance to the boundary between space rays
// passed through and space no ray has seen (inside: not seen), if it is
// nearer inside, flagged inferred. Only space the camera looked at (in the
// view of one of the newest 3 frames) and no ray reached is unknown in this
// sense: hidden behind a seen surface. Space out of view is no evidence
// either way and is not made solid (the mast camera's image ends below the
// height the tool comes down from: made solid, the tool met a ceiling there,
// 35 N force error RMS on the home table against 2.9 N). A measured or fitted surface is never
// replaced by that coarse boundary (it sits up to a voxel and the clear
// margin off: a centimetre is ~40 N at the tool's stiffness). Only inside
// the region of interest (outside it nothing is recorded) and only in the
// blocks the surfaces and primitives allocate.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "common/mapping/shape_completion3d.h"

namespace hemm::vps {
struct Voxmap;
}

namespace hemm::mapping {

struct DepthChunkData;

struct LiveVoxmapParams {
  double voxel_size = 0.01;  // m: the tool's 5 cm scale needs ~1 cm; finer costs memory as 1/s^2
  Eigen::AlignedBox3d roi = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -0.1), Eigen::Vector3d(1, 1, 1.5));  // W
  // Occupancy in log-odds: one hit makes a cell occupied, two misses clear
  // a single hit; the clamp at log_odds_max lets a well-seen surface that
  // is taken away become free after 4 misses (a third of a second at 15 Hz)
  // and be forgotten after 10.
  float log_odds_hit = 0.85f;
  float log_odds_miss = -0.4f;
  float log_odds_min = -2.0f;  // a cell below this is forgotten
  float log_odds_max = 2.0f;
  float occupied = 0.5f;
  double downsample_leaf = 0.005;  // m, PCL VoxelGrid leaf (<= voxel_size / 2 keeps the cell means)
  int outlier_neighbours = 8;      // PCL StatisticalOutlierRemoval mean_k (0 disables)
  double outlier_stddev = 2.5;     // ... its std-dev multiplier
  // Rays stop clearing this far before their hit: a grazing ray crosses the
  // surface's own voxels before it ends (one voxel plus the noise).
  double clear_margin = 0.015;
  // m, PCL normal estimation radius over cell means: it must span two image
  // rows where the probe explores (80 x 60 over 60 degrees: rows 1.3 cm apart
  // at 1 m facing the surface, 2.8 cm on a table top 0.9 m away seen at 24
  // degrees from a 1.1 m mast; the operator's probe_3d config sets 5 cm).
  double normal_radius = 0.025;
  int min_support = 4;             // occupied cells within normal_radius for a cell to be rendered
  // A cell whose normal makes an angle beyond acos(min_view_cosine) with the
  // direction it was seen from is not rendered (an edge-on normal: see the
  // snapshot). 0.1: 84 degrees, beyond any surface a depth camera measures.
  double min_view_cosine = 0.1;
  int layers = 4;                  // distance layers in the snapshot, each side
  std::size_t max_cells = 4'000'000;
  // Off here (the raw model's tests); on in the operator's probe_3d config.
  bool shape_completion = false;
  Shape3dParams shapes;
  bool unknown_solid = false;
};

struct LiveVoxmapStats {
  std::uint64_t chunks = 0;
  std::uint64_t points_in_roi = 0;     // valid pixels whose point lies in the ROI
  std::uint64_t points_kept = 0;       // after down-sampling and outlier removal
  std::uint64_t rays_cleared = 0;
  std::uint64_t voxels_cleared = 0;    // miss updates applied to stored cells
  std::uint64_t cells_forgotten = 0;
  std::uint64_t cells_refused = 0;     // hits dropped because max_cells was reached
};

// The newest snapshot's shape completion and unknown space. Times only with
// a clock given to snapshot().
struct LiveVoxmapSnapshotReport {
  std::size_t primitives = 0, boxes = 0, cylinders = 0, spheres = 0;
  std::size_t primitives_kept = 0, primitives_refused_free = 0;
  std::size_t cells_completed = 0;     // rendered cells a primitive stands for
  std::size_t voxels_primitive = 0, voxels_inferred = 0, voxels_unknown = 0;
  std::int64_t completion_ns = 0, unknown_ns = 0, snapshot_ns = 0;
};

class LiveVoxmap {
 public:
  // A reason if params are unusable (sizes, ROI, log-odds signs); nothing else.
  static std::optional<std::string> check(const LiveVoxmapParams& params);
  explicit LiveVoxmap(const LiveVoxmapParams& params);  // params must pass check()
  ~LiveVoxmap();
  LiveVoxmap(LiveVoxmap&&) noexcept;
  LiveVoxmap& operator=(LiveVoxmap&&) noexcept;

  // One validated chunk (decode_depth_chunk), placed by its own T_W_S.
  void integrate(const DepthChunkData& chunk);
  // Moves the region of interest; cells outside it are dropped.
  void set_roi(const Eigen::AlignedBox3d& roi_W);
  // The signed voxmap of the occupied cells (frame W). Fails if nothing is
  // occupied; *out is untouched then. now_ns (may be null): a clock for the
  // completion's and the unknown space's times in stats().
  std::optional<std::string> snapshot(vps::Voxmap* out, std::int64_t (*now_ns)() = nullptr) const;
  // The newest snapshot's shape completion (model thread; tests, view).
  const Shape3dModel& shapes() const;
  // The cells that completion was fitted to (empty with it off): the shape log's input.
  const std::vector<CellSample3>& shape_samples() const;
  // The free-space record's bytes (0 with unknown_solid off).
  std::size_t free_space_bytes() const;
  // Whether a ray passed through the voxel holding x (free-space record).
  bool recorded_free(const Eigen::Vector3d& x) const;

  std::size_t cells() const;
  std::size_t occupied_cells() const;
  std::size_t memory_bytes() const;  // cell storage, including the hash map's buckets and nodes
  const LiveVoxmapStats& stats() const;
  const LiveVoxmapSnapshotReport& snapshot_report() const;
  const LiveVoxmapParams& params() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hemm::mapping
