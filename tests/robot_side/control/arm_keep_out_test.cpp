// The keep-out check of arm targets (robot_side/control/arm_keep_out.h)
// against closed forms.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "common/math/geometry3.h"
#include "robot_side/control/arm_keep_out.h"

namespace hr = hemm::robot;

TEST(ArmKeepOut, RefusesPosesIntoTheFloorTheBaseAndSeenGeometry) {
  const hr::ArmKeepOut k;
  const Eigen::Vector3d shoulder(0.02, 0.0, 0.36);
  // Reaching forward and level, over free floor: allowed.
  const std::vector<Eigen::Vector3d> level = {shoulder, {0.08, 0, 0.36}, {0.24, 0, 0.36}, {0.38, 0, 0.36},
                                              {0.52, 0, 0.36}};
  EXPECT_EQ(hr::check_arm_chain(k, level, {}), hr::ArmRefusal::kNone);
  // Down into the floor in front of the robot.
  const std::vector<Eigen::Vector3d> floor = {shoulder, {0.08, 0, 0.36}, {0.24, 0, 0.20}, {0.38, 0, 0.06},
                                              {0.45, 0, 0.01}};
  EXPECT_EQ(hr::check_arm_chain(k, floor, {}), hr::ArmRefusal::kFloor);
  // Folded back down onto the chassis top (z 0.26).
  const std::vector<Eigen::Vector3d> base = {shoulder, {-0.04, 0, 0.36}, {-0.15, 0, 0.30}, {-0.20, 0, 0.27}};
  EXPECT_EQ(hr::check_arm_chain(k, base, {}), hr::ArmRefusal::kBase);
  // Onto the laser head (x 0.14..0.22, z up to 0.32).
  const std::vector<Eigen::Vector3d> head = {shoulder, {0.08, 0, 0.36}, {0.18, 0, 0.33}};
  EXPECT_EQ(hr::check_arm_chain(k, head, {}), hr::ArmRefusal::kBase);
  // A wall the laser saw 0.45 m ahead: the level reach to 0.52 m goes through it.
  const std::vector<Eigen::Vector2d> wall = {{0.45, -0.1}, {0.45, 0.0}, {0.45, 0.1}};
  hr::SeenScene seen;
  seen.columns_R = wall;
  EXPECT_EQ(hr::check_arm_chain(k, level, seen), hr::ArmRefusal::kScene);
  // ... a wall 0.6 m ahead leaves it free (tip 0.08 m short).
  const std::vector<Eigen::Vector2d> far_wall = {{0.60, -0.1}, {0.60, 0.0}, {0.60, 0.1}};
  seen.columns_R = far_wall;
  EXPECT_EQ(hr::check_arm_chain(k, level, seen), hr::ArmRefusal::kNone);
  EXPECT_STRNE(hr::to_string(hr::ArmRefusal::kScene), hr::to_string(hr::ArmRefusal::kFloor));
}

// ---------------------------------------------------------------- 3D keep-out (issue 13)

TEST(ArmKeepOut3d, SegmentSegmentDistanceMatchesClosedForms) {
  const Eigen::Vector3d o(0, 0, 0), x1(1, 0, 0);
  // Skew, perpendicular, crossing over the middle at height h.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {0.5, -1, 0.3}, {0.5, 1, 0.3}).distance, 0.3, 1e-12);
  // Parallel, offset sideways by 0.2 and overlapping.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {0.5, 0.2, 0}, {1.5, 0.2, 0}).distance, 0.2, 1e-12);
  // Collinear, apart by a gap of 0.25 past the end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {1.25, 0, 0}, {2, 0, 0}).distance, 0.25, 1e-12);
  // A point (degenerate segment) beyond an end: distance to the end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {2, 0, 0}, {2, 0, 0}).distance, 1.0, 1e-12);
  EXPECT_NEAR(hemm::math::segment_segment({3, 4, 0}, {3, 4, 0}, o, o).distance, 5.0, 1e-12);
  // Skew lines whose closest points lie past both ends: end to end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {2, 1, 0}, {3, 1, 0}).distance, std::sqrt(2.0), 1e-12);
}

namespace {
// A plane z = z0 of seen points in P on a 1 cm grid (x 0..0.8, y -0.3..0.3),
// so that the point straight below any point of a chain along x at y = 0 is
// in the set: the chain's distance to the set is its height above z0.
std::vector<Eigen::Vector3f> plane_points(double z0, const Eigen::Isometry3d& T_P_R) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i <= 80; ++i)
    for (int j = -30; j <= 30; ++j) pts.push_back((T_P_R * Eigen::Vector3d(0.01 * i, 0.01 * j, z0)).cast<float>());
  return pts;
}
}  // namespace

TEST(ArmKeepOut3d, AChainAboveSeenPointsIsRefusedExactlyInsideTheReach) {
  const hr::ArmKeepOut k;
  const double reach = k.link_radius + k.clearance + k.seen_pad;  // 0.04 m
  // The robot stands anywhere in P (the points are in P, the chain in R).
  Eigen::Isometry3d T_P_R = Eigen::Isometry3d::Identity();
  T_P_R.translation() << 2.0, -1.0, 0.0;
  T_P_R.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double z0 = 0.46;  // a seat
  const std::vector<Eigen::Vector3f> pts = plane_points(z0, T_P_R);
  // The shoulder high above, the forearm and tool level over the plane at h.
  auto chain_at = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, 0.80}, {0.08, 0, 0.80}, {0.20, 0, 0.80}, {0.30, 0, h}, {0.44, 0, h}};
  };
  hr::SeenScene seen;
  seen.points_P = pts;
  seen.T_P_R = T_P_R;
  // float points: within 1e-5 m of the threshold either way.
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach + 1e-5), seen), hr::ArmRefusal::kNone);
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach - 1e-5), seen), hr::ArmRefusal::kScene);
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + 0.2), seen), hr::ArmRefusal::kNone);
  // The same chain with the robot elsewhere in P: the plane is not under it.
  hr::SeenScene moved = seen;
  moved.T_P_R.translation().x() += 3.0;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach - 1e-3), moved), hr::ArmRefusal::kNone);
  // Floor and base come first, as before.
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.01), seen), hr::ArmRefusal::kFloor);
}

TEST(ArmKeepOut3d, CappedColumnsLetTheArmReachOverWhatTheLaserSaw) {
  const hr::ArmKeepOut k;
  const double r = k.link_radius + k.clearance;
  // The front of a seat the laser saw 0.32 m ahead; the tool reaches level
  // over it at height h to 0.50 m.
  const std::vector<Eigen::Vector2d> front = {{0.32, -0.1}, {0.32, 0.0}, {0.32, 0.1}};
  auto chain_at = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, 0.36}, {0.08, 0, 0.50}, {0.22, 0, 0.70}, {0.36, 0, h}, {0.50, 0, h}};
  };
  const double top = 0.40;
  hr::SeenScene infinite;
  infinite.columns_R = front;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), infinite), hr::ArmRefusal::kScene);
  const std::vector<std::uint8_t> capped = {1, 1, 1};
  hr::SeenScene with_caps = infinite;
  with_caps.column_capped = capped;
  with_caps.column_top_z = top;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), with_caps), hr::ArmRefusal::kNone);
  // Exactly at the threshold: a level chain at top + r over the capped
  // columns is allowed, just below it refused.
  auto level = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, h}, {0.10, 0, h}, {0.30, 0, h}, {0.50, 0, h}};
  };
  EXPECT_EQ(hr::check_arm_chain(k, level(top + r + 1e-9), with_caps), hr::ArmRefusal::kNone);
  EXPECT_EQ(hr::check_arm_chain(k, level(top + r - 1e-9), with_caps), hr::ArmRefusal::kScene);
  // Only the flagged columns are capped.
  const std::vector<std::uint8_t> one = {1, 0, 1};  // the one under the chain (y = 0) not capped
  hr::SeenScene partly = with_caps;
  partly.column_capped = one;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), partly), hr::ArmRefusal::kScene);
}

TEST(ArmKeepOut3d, ACameraLookingStraightDownSeesItsConeOnly) {
  // Camera 1.1 m above R's origin looking straight down (optical z = -z_R).
  const hemm::mapping::DepthIntrinsics K =
      hemm::mapping::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  Eigen::Isometry3d T_R_S = Eigen::Isometry3d::Identity();
  T_R_S.linear().col(0) = Eigen::Vector3d(0, -1, 0);  // x_S right (image)
  T_R_S.linear().col(2) = Eigen::Vector3d(0, 0, -1);  // z_S down
  T_R_S.linear().col(1) = T_R_S.linear().col(2).cross(T_R_S.linear().col(0));
  T_R_S.translation() << 0, 0, 1.1;
  const Eigen::Isometry3d T_S_R = T_R_S.inverse();
  // Half the horizontal field (across y_R) at depth d is d tan(30 deg).
  const double d = 0.6, half = d * std::tan(30.0 * std::numbers::pi / 180.0);
  EXPECT_TRUE(hr::in_camera_view(K, T_S_R, {0.0, half - 1e-6, 1.1 - d}));
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, half + 1e-6, 1.1 - d}));
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, 0.0, 1.1 - 0.15}));  // nearer than range_min
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, 0.0, 1.2}));         // behind
  // A column 0.1 m to the side seen from 0.4 to 0.8 m: both ends in the cone.
  EXPECT_TRUE(hr::column_seen_from_above(K, T_S_R, {0.0, 0.1}, 0.4, 0.8));
  // 0.4 m to the side: the top end (0.3 m below the camera) is outside.
  EXPECT_FALSE(hr::column_seen_from_above(K, T_S_R, {0.0, 0.4}, 0.4, 0.8));
}
