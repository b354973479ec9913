// A depth image from a pinhole depth camera (time-of-flight or structured
// light), the organised cloud both stations share: the robot's SIMULATED
// camera produces it, the stream carries it in chunks of rows, the operator's
// live voxmap unprojects it. Pure value types and geometry.
//
// Sensor frame S is the optical frame: z along the optical axis, x right, y
// down the image. Pixel (u, v) (column, row) looks along the ray through
// ((u + 0.5 - cx) / fx, (v + 0.5 - cy) / fy, 1). depth is z in S (what depth
// cameras report), not the range along the ray.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

namespace hemm::mapping {

struct DepthIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0;  // focal lengths, pixels
  double cx = 0.0, cy = 0.0;  // principal point, pixels (image corner = 0)
  double range_min = 0.0;     // metres along the ray: nearer returns are not reported
  double range_max = 0.0;     // metres along the ray: the sensor sees nothing beyond
};

// Per pixel. kDropout says nothing (absorbed, saturated, mixed pixel, below
// range_min); kNoReturn says the ray met nothing up to range_max (free space
// along the whole ray), as the 2D scans' no_return does.
enum class DepthStatus : std::uint8_t { kValid = 0, kDropout = 1, kNoReturn = 2 };

struct DepthImage {
  std::int64_t stamp_ns = 0;  // steady clock of the station that holds it, at acquisition
  std::uint32_t cloud_id = 0;
  DepthIntrinsics K;
  Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();        // best estimate (odometry) at acquisition
  Eigen::Isometry3d T_W_S_truth = Eigen::Isometry3d::Identity();  // SIMULATION ONLY, for evaluation
  std::vector<float> depth;                // metres (z in S), row-major v * width + u; 0 unless kValid
  std::vector<DepthStatus> status;         // same layout
};

// Ray of pixel (u, v) in S with z = 1 (multiply by depth for the point).
inline Eigen::Vector3d pixel_ray_z1(const DepthIntrinsics& K, int u, int v) {
  return {(u + 0.5 - K.cx) / K.fx, (v + 0.5 - K.cy) / K.fy, 1.0};
}

// Intrinsics of a camera with square pixels and horizontal field of view
// hfov (rad), principal point at the image centre.
inline DepthIntrinsics intrinsics_from_hfov(int width, int height, double hfov, double range_min, double range_max) {
  DepthIntrinsics K;
  K.width = width;
  K.height = height;
  K.fx = K.fy = 0.5 * width / std::tan(0.5 * hfov);
  K.cx = 0.5 * width;
  K.cy = 0.5 * height;
  K.range_min = range_min;
  K.range_max = range_max;
  return K;
}

}  // namespace hemm::mapping
