// The scene's `task:` lines (operator/twoarm_tasks/task_scene.h): what the
// operator's scripts know of the objects agrees with the SIMULATED scene's
// bodies and geoms (MuJoCo's reading of the same file), and bad lines are
// refused with file:line and the reason.
#include "operator/twoarm_tasks/task_scene.h"
#include "robot_side/twoarm/workbench_sim.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <mujoco/mujoco.h>

namespace hs = hemm::twoarm_tasks;
namespace ht = hemm::twoarm;

namespace {

double scene_test_geom_size(const ht::WorkbenchSim& sim, const char* geom, int k) {
  const int g = mj_name2id(sim.m(), mjOBJ_GEOM, geom);
  EXPECT_GE(g, 0) << geom;
  return g < 0 ? 0.0 : sim.m()->geom_size[3 * g + k];
}

const char* const kSceneTestGood =
    "task: box centre 0.58 -0.38 0.825 size 0.20 0.30 0.15\n"
    "task: shelf place 0.60 -0.72 0.95\n"
    "task: peg centre 0.50 0.55 0.80 half 0.0125 length 0.10\n"
    "task: hole top 0.55 0.30 0.80 depth 0.04\n"
    "task: bar centre 0.40 0.0 0.815 radius 0.015 length 0.50\n";

}  // namespace

namespace {

void scene_test_lines_agree(const std::string& path) {
  SCOPED_TRACE(path);
  const hs::TaskSceneResult r = hs::load_task_scene(path);
  ASSERT_TRUE(r.scene) << r.error;
  const hs::TaskScene& s = *r.scene;
  ht::WorkbenchSim sim(path);
  constexpr double kTol = 1e-9;
  EXPECT_LT((s.box_centre - sim.body_pose_A("box").translation()).norm(), kTol);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.box_size(k), 2.0 * scene_test_geom_size(sim, "box_geom", k), kTol);
  const Eigen::Vector3d board = sim.body_pose_A("shelf").translation() + Eigen::Vector3d(0, 0, 0.94);
  EXPECT_LT((s.shelf_place - (board + Eigen::Vector3d(0, 0, scene_test_geom_size(sim, "shelf_board", 2)))).norm(), kTol);
  EXPECT_LT((s.peg_centre - sim.body_pose_A("peg").translation()).norm(), kTol);
  EXPECT_NEAR(s.peg_half_width_m, scene_test_geom_size(sim, "peg_geom", 0), kTol);
  EXPECT_NEAR(s.peg_half_width_m, scene_test_geom_size(sim, "peg_geom", 1), kTol);
  EXPECT_NEAR(s.peg_length_m, 2.0 * scene_test_geom_size(sim, "peg_geom", 2), kTol);
  const int hole = mj_name2id(sim.m(), mjOBJ_SITE, "fixture_hole");
  ASSERT_GE(hole, 0);
  const mjtNum* h = sim.d()->site_xpos + 3 * hole;
  EXPECT_LT((s.hole_top - Eigen::Vector3d(h[0], h[1], h[2])).norm(), kTol);
  // The ring's boxes reach from the base plate's top to the hole's top.
  const double base_top = sim.body_pose_A("fixture").translation().z() + 2.0 * scene_test_geom_size(sim, "fixture_base", 2);
  EXPECT_NEAR(s.hole_depth_m, s.hole_top.z() - base_top, kTol);
  EXPECT_LT((s.bar_centre - sim.body_pose_A("bar").translation()).norm(), kTol);
  EXPECT_NEAR(s.bar_radius_m, scene_test_geom_size(sim, "bar_geom", 0), kTol);
  EXPECT_NEAR(s.bar_length_m, 2.0 * scene_test_geom_size(sim, "bar_geom", 1), kTol);
}

std::string scene_test_read(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(TaskScene, ShippedLinesAgreeWithTheSimulatedScene) { scene_test_lines_agree(hemm::test::kWorkbenchScene); }
TEST(TaskScene, BoxSceneLinesAgreeWithTheSimulatedScene) { scene_test_lines_agree(hemm::test::workbench_box_scene()); }

// workbench_box.xml is workbench.xml with the box and the shelf moved (bodies
// and task: lines together) and a header comment: nothing else differs.
TEST(TaskScene, BoxSceneDiffersOnlyInTheBoxAndShelfPositions) {
  std::string xml = scene_test_read(hemm::test::kWorkbenchScene);
  const std::string box = scene_test_read(hemm::test::workbench_box_scene());
  const std::pair<const char*, const char*> moves[] = {
      {"task: box   centre 0.58 -0.38 0.825", "task: box   centre 0.64 -0.02 0.825"},
      {"task: shelf place 0.60 -0.72 0.95", "task: shelf place 0.57 -0.415 0.95"},
      {"<body name=\"shelf\" pos=\"0.60 -0.72 0\">", "<body name=\"shelf\" pos=\"0.57 -0.415 0\">"},
      {"<body name=\"box\" pos=\"0.58 -0.38 0.825\">", "<body name=\"box\" pos=\"0.64 -0.02 0.825\">"}};
  for (const auto& [from, to] : moves) {
    const std::size_t at = xml.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    xml.replace(at, std::string(from).size(), to);
  }
  const std::size_t body = box.find("-->\n");  // the end of its own header comment
  ASSERT_NE(body, std::string::npos);
  EXPECT_EQ(box.substr(body + 4), xml);
}

TEST(TaskScene, BadLinesAreRefusedWithFileLineAndReason) {
  ASSERT_TRUE(hs::parse_task_scene(kSceneTestGood, "t.xml").scene);
  struct Case {
    std::string text, error;
  };
  const std::string good = kSceneTestGood;
  const std::vector<Case> cases = {
      {good + "task: box centre 0 0 0 size 1 1 1\n", "t.xml:6: a second line for 'box'"},
      {good + "task: table top 0 0 0\n", "t.xml:6: unknown task object 'table'"},
      {"task: box centre 0.58 -0.38 size 0.20 0.30 0.15\n", "t.xml:1: 'box centre': 'size' is not a finite number"},
      {"task: box centre 0.58 -0.38 0.825 size 0.20 0.30\n", "t.xml:1: 'box size' needs 3 numbers"},
      {"task: box centre 0.58 -0.38 nan size 0.20 0.30 0.15\n", "t.xml:1: 'box centre': 'nan' is not a finite number"},
      {"task: box centre 0.58 -0.38 0.825\n", "t.xml:1: 'box' lacks 'size'"},
      {"task: box centre 0.58 -0.38 0.825 size 0.2 0.3 0.15 mass 2\n", "t.xml:1: 'box' has no key 'mass'"},
      {"task: box centre 1 2 3 centre 1 2 3 size 1 1 1\n", "t.xml:1: 'box': 'centre' given twice"},
      {"task: peg centre 0 0 0 half -0.01 length 0.1\n", "t.xml:1: 'peg half' must be positive"},
      {"task:\n", "t.xml:1: a task line names no object"},
      {"<!-- no task lines -->\n", "t.xml: no 'task: box' line"},
  };
  for (const Case& c : cases) {
    const hs::TaskSceneResult r = hs::parse_task_scene(c.text, "t.xml");
    EXPECT_FALSE(r.scene) << c.text;
    EXPECT_EQ(r.error.rfind(c.error, 0), 0u) << "got: " << r.error << "\nwanted: " << c.error;
  }
  const hs::TaskSceneResult missing = hs::load_task_scene("/nonexistent/workbench.xml");
  EXPECT_FALSE(missing.scene);
  EXPECT_EQ(missing.error, "/nonexistent/workbench.xml: cannot be read");
}
