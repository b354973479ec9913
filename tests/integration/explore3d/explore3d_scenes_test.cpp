// The table scenes of the 6-DoF exploration (deploy/scenes/home.xml,
// table_round.xml, table_mixed.xml), without running a station: each loads
// in MuJoCo, every geom in its truth region is meshed and voxelised by the
// truth tool (robot_side/truth: none skipped, the objects named), the
// SIMULATED mast camera's rays (mj_ray, from the start the header gives)
// reach every object on the table, the header's robot start is where the
// robot starts (the scene's robot_start site; home.xml: robot_depth.pbtxt's
// start), and the route's keys lie in the tool's workspace: the SIMULATED
// rigid hand's box and speed (check_route_reach) and the SIMULATED bimanual
// device's right arm with the shipped offset (hand_path_check.h, through
// make_tool6_bimanual_device).
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "common/config/config.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_image.h"
#include "common/sim/mujoco_owner.h"
#include "config_operator.pb.h"
#include "config_robot.pb.h"
#include "operator/station/explore_route.h"
#include "operator/station/tool6_bimanual.h"
#include "operator/station/tool6_explorer.h"
#include "robot_side/sim/depth_camera.h"
#include "robot_side/truth/scene_slice.h"
#include "robot_side/truth/tool6_truth.h"
#include "tests/sanitizer_build.h"

namespace ho = hemm::op;
namespace hr = hemm::robot;

namespace {

struct Scene {
  std::string file;
  std::vector<std::string> objects;  // on the table, each to be meshed and seen
};

const std::vector<Scene>& scenes() {
  static const std::vector<Scene> s = {
      {"home.xml", {"table_block", "table_book", "table_mug"}},
      {"table_round.xml", {"cyl_lying", "ball", "box30"}},
      {"table_mixed.xml",
       {"plate", "step_a", "step_b", "tray_floor", "tray_front", "tray_back", "tray_left", "tray_right"}},
  };
  return s;
}

std::string path_of(const std::string& f) { return std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/" + f; }

// The shipped 6-DoF exploration config (its H origin, its bimanual offset).
hemm::config::OperatorConfig explore_config() {
  hemm::config::OperatorConfig c;
  const auto e = hemm::config::load_operator_config(HEMM_SOURCE_DIR "/deploy/configs/operator_explore3d.pbtxt", &c);
  EXPECT_FALSE(e) << e->to_string();
  return c;
}

}  // namespace

TEST(Explore3dScenes, EveryGeomOnTheTableIsVoxelisedByTheTruthTool) {
  for (const Scene& sc : scenes()) {
    SCOPED_TRACE(sc.file);
    ho::SceneExploration x;
    ASSERT_EQ(ho::load_scene_exploration(path_of(sc.file), &x), std::nullopt);
    ASSERT_NE(x.find("explore-table"), nullptr);
    hr::SceneMeshes m;
    std::string err;
    ASSERT_TRUE(hr::load_scene_meshes(path_of(sc.file), x.region_W, &m, &err)) << err;
    for (const auto& s : m.skipped) ADD_FAILURE() << "skipped " << s.name << " (" << s.kind << "): " << s.detail;
    std::set<std::string> parts;
    for (const auto& p : m.parts) parts.insert(p.name);
    for (const std::string& o : sc.objects) EXPECT_EQ(parts.count(o), 1u) << o << " not meshed";
    // The truth tool's own voxmap (at 5 mm here, 2.5 mm in the runs) takes the same parts.
    // Under the sanitizers the first scene's alone: the same code (tests/sanitizer_build.h).
    if (hemm::test::kSanitizerBuild && &sc != &scenes().front()) continue;
    hemm::vps::Voxmap vm;
    std::vector<std::string> names;
    ASSERT_TRUE(hr::build_truth_voxmap(path_of(sc.file), x.region_W, 0.005, &vm, &names, &err)) << err;
    EXPECT_EQ(std::set<std::string>(names.begin(), names.end()), parts);
    EXPECT_GT(vm.memory_bytes(), 0u);
  }
}

TEST(Explore3dScenes, TheHeadersStartIsTheRobotsAndTheMastCameraSeesEveryObject) {
  // home.xml's robot_start (the origin) is the 2D demos'; its explore-start
  // is robot_depth.pbtxt's start.
  hemm::config::RobotConfig rc;
  ASSERT_FALSE(hemm::config::load_robot_config(HEMM_SOURCE_DIR "/deploy/configs/robot_depth.pbtxt", &rc));
  for (const Scene& sc : scenes()) {
    SCOPED_TRACE(sc.file);
    ho::SceneExploration x;
    ASSERT_EQ(ho::load_scene_exploration(path_of(sc.file), &x), std::nullopt);
    hemm::sim::MujocoOwner s = hemm::sim::MujocoOwner::from_file(path_of(sc.file));
    mj_forward(s.m(), s.d());
    const mjModel* m = s.m();
    const mjData* d = s.d();
    if (sc.file == "home.xml") {
      EXPECT_NEAR(x.start_W.x, rc.sim().start_x_m(), 1e-9);
      EXPECT_NEAR(x.start_W.y, rc.sim().start_y_m(), 1e-9);
      EXPECT_NEAR(x.start_W.theta, rc.sim().start_theta_rad(), 1e-6);
    } else {
      const int site = mj_name2id(m, mjOBJ_SITE, "robot_start");
      ASSERT_GE(site, 0);
      EXPECT_NEAR(d->site_xpos[3 * site], x.start_W.x, 1e-9);
      EXPECT_NEAR(d->site_xpos[3 * site + 1], x.start_W.y, 1e-9);
      // Heading: the site's x axis (column 0 of its rotation) in the ground plane.
      const double yaw = std::atan2(d->site_xmat[9 * site + 3], d->site_xmat[9 * site]);
      EXPECT_NEAR(std::remainder(yaw - x.start_W.theta, 2 * std::numbers::pi), 0.0, 1e-9);
    }
    // The SIMULATED mast camera at its defaults (robot_depth.pbtxt: mast
    // (0.10, 0, 1.10) in R, pitched 35 degrees, 80 x 60 over 60 degrees),
    // one mj_ray a pixel past the robot's own geoms (group 3).
    hr::SimDepthCameraParams cam;
    const hemm::config::DepthCameraConfig dc = rc.depth_camera();
    cam.width = static_cast<int>(dc.width());
    cam.height = static_cast<int>(dc.height());
    cam.hfov = dc.hfov_deg() * std::numbers::pi / 180;
    cam.range_min = dc.range_min_m();
    cam.range_max = dc.range_max_m();
    cam.T_mount_S = hr::SimDepthCameraParams::mast_mount(dc.mast_x_m(), dc.mast_z_m(), dc.mast_pitch_deg() * std::numbers::pi / 180);
    const Eigen::Isometry3d T_W_S = ho::robot_pose3(x.start_W) * cam.T_mount_S;
    const hemm::mapping::DepthIntrinsics K = cam.intrinsics();
    const mjtByte groups[6] = {1, 1, 1, 0, 1, 1};
    std::map<std::string, int> hits;
    for (int v = 0; v < K.height; ++v)
      for (int u = 0; u < K.width; ++u) {
        const Eigen::Vector3d dir = (T_W_S.linear() * hemm::mapping::pixel_ray_z1(K, u, v)).normalized();
        const mjtNum p[3] = {T_W_S.translation().x(), T_W_S.translation().y(), T_W_S.translation().z()};
        const mjtNum dv[3] = {dir.x(), dir.y(), dir.z()};
        int g = -1;
        const mjtNum r = mj_ray(m, d, p, dv, groups, 1, -1, &g);
        if (g >= 0 && r >= K.range_min && r <= K.range_max) {
          const char* n = mj_id2name(m, mjOBJ_GEOM, g);
          ++hits[n != nullptr ? n : "?"];
        }
      }
    std::string seen;
    for (const std::string& o : sc.objects) {
      seen += " " + o + " " + std::to_string(hits[o]);
      EXPECT_GE(hits[o], 2) << o << " is (nearly) not in the mast camera's view";
    }
    std::printf("%s: pixels of the mast camera's 80 x 60 on each object:%s\n", sc.file.c_str(), seen.c_str());
  }
}

TEST(Explore3dScenes, TheRoutesLieInTheToolsWorkspace) {
  const hemm::config::OperatorConfig c = explore_config();
  const auto& p3 = c.probe_3d();
  const Eigen::Vector3d origin_R(p3.origin_x_m(), 0.0, p3.origin_z_m());
  const Eigen::Vector3d offset_D(p3.tool_device_offset_x_m(), p3.tool_device_offset_y_m(), p3.tool_device_offset_z_m());
  for (const Scene& sc : scenes()) {
    ho::SceneExploration x;
    ASSERT_EQ(ho::load_scene_exploration(path_of(sc.file), &x), std::nullopt);
    for (const ho::ExploreRoute& r : x.routes) {
      SCOPED_TRACE(sc.file + " " + r.name);
      // Every key inside the truth region's footprint (what the truth models).
      for (const ho::RouteKey& k : r.keys)
        EXPECT_TRUE(x.region_W.contains(ho::robot_pose3(x.start_W) * k.tip_R))
            << "line " << k.line << ": the tip outside the truth region";
      // The SIMULATED rigid hand (sim-hand6) ...
      const hemm::device::EndEffectorLimits hand = hemm::device::rigid_hand_limits(1).ee[0];
      EXPECT_EQ(ho::check_route_reach(r, origin_R, hand, sc.file), std::nullopt);
      // ... and the SIMULATED bimanual device's right arm (sim-bimanual):
      // workspace, reach with the elbow bent, out of the table's zone.
      ho::Tool6Params tp;
      try {
        const auto dev = ho::make_tool6_bimanual_device(hemm::config::BimanualDeviceConfig{},
                                                        ho::make_hand6_trajectory(r, origin_R), offset_D, 1e-3, &tp);
        EXPECT_NE(dev, nullptr);
      } catch (const std::invalid_argument& e) {
        ADD_FAILURE() << e.what();
      }
    }
  }
}
