#include "common/math/workspace_maps.h"

#include <gtest/gtest.h>
#include <numbers>

namespace hemm::math {
namespace {

const DeviceWorkspace kOmni{};  // 70 D x 160 W x 120 H mm

TEST(WorkspaceMaps, ExplorationScaleFollowsSensorRange) {
  // Half the Omni's 160 mm width spans the sensor's range.
  EXPECT_DOUBLE_EQ(horizontal_half_extent(kOmni), 0.08);
  EXPECT_DOUBLE_EQ(make_exploration_map(kOmni, 10.0).map.scale, 10.0 / 0.08);  // laser
  EXPECT_DOUBLE_EQ(make_exploration_map(kOmni, 5.0).map.scale, 5.0 / 0.08);    // sonar
  EXPECT_DOUBLE_EQ(make_exploration_map(kOmni, 0.5).map.scale, 0.5 / 0.08);    // arm reach
  // The stylus at the workspace's left edge reaches exactly the sensor range
  // to the robot's left, in R and (through the robot pose) in W.
  const ExplorationMap e = make_exploration_map(kOmni, 10.0);
  const Eigen::Vector3d left_edge_B(0.0, 0.08, 0.0);
  EXPECT_NEAR((exploration_point_R(e, left_edge_B) - Eigen::Vector3d(0, 10, 0)).norm(), 0.0, 1e-12);
  const Pose2 T_W_R{2.0, -1.0, std::numbers::pi / 2};  // robot facing +y in W
  // R's +y (left) is W's -x when the robot faces +y.
  EXPECT_NEAR((exploration_point_W(e, T_W_R, left_edge_B) - Eigen::Vector3d(2.0 - 10.0, -1.0, 0)).norm(), 0.0,
              1e-9);
  // Centre maps onto the robot; the inverse map returns the stylus.
  EXPECT_NEAR((exploration_point_W(e, T_W_R, kOmni.centre_B) - Eigen::Vector3d(2.0, -1.0, 0)).norm(), 0.0, 1e-12);
  const Eigen::Vector3d p_B(0.01, -0.02, 0.03);
  EXPECT_NEAR((unmap_point(e.map, map_point(e.map, p_B)) - p_B).norm(), 0.0, 1e-15);
  EXPECT_TRUE(validate(e.map).empty());
  ScaledMap bad = e.map;
  bad.scale = 0.0;
  EXPECT_FALSE(validate(bad).empty());
}

TEST(WorkspaceMaps, NavigationDeadBandAndSaturation) {
  NavigationMap n = make_navigation_map(kOmni, 2.0);
  ASSERT_TRUE(validate(n).empty());
  const double db = n.dead_band, sat = n.saturation;
  // Inside the dead band: nothing moves.
  EXPECT_EQ(navigation_command(n, {0.999 * db, -0.999 * db, 0.05}).v, 0.0);
  EXPECT_EQ(navigation_command(n, {0.999 * db, -0.999 * db, 0.05}).omega, 0.0);
  // Half way between dead band and saturation: half speed.
  const double mid = 0.5 * (db + sat);
  EXPECT_NEAR(navigation_command(n, {mid, 0, 0}).v, 0.5 * n.v_max, 1e-12);
  EXPECT_NEAR(navigation_command(n, {-mid, 0, 0}).v, -0.5 * n.v_max, 1e-12);
  EXPECT_NEAR(navigation_command(n, {0, mid, 0}).omega, 0.5 * n.omega_max, 1e-12);
  // Saturated: exactly the Pioneer's 0.7 m/s, whatever the overshoot.
  EXPECT_DOUBLE_EQ(navigation_command(n, {0.07, 0, 0}).v, 0.7);
  EXPECT_DOUBLE_EQ(navigation_command(n, {sat, 0, 0}).v, 0.7);
  EXPECT_DOUBLE_EQ(navigation_command(n, {-1.0, 0, 0}).v, -0.7);
  // Linear in between: a(u) = (|u| - db) / (sat - db).
  const double u = db + 0.3 * (sat - db);
  EXPECT_NEAR(dead_band_saturate(u, db, sat), 0.3, 1e-12);
  EXPECT_EQ(dead_band_saturate(std::nan(""), db, sat), 0.0);
}

TEST(WorkspaceMaps, WheelSpeedsDifferential) {
  NavigationMap n = make_navigation_map(kOmni, 2.0);
  n.track_width = 0.4;
  n.wheel_speed_max = 0.7;
  // left = v - w W/2, right = v + w W/2.
  WheelSpeeds w = wheel_speeds(n, {0.3, 1.0});
  EXPECT_DOUBLE_EQ(w.left, 0.3 - 0.2);
  EXPECT_DOUBLE_EQ(w.right, 0.3 + 0.2);
  w = wheel_speeds(n, {0.0, 1.0});  // turn in place
  EXPECT_DOUBLE_EQ(w.left, -0.2);
  EXPECT_DOUBLE_EQ(w.right, 0.2);
  // Saturation scales both wheels by one factor: the curvature is kept.
  w = wheel_speeds(n, {0.7, 1.4});  // raw: 0.42, 0.98
  EXPECT_NEAR(w.right, 0.7, 1e-12);
  EXPECT_NEAR(w.left, 0.42 * 0.7 / 0.98, 1e-12);
  EXPECT_NEAR(w.left / w.right, 0.42 / 0.98, 1e-12);
}

TEST(WorkspaceMaps, ManipulationScaledOffsetAndClamped) {
  const Eigen::Vector3d arm_base(0.1, 0.0, 0.3), centre(0.35, 0.0, 0.3);
  const ManipulationMap m = make_manipulation_map(kOmni, arm_base, centre, 0.5);
  EXPECT_DOUBLE_EQ(m.map.scale, 0.5 / 0.08);
  // Centre of the device -> centre of the arm's workspace, inside reach.
  ManipulationTarget t = manipulation_target(m, kOmni.centre_B);
  EXPECT_FALSE(t.clamped);
  EXPECT_NEAR((t.p_R - centre).norm(), 0.0, 1e-12);
  // 1 cm of stylus = 6.25 cm of target.
  t = manipulation_target(m, {0.0, 0.01, 0.0});
  EXPECT_NEAR((t.p_R - (centre + Eigen::Vector3d(0, 0.0625, 0))).norm(), 0.0, 1e-12);
  // Far forward: clamped onto the 0.5 m sphere around the arm base, same direction.
  t = manipulation_target(m, {0.06, 0.0, 0.0});  // raw x = 0.35 + 0.375 = 0.725 -> 0.625 from base
  EXPECT_TRUE(t.clamped);
  EXPECT_NEAR((t.p_R - arm_base).norm(), 0.5, 1e-12);
  EXPECT_NEAR((t.p_R - Eigen::Vector3d(0.6, 0.0, 0.3)).norm(), 0.0, 1e-12);
}

TEST(WorkspaceMaps, ReanchorKeepsSpringVectorAcrossSwitch) {
  // Exploration (laser) -> manipulation: the device-side spring vector
  // (proxy - point) / scale, and hence k times it, must not jump.
  const ExplorationMap e = make_exploration_map(kOmni, 10.0);
  const ManipulationMap m = make_manipulation_map(kOmni, {0.1, 0, 0.3}, {0.35, 0, 0.3}, 0.5);
  const Pose2 T_W_R{1.0, 2.0, 0.7};
  const Eigen::Vector3d p_B(0.02, -0.01, 0.005);
  const Eigen::Vector3d device_W = exploration_point_W(e, T_W_R, p_B);
  const Eigen::Vector3d proxy_W = device_W + Eigen::Vector3d(-0.3, 0.1, 0.0);  // a contact, in W
  const Eigen::Vector3d before = (proxy_W - device_W) / e.map.scale;

  ModeAnchor a = reanchor_at_switch(m.map, T_W_R, p_B, proxy_W, device_W, e.map.scale);
  const Eigen::Vector3d after_point = anchored_point_W(m.map, a, T_W_R, p_B);
  const Eigen::Vector3d after = (proxy_W - after_point) / m.map.scale;
  EXPECT_NEAR((after.head<2>() - before.head<2>()).norm(), 0.0, 1e-12);
  // Relaxation moves the anchor toward zero at the given device speed.
  const double n0 = a.offset_B.norm();
  relax_anchor(a, 0.01, 0.001);
  EXPECT_NEAR(a.offset_B.norm(), std::max(0.0, n0 - 1e-5), 1e-12);
  for (int i = 0; i < 200000 && a.offset_B.norm() > 0.0; ++i) relax_anchor(a, 0.01, 0.001);
  EXPECT_EQ(a.offset_B.norm(), 0.0);
  // Without an anchor, the natural manipulation map would have jumped.
  const Eigen::Vector3d natural = (proxy_W - apply(T_W_R, map_point(m.map, p_B))) / m.map.scale;
  EXPECT_GT((natural - before).norm(), 0.01);
}

TEST(WorkspaceMaps, ForceIntoDeviceFrame) {
  const Pose2 T_W_R{0, 0, std::numbers::pi / 2};
  // A force along W's +x is along R's -y (the robot faces +y).
  const Eigen::Vector3d F_B = force_W_to_B(T_W_R, {1.0, 0.0, 0.0});
  EXPECT_NEAR((F_B - Eigen::Vector3d(0, -1, 0)).norm(), 0.0, 1e-12);
}

}  // namespace
}  // namespace hemm::math
