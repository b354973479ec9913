#include "robot_side/truth/scene_slice.h"

#include <numbers>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "common/math/frames.h"
#include "tests/temp_dir.h"

namespace hemm::robot {
namespace {

using Eigen::Vector2d;

class TempDir {
 public:
  TempDir() {
    std::string t = (std::filesystem::temp_directory_path() / "hemm_slice_XXXXXX").string();
    if (mkdtemp(t.data()) != nullptr) path_ = t;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::set<std::string> names(const std::vector<SliceEntry>& v) {
  std::set<std::string> s;
  for (const auto& e : v) s.insert(e.name);
  return s;
}

const haptics::ExactCircle* circle_at(const haptics::ExactScene& s, const Vector2d& c) {
  for (const auto& k : s.circles)
    if ((k.centre - c).norm() < 1e-9) return &k;
  return nullptr;
}

bool has_vertex(const haptics::ExactScene& s, const Vector2d& p) {
  return std::any_of(s.segments.begin(), s.segments.end(),
                     [&](const haptics::ExactSegment& g) { return (g.a - p).norm() < 1e-9 || (g.b - p).norm() < 1e-9; });
}

constexpr double kZ = 0.35;

// One of each case the slicer must handle (slice at z = 0.35).
constexpr const char* kTestScene = R"(<mujoco model="slice_test">
  <compiler angle="radian"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="yawbox" type="box" pos="1 2 0.5" euler="0 0 0.5235987755982988" size="0.3 0.1 0.5"/>
    <geom name="sidebox" type="box" pos="-3 1 0.5" zaxis="1 0 0" size="0.5 0.2 0.1"/>
    <geom name="cyl" type="cylinder" pos="-1 0.5 0.4" size="0.2 0.4"/>
    <geom name="ball" type="sphere" pos="2 -1 0.5" size="0.25"/>
    <geom name="high" type="box" pos="0 -2 1.5" size="0.2 0.2 0.2"/>
    <geom name="tilted" type="cylinder" pos="-2 -2 0.5" euler="0.4 0 0" size="0.1 0.5"/>
    <geom name="egg" type="ellipsoid" pos="4 4 0.3" size="0.1 0.2 0.3"/>
    <body name="bot" pos="0 0 0.3">
      <freejoint/>
      <geom name="bot_box" type="box" size="0.1 0.1 0.1"/>
    </body>
    <body name="stand" pos="3 3 0">
      <geom name="pole" type="capsule" pos="0 0 0.3" size="0.1 0.2"/>
      <geom name="stub" type="capsule" pos="1 0 0" size="0.1 0.3"/>
    </body>
  </worldbody>
</mujoco>
)";

TEST(SceneSlice, ClosedFormShapes) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string path = dir.path() + "/scene.xml";
  std::ofstream(path) << kTestScene;
  SceneSlice s;
  std::string err;
  ASSERT_TRUE(load_scene_slice(path, kZ, &s, &err)) << err;
  EXPECT_DOUBLE_EQ(s.height, kZ);

  EXPECT_EQ(names(s.included), (std::set<std::string>{"yawbox", "sidebox", "cyl", "ball", "pole", "stub"}));
  EXPECT_EQ(names(s.skipped), (std::set<std::string>{"tilted", "egg"}));
  EXPECT_EQ(names(s.off_slice), (std::set<std::string>{"floor", "high"}));
  EXPECT_EQ(s.moving_geoms, 1u);  // bot_box (free joint)

  // Box yawed 30 deg: corners c +- R(30)(0.3, 0) +- R(30)(0, 0.1).
  ASSERT_EQ(s.scene.segments.size(), 8u);  // two rectangles
  const Eigen::Matrix2d R = math::rotation2(std::numbers::pi / 6);
  for (double sa : {-1.0, 1.0})
    for (double sb : {-1.0, 1.0}) {
      const Vector2d corner = Vector2d(1, 2) + R * Vector2d(sa * 0.3, sb * 0.1);
      EXPECT_TRUE(has_vertex(s.scene, corner)) << corner.transpose();
    }
  // Box with its local x vertical (zaxis = world x): footprint x +- 0.1, y +- 0.2.
  for (double sa : {-1.0, 1.0})
    for (double sb : {-1.0, 1.0}) EXPECT_TRUE(has_vertex(s.scene, Vector2d(-3 + sa * 0.1, 1 + sb * 0.2)));
  // The yawed box's surface seen from its centre line: distance along its
  // local y axis from 0.5 m out is 0.5 - 0.1.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, Vector2d(1, 2) + R * Vector2d(0, 0.5)), 0.4, 1e-12);

  ASSERT_EQ(s.scene.circles.size(), 4u);
  const auto* cyl = circle_at(s.scene, {-1, 0.5});
  ASSERT_NE(cyl, nullptr);
  EXPECT_NEAR(cyl->radius, 0.2, 1e-12);
  const auto* ball = circle_at(s.scene, {2, -1});
  ASSERT_NE(ball, nullptr);
  EXPECT_NEAR(ball->radius, std::sqrt(0.25 * 0.25 - 0.15 * 0.15), 1e-12);  // dz = 0.15
  const auto* pole = circle_at(s.scene, {3, 3});  // slice through the capsule's cylinder part
  ASSERT_NE(pole, nullptr);
  EXPECT_NEAR(pole->radius, 0.1, 1e-12);
  const auto* stub = circle_at(s.scene, {4, 3});  // slice 0.05 m into the top cap
  ASSERT_NE(stub, nullptr);
  EXPECT_NEAR(stub->radius, std::sqrt(0.1 * 0.1 - 0.05 * 0.05), 1e-12);

  // Nothing of the free body: its box would put (0, 0) inside the scene.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0, 0}), (Vector2d(-1, 0.5).norm() - 0.2), 1e-12);
}

TEST(SceneSlice, BadInputs) {
  SceneSlice s;
  s.height = -7.0;  // must stay untouched on error
  std::string err;
  EXPECT_FALSE(load_scene_slice("/nonexistent/scene.xml", kZ, &s, &err));
  EXPECT_NE(err.find("/nonexistent/scene.xml"), std::string::npos) << err;
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string path = dir.path() + "/bad.xml";
  std::ofstream(path) << "<mujoco><worldbody><geom type=\"box\" size=\"1\"";
  err.clear();
  EXPECT_FALSE(load_scene_slice(path, kZ, &s, &err));
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_FALSE(load_scene_slice(HEMM_SOURCE_DIR "/deploy/scenes/home.xml", std::nan(""), &s, &err));
  EXPECT_DOUBLE_EQ(s.height, -7.0);
}

// The truth meshes of the 3D probe: home.xml's table top and the objects on
// it, exactly (boxes) or within 0.03 % of the radius (cylinders), placed as
// the MJCF says; an ellipsoid is reported as skipped (not dropped).
TEST(SceneMeshes, HomeTableAndItsObjectsAreMeshedWhereTheSceneSays) {
  SceneMeshes m;
  std::string err;
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.8, 1.5, 0.6), Eigen::Vector3d(2.2, 2.5, 0.9));
  ASSERT_TRUE(load_scene_meshes(HEMM_SOURCE_DIR "/deploy/scenes/home.xml", region, &m, &err)) << err;
  std::map<std::string, Eigen::AlignedBox3d> boxes;
  for (const auto& p : m.parts)
    for (const Eigen::Vector3d& v : p.mesh.vertices) boxes[p.name].extend(v);
  // MJCF: body at (1.5, 2.0, 0); top at z 0.73, half sizes 0.6 0.4 0.02.
  ASSERT_EQ(boxes.count("table_top"), 1u);
  EXPECT_LT((boxes["table_top"].min() - Eigen::Vector3d(0.9, 1.6, 0.71)).norm(), 1e-9);
  EXPECT_LT((boxes["table_top"].max() - Eigen::Vector3d(2.1, 2.4, 0.75)).norm(), 1e-9);
  ASSERT_EQ(boxes.count("table_block"), 1u);
  EXPECT_LT((boxes["table_block"].min() - Eigen::Vector3d(1.70, 1.80, 0.75)).norm(), 1e-9);
  EXPECT_LT((boxes["table_block"].max() - Eigen::Vector3d(1.80, 1.90, 0.85)).norm(), 1e-9);
  // The mug (r 0.04, half height 0.05 at (1.6, 2.2, 0.8)): 128 vertices on the circle.
  ASSERT_EQ(boxes.count("table_mug"), 1u);
  EXPECT_LT((boxes["table_mug"].min() - Eigen::Vector3d(1.56, 2.16, 0.75)).norm(), 1e-9);
  EXPECT_LT((boxes["table_mug"].max() - Eigen::Vector3d(1.64, 2.24, 0.85)).norm(), 1e-9);
  // The legs reach into the region (z up to 0.72) and are cylinders too.
  EXPECT_EQ(boxes.count("table_leg1"), 1u);
  EXPECT_EQ(boxes.count("table_book"), 1u);
  EXPECT_TRUE(m.skipped.empty());

  // A shape that cannot be meshed is reported, not dropped.
  const std::string path = hemm::test::make_temp_dir() + "/scene_meshes_ellipsoid.xml";
  {
    std::ofstream f(path);
    f << "<mujoco><worldbody><geom name=\"egg\" type=\"ellipsoid\" size=\"0.1 0.2 0.3\" pos=\"0 0 1\"/>"
         "<geom name=\"cube\" type=\"box\" size=\"0.1 0.1 0.1\" pos=\"0 0 1\"/></worldbody></mujoco>";
  }
  SceneMeshes e;
  ASSERT_TRUE(load_scene_meshes(path, Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2)), &e,
                                &err)) << err;
  ASSERT_EQ(e.skipped.size(), 1u);
  EXPECT_EQ(e.skipped[0].name, "egg");
  ASSERT_EQ(e.parts.size(), 1u);
  EXPECT_EQ(e.parts[0].name, "cube");

  const std::size_t parts = m.parts.size();
  EXPECT_FALSE(load_scene_meshes("/nonexistent/scene.xml", region, &m, &err));
  EXPECT_EQ(m.parts.size(), parts);  // untouched on error
}

TEST(SceneSlice, HomeSceneKnownFacts) {
  const std::string home = HEMM_SOURCE_DIR "/deploy/scenes/home.xml";
  SceneSlice s;
  std::string err;
  ASSERT_TRUE(load_scene_slice(home, 0.30, &s, &err)) << err;  // the laser plane
  EXPECT_TRUE(s.skipped.empty());
  EXPECT_GT(s.moving_geoms, 0u);  // the robot
  const std::set<std::string> in = names(s.included);
  for (const char* robot_geom : {"chassis", "laser_head", "wheel_fl", "arm_column", "arm_link2", "payload"})
    EXPECT_EQ(in.count(robot_geom), 0u) << robot_geom;
  // Every obstacle reaches the laser plane; the table only with its legs.
  for (const char* g : {"wall_west", "wall_mid_s", "table_leg1", "chair_w_legs", "sofa_seat", "sofa_back", "bin",
                        "partition", "crate"})
    EXPECT_EQ(in.count(g), 1u) << g;
  for (const char* g : {"table_top", "chair_w_seat", "chair_e_back"}) EXPECT_EQ(in.count(g), 0u) << g;

  const auto* bin = circle_at(s.scene, {1.5, -1.2});
  ASSERT_NE(bin, nullptr);
  EXPECT_NEAR(bin->radius, 0.15, 1e-12);
  // West wall inner face at x = -0.95 (wall centre -1, half thickness 0.05).
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {-0.5, 0.0}), 0.45, 1e-12);
  // At the robot's start nothing is nearer than that wall: no robot geometry.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0.0, 0.0}), 0.95, 1e-12);
  // The sofa seat's front face: y = -2.5 + 0.05 + 0.35.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {1.0, -1.9}), 0.2, 1e-12);

  // At 0.35 m the same geoms are cut (hemm-truth --help says so).
  SceneSlice s35;
  ASSERT_TRUE(load_scene_slice(home, 0.35, &s35, &err)) << err;
  EXPECT_EQ(names(s35.included), in);
}

TEST(SceneSlice, CorridorsSceneColumnsBoardAndDoorway) {
  SceneSlice s;
  std::string err;
  ASSERT_TRUE(load_scene_slice(HEMM_SOURCE_DIR "/deploy/scenes/corridors.xml", 0.30, &s, &err)) << err;
  EXPECT_TRUE(s.skipped.empty());
  const struct {
    Eigen::Vector2d c;
    double r;
  } columns[] = {{{1.5, 0.55}, 0.07}, {{2.6, -0.5}, 0.12}, {{3.3, 0.6}, 0.30}, {{5.35, 2.2}, 0.22}};
  for (const auto& col : columns) {
    const auto* c = circle_at(s.scene, col.c);
    ASSERT_NE(c, nullptr) << col.r;
    EXPECT_NEAR(c->radius, col.r, 1e-12);
  }
  // The board is 1 cm thick, its faces at y = 3.195 and 3.205.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {4.35, 3.1}), 0.095, 1e-9);
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {4.35, 3.3}), 0.095, 1e-9);
  // The doorway's middle is 0.45 m from both jambs.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {5.0, 4.3}), 0.45, 1e-9);
  // The start: corridor A's faces 0.95 m away on both sides.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0.0, 0.0}), 0.95, 1e-12);
}

TEST(SceneSlice, OfficeSceneMixedShapes) {
  SceneSlice s;
  std::string err;
  ASSERT_TRUE(load_scene_slice(HEMM_SOURCE_DIR "/deploy/scenes/office.xml", 0.30, &s, &err)) << err;
  EXPECT_TRUE(s.skipped.empty());
  const struct {
    Eigen::Vector2d c;
    double r;
  } circles[] = {{{1.6, 0.8}, 0.20},     // the bin
                 {{0.9, -1.35}, 0.30},   // the ball, cut at its equator
                 {{2.45, 0.9}, 0.025},   // the table's legs
                 {{3.55, 1.5}, 0.025}};
  for (const auto& c : circles) {
    const auto* got = circle_at(s.scene, c.c);
    ASSERT_NE(got, nullptr) << c.r;
    EXPECT_NEAR(got->radius, c.r, 1e-12);
  }
  // The pillar (0.4 m square turned 30 deg about z): 0.3 m from a face
  // along its normal at 30 deg is 0.5 m from the centre.
  const Eigen::Vector2d n(std::cos(std::numbers::pi / 6), std::sin(std::numbers::pi / 6));
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, Eigen::Vector2d(1.3, -0.85) + 0.5 * n), 0.3, 1e-9);
  // The board: 1.5 cm thick, faces at x = 0.3925 and 0.4075.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0.3, 1.7}), 0.0925, 1e-9);
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0.5, 1.7}), 0.0925, 1e-9);
  // The table top is above the laser plane: between the legs is free.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {3.0, 1.2}), std::hypot(0.55, 0.3) - 0.025, 1e-9);
  // The start: the west wall's face 0.95 m away is the nearest.
  EXPECT_NEAR(haptics::distance_to_scene(s.scene, {0.0, 0.0}), 0.95, 1e-12);
}

}  // namespace
}  // namespace hemm::robot
