// The robot station's store of seen voxels from its own depth camera (what
// the arm keep-out, arm_keep_out.h, checks 3D points against).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mapping/depth_image.h"

namespace hemm::robot {

// The robot's own sparse set of seen voxels, from its depth frames: each
// valid pixel's point (placed with the frame's odometry pose T_P_S) marks
// its voxel seen at the frame's time, the voxel keeping the newest frame's
// point (not its centre: no quantisation added). Bounded: only recent
// frames count (a voxel not seen for keep_ns is forgotten: odometry drifts
// and things move), at most max_voxels (the oldest go first), and only what
// the arm could touch: points within max_range of the sensor and above the
// floor band (the floor keep-out covers the floor itself). Voxels are not
// cleared by free space seen through them (a thing that moved away stays
// forbidden until keep_ns passes: conservative). Not thread-safe; the robot
// keeps it on its depth worker thread and publishes points() snapshots.
struct SeenVoxelParams {
  double voxel_size = 0.02;               // m: the depth samples' spacing at arm's reach (1.3-2.8 cm)
  std::int64_t keep_ns = 10'000'000'000;  // 10 s
  std::size_t max_voxels = 20'000;        // ~0.5 MB with the hash index
  double min_z = 0.03;                    // m in P: points below are floor
  double max_range = 2.5;                 // m from the sensor
};
std::optional<std::string> validate(const SeenVoxelParams& p);

class SeenVoxels {
 public:
  explicit SeenVoxels(const SeenVoxelParams& p = {});
  // Adds one frame (its stamp_ns and depth, placed with T_P_S); forgets
  // voxels older than stamp_ns - keep_ns. Returns the valid pixels used.
  std::size_t add_frame(const mapping::DepthImage& img, const Eigen::Isometry3d& T_P_S);
  std::size_t size() const { return voxels_.size(); }
  std::size_t memory_bytes() const;
  // The seen points (one per voxel), in P.
  void points(std::vector<Eigen::Vector3f>* out) const;
  const SeenVoxelParams& params() const { return p_; }

 private:
  struct Voxel {
    Eigen::Vector3f point;
    std::int64_t stamp_ns;
  };
  SeenVoxelParams p_;
  std::unordered_map<std::uint64_t, Voxel> voxels_;
  std::uint64_t key_of(const Eigen::Vector3d& p) const;
  void forget_before(std::int64_t t_ns);
};

}  // namespace hemm::robot
