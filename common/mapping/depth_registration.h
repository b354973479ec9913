// Registration-corrected fusion of depth frames (issue 24): before a frame
// is integrated into the live voxmap, its points (placed with the frame's
// T_W_S, the pose at acquisition from odometry and the head's encoders) are
// registered against the voxmap's current surface by PCL's point-to-plane
// ICP (IterativeClosestPointWithNormals: the target's normals are the
// snapshot's distance gradients), and T_W_S is corrected when the fit is
// good. Pure computation (PCL private to the .cpp); the operator's voxmap
// thread calls it (operator/model/model_thread.cpp).
//
// A correction is accepted only when all of these hold (DepthRegistrationParams):
//   * enough points: the frame has min_points after down-sampling (leaf_m)
//     within the surface's bounds (the voxmap's region of interest) and the
//     surface min_target_points;
//   * they fix every direction (min_constraint; else kDegenerate);
//   * the fit is good: after ICP at least min_overlap of the frame's points
//     have a surface point within max_correspondence_m, and their point-to-
//     plane RMS is at most max_rmse_m and at least min_improvement_m below
//     what it was (from a pose that already fits, ICP drifts along the
//     scene's weakly constrained directions -- sliding on the table --
//     toward the map's own bias, half a voxel, for a fraction of a mm of
//     RMS: such a "correction" is refused, kNoGain);
//   * the step is bounded: the correction moves the sensor by at most
//     max_translation_m and turns it by at most max_rotation_rad (encoder
//     bias and odometry drift between frames are millimetres and tenths of
//     a degree; a larger "correction" is a wrong match, e.g. sliding along
//     a plane, and is refused).
// Otherwise the frame is integrated with its own pose (rejected, counted by
// reason). Defaults: 1 cm voxels seen at 0.5-1.5 m by the SIMULATED camera
// (range noise 2.5 mm at 1 m): an RMS of 4 mm is noise plus the voxmap's
// patch error; 3 cm of correspondence catches 1-2 degree errors at 1 m.
//
// Frames arrive as chunks of rows (depth_stream.h); DepthFrameRegistration
// holds a cloud's chunks until it is complete (its last row arrived) or a
// newer cloud begins, registers the whole frame once, and releases its
// chunks with the corrected pose: at most one frame of delay, only for a
// frame whose last chunk was lost.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/mapping/depth_stream.h"

namespace hemm::vps {
struct Voxmap;
}

namespace hemm::mapping {

struct DepthRegistrationParams {
  double leaf_m = 0.01;                 // frame points down-sampled to one per leaf (PCL VoxelGrid)
  double max_correspondence_m = 0.03;
  double refine_correspondence_m = 0.01;  // the second pass (one voxel)
  // A frame is registered only if its correspondences fix every direction
  // of a correction to at least this share of the best-fixed one (the .cpp:
  // constraint_spectrum). A table scene seen from the robot's side has two
  // directions at 0.3-0.7 % (sliding along the table, turning about its
  // normal) that still fix most of a degree-sized error; a single plane has
  // three at 0.
  double min_constraint = 0.001;
  int max_iterations = 30;
  double max_rmse_m = 0.004;
  double min_improvement_m = 0.001;
  double min_overlap = 0.5;
  std::size_t min_points = 200;
  std::size_t min_target_points = 500;
  double max_translation_m = 0.03;
  double max_rotation_rad = 0.035;      // 2 degrees
};

// A reason if unusable.
std::optional<std::string> check(const DepthRegistrationParams& p);

// The surface the frames are registered against, frame W.
struct RegistrationSurface {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;  // unit, outward
};
// The surface voxels (layer 0) of a signed snapshot: each centre moved onto
// its patch (centre - sdf * gradient), its gradient as the normal.
void surface_from_voxmap(const vps::Voxmap& vm, RegistrationSurface* out);

enum class RegistrationVerdict { kAccepted, kTooFewPoints, kNoSurface, kDegenerate, kPoorFit, kNoGain, kStepTooLarge };
const char* to_string(RegistrationVerdict v);

struct RegistrationResult {
  RegistrationVerdict verdict = RegistrationVerdict::kNoSurface;
  // Left-multiplied onto the frame's pose: T_W_S' = correction * T_W_S
  // (identity unless accepted).
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d candidate = Eigen::Isometry3d::Identity();  // what ICP found, accepted or not
  std::size_t points = 0;      // frame points after down-sampling
  double rmse_before = 0.0;    // point-to-plane RMS (m) of the matched points, before and after
  double rmse_after = 0.0;
  double overlap_before = 0.0, overlap_after = 0.0;  // share of points matched
  double weakest_constraint = 0.0;  // the least fixed direction, relative to the best (see min_constraint)
};

// Registers points_W (the frame's points placed with its T_W_S, whose
// optical centre is sensor_W) against surface.
RegistrationResult register_points(const std::vector<Eigen::Vector3f>& points_W, const Eigen::Vector3d& sensor_W,
                                   const RegistrationSurface& surface, const DepthRegistrationParams& p);

// The valid pixels of a chunk as points in W, placed with T_W_S (appended).
void chunk_points_W(const DepthChunkData& c, const Eigen::Isometry3d& T_W_S, std::vector<Eigen::Vector3f>* out);

struct DepthRegistrationStats {
  std::uint64_t frames = 0;          // frames released
  std::uint64_t accepted = 0;
  std::uint64_t too_few_points = 0, no_surface = 0, degenerate = 0, poor_fit = 0, no_gain = 0, step_too_large = 0;
  double last_rmse_before_m = 0.0, last_rmse_after_m = 0.0;
  double last_step_m = 0.0, max_step_m = 0.0;  // accepted corrections' sensor displacement
  // SIMULATION ONLY (frames with T_W_S_truth): the sensor pose's error
  // against the truth before and after (accepted frames; rejected ones keep
  // their error), summed for means.
  std::uint64_t truth_frames = 0;
  double sum_error_before_m = 0.0, sum_error_after_m = 0.0;
  double sum_error_before_rad = 0.0, sum_error_after_rad = 0.0;
  // ... and the mean displacement of the frame's points from where the true
  // pose puts them (what the voxmap sees of the error), summed over frames.
  double sum_point_error_before_m = 0.0, sum_point_error_after_m = 0.0;
};

class DepthFrameRegistration {
 public:
  explicit DepthFrameRegistration(const DepthRegistrationParams& p) : p_(p) {}
  // An accepted chunk. Chunks ready to integrate are appended to *ready:
  // the previous cloud's (registered) when this one is of a newer cloud,
  // this cloud's when its last row came. surface may be null or empty (no
  // surface yet: frames pass with their own pose).
  void add(const DepthChunkData& c, const RegistrationSurface* surface, std::vector<DepthChunkData>* ready);
  // Releases what is held (registered), e.g. before a restart.
  void flush(const RegistrationSurface* surface, std::vector<DepthChunkData>* ready);
  void clear() { held_.clear(); }
  const DepthRegistrationStats& stats() const { return stats_; }
  const DepthRegistrationParams& params() const { return p_; }

 private:
  void release(const RegistrationSurface* surface, std::vector<DepthChunkData>* ready);
  DepthRegistrationParams p_;
  std::vector<DepthChunkData> held_;  // chunks of one cloud
  int rows_held_ = 0;
  DepthRegistrationStats stats_;
  std::vector<Eigen::Vector3f> points_S_, points_;  // reused
};

// The pose error of T against the truth: translation (m) and rotation angle (rad).
Eigen::Vector2d pose_error(const Eigen::Isometry3d& T, const Eigen::Isometry3d& truth);

}  // namespace hemm::mapping
