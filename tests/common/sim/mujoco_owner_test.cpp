// The MuJoCo model/data owner: loads from text and from a file, says what
// failed (the name or path and MuJoCo's message), moves without copying.
#include "common/sim/mujoco_owner.h"

#include <mujoco/mujoco.h>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <unistd.h>

namespace hs = hemm::sim;

namespace {

// One free box of 2 kg at z = 1 m above a plane.
constexpr const char* kBoxXml = R"(<mujoco>
  <worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body name="box" pos="0 0 1">
      <freejoint/>
      <geom type="box" size="0.1 0.1 0.1" mass="2"/>
    </body>
  </worldbody>
</mujoco>)";

std::string what_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MujocoOwner, LoadsFromTextWithDataAtTheModelsReferencePose) {
  const hs::MujocoOwner o = hs::MujocoOwner::from_xml("box.xml", kBoxXml);
  ASSERT_TRUE(o);
  ASSERT_NE(o.d(), nullptr);
  EXPECT_EQ(o.m()->nbody, 2);  // world and the box
  EXPECT_EQ(o.m()->nq, 7);     // a free joint
  const int box = mj_name2id(o.m(), mjOBJ_BODY, "box");
  ASSERT_GE(box, 0);
  EXPECT_DOUBLE_EQ(o.m()->body_mass[box], 2.0);
  mj_forward(o.m(), o.d());
  EXPECT_DOUBLE_EQ(o.d()->xpos[3 * box + 2], 1.0);
  // The data is the owner's and is stepped: the box falls as g t^2 / 2.
  const double dt = o.m()->opt.timestep;
  for (int i = 0; i < 100; ++i) mj_step(o.m(), o.d());
  const double t = 100 * dt;
  EXPECT_NEAR(o.d()->xpos[3 * box + 2], 1.0 - 0.5 * 9.81 * t * t, 0.01);
}

TEST(MujocoOwner, LoadsFromAFileAndMovesItsModelAndData) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mujoco_owner_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "box.xml").string();
  std::ofstream(path) << kBoxXml;
  hs::MujocoOwner a = hs::MujocoOwner::from_file(path);
  ASSERT_TRUE(a);
  const mjModel* m = a.m();
  const mjData* d = a.d();
  hs::MujocoOwner b = std::move(a);
  EXPECT_EQ(b.m(), m);
  EXPECT_EQ(b.d(), d);
  EXPECT_FALSE(a);  // NOLINT(bugprone-use-after-move): a moved-from owner is empty
  EXPECT_EQ(a.d(), nullptr);
  std::filesystem::remove_all(dir);
}

TEST(MujocoOwner, ABadSceneSaysItsNameAndMuJoCosMessage) {
  const std::string text = what_of([] { hs::load_model_xml("broken.xml", "<mujoco><worldbody><body>"); });
  EXPECT_EQ(text.rfind("broken.xml: ", 0), 0u) << text;
  EXPECT_GT(text.size(), std::string("broken.xml: ").size()) << text;  // MuJoCo's own message follows
  const std::string missing = "/nonexistent/hemm/scene.xml";
  const std::string file = what_of([&] { hs::MujocoOwner::from_file(missing); });
  EXPECT_EQ(file.rfind(missing + ": ", 0), 0u) << file;
  // A model's separate data, as a second reader of one const model keeps.
  const hs::MjModelPtr m = hs::load_model_xml("box.xml", kBoxXml);
  const hs::MjDataPtr d = hs::make_data(m.get());
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->qpos[2], 1.0);  // qpos0 of the free joint: the body's position
}
