// The store of seen voxels (robot_side/control/seen_voxels.h).
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/seen_voxels.h"

namespace hr = hemm::robot;

TEST(SeenVoxels, AFlatImageMarksOneVoxelPerCellOfThePlaneAndForgetsOldFrames) {
  // A camera 1 m above a floor-parallel plane at z = 0.5 (P), looking down:
  // every pixel's depth is 0.5 m.
  hemm::mapping::DepthImage img;
  img.K = hemm::mapping::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  img.depth.assign(80 * 60, 0.5f);
  img.status.assign(80 * 60, hemm::mapping::DepthStatus::kValid);
  img.status[0] = hemm::mapping::DepthStatus::kDropout;
  img.stamp_ns = 1'000'000'000;
  Eigen::Isometry3d T_P_S = Eigen::Isometry3d::Identity();
  T_P_S.linear().col(0) = Eigen::Vector3d(0, -1, 0);
  T_P_S.linear().col(2) = Eigen::Vector3d(0, 0, -1);
  T_P_S.linear().col(1) = T_P_S.linear().col(2).cross(T_P_S.linear().col(0));
  T_P_S.translation() << 0, 0, 1.0;
  hr::SeenVoxelParams p;
  p.voxel_size = 0.02;
  p.keep_ns = 500'000'000;
  hr::SeenVoxels sv(p);
  EXPECT_EQ(sv.add_frame(img, T_P_S), 80u * 60u - 1u);
  std::vector<Eigen::Vector3f> pts;
  sv.points(&pts);
  ASSERT_EQ(pts.size(), sv.size());
  // Every point is a pixel's point on the plane, and each 2 cm cell of the
  // imaged rectangle (0.577 x 0.433 m at 0.5 m) holds one.
  for (const Eigen::Vector3f& q : pts) EXPECT_NEAR(q.z(), 0.5f, 1e-5f);
  const double w = 2 * 0.5 * std::tan(30.0 * std::numbers::pi / 180.0), h = w * 60.0 / 80.0;
  EXPECT_NEAR(static_cast<double>(pts.size()), (w / 0.02 + 1) * (h / 0.02 + 1), 0.1 * (w / 0.02) * (h / 0.02));
  EXPECT_GT(sv.memory_bytes(), pts.size() * sizeof(Eigen::Vector3f));
  // A frame of nothing valid 0.4 s later keeps them; 0.6 s later forgets them.
  hemm::mapping::DepthImage none = img;
  none.status.assign(80 * 60, hemm::mapping::DepthStatus::kNoReturn);
  none.stamp_ns = img.stamp_ns + 400'000'000;
  EXPECT_EQ(sv.add_frame(none, T_P_S), 0u);
  EXPECT_EQ(sv.size(), pts.size());
  none.stamp_ns = img.stamp_ns + 600'000'000;
  sv.add_frame(none, T_P_S);
  EXPECT_EQ(sv.size(), 0u);
  // The floor band is left to the floor keep-out; the bound holds.
  Eigen::Isometry3d low = T_P_S;
  low.translation().z() = 0.52;  // plane at z = 0.02 < min_z
  EXPECT_EQ(sv.add_frame(img, low), 0u);
  hr::SeenVoxelParams small = p;
  small.max_voxels = 100;
  hr::SeenVoxels bounded(small);
  bounded.add_frame(img, T_P_S);
  EXPECT_EQ(bounded.size(), 100u);
  // A malformed image (sizes disagree) adds nothing.
  hemm::mapping::DepthImage bad = img;
  bad.depth.pop_back();
  hr::SeenVoxels fresh(p);
  EXPECT_EQ(fresh.add_frame(bad, T_P_S), 0u);
  EXPECT_EQ(fresh.size(), 0u);
  hr::SeenVoxelParams zero = p;
  zero.voxel_size = 0.0;
  EXPECT_THROW(hr::SeenVoxels{zero}, std::invalid_argument);
}
