// The robot config's two-arm block (proto/config_robot.proto kind, twoarm):
// the defaults validate; each bad value is refused naming its field; the
// shipped two-arm config loads.
#include <gtest/gtest.h>

#include <fstream>

#include "common/config/config.h"
#include "config_robot.pb.h"
#include "robot_side/twoarm/twoarm_station.h"
#include "tests/temp_dir.h"

namespace hc = hemm::config;

namespace {

std::vector<std::string> fields_refused(const std::string& text) {
  hc::RobotConfig c;
  const auto e = hc::parse_text_config(text, "test.pbtxt", nullptr, &c);
  EXPECT_FALSE(e) << e->to_string();
  std::vector<std::string> out;
  for (const hc::FieldIssue& i : hc::validate_robot_config(c)) out.push_back(i.field + ": " + i.message);
  return out;
}

}  // namespace

TEST(TwoArmConfig, DefaultsAndTwoArmKindValidate) {
  EXPECT_TRUE(fields_refused("").empty());
  EXPECT_TRUE(fields_refused("kind: \"twoarm\" twoarm { stiffness_n_per_m: 800 force_limit_n: 25 }").empty());
}

TEST(TwoArmConfig, BadValuesAreRefusedByField) {
  const std::pair<const char*, const char*> cases[] = {
      {"kind: \"tank\"", "kind: "},
      {"twoarm { stiffness_n_per_m: -1 }", "twoarm.stiffness_n_per_m: "},
      {"twoarm { stiffness_n_per_m: 9000 }", "twoarm.stiffness_n_per_m: "},
      {"twoarm { damping_ns_per_m: nan }", "twoarm.damping_ns_per_m: "},
      {"twoarm { force_limit_n: 0 }", "twoarm.force_limit_n: "},
      {"twoarm { force_limit_n: 500 }", "twoarm.force_limit_n: "},
      {"twoarm { torque_limit_nm: inf }", "twoarm.torque_limit_nm: "},
      {"twoarm { joint_limit_margin_rad: 1 }", "twoarm.joint_limit_margin_rad: "},
      {"twoarm { avoidance_activation_m: 0 }", "twoarm.avoidance_activation_m: "},
      {"twoarm { max_target_jump_m: 3 }", "twoarm.max_target_jump_m: "},
      {"twoarm { reach_margin_m: -0.01 }", "twoarm.reach_margin_m: "},
      {"twoarm { reach_margin_m: nan }", "twoarm.reach_margin_m: "},
      {"twoarm { reach_margin_rad: 1 }", "twoarm.reach_margin_rad: "},
      {"twoarm { gripper_approach_speed_mps: -0.1 }", "twoarm.gripper_approach_speed_mps: "},
      {"twoarm { relative_stiffness_ratio: 1.5 }", "twoarm.relative_stiffness_ratio: "},
      {"twoarm { relative_stiffness_ratio: nan }", "twoarm.relative_stiffness_ratio: "},
      {"twoarm { direct_twist_hold_ms: 0 }", "twoarm.direct_twist_hold_ms: "},
      {"twoarm { direct_twist_hold_ms: nan }", "twoarm.direct_twist_hold_ms: "},
      {"twoarm { direct_twist_hold_ms: 400 }", "twoarm.direct_twist_hold_ms: "},
      {"twoarm { task: \"ball\" }", "twoarm.task: "},
  };
  for (const auto& [text, field] : cases) {
    SCOPED_TRACE(text);
    const auto issues = fields_refused(text);
    ASSERT_EQ(issues.size(), 1u);
    EXPECT_EQ(issues[0].rfind(field, 0), 0u) << issues[0];
  }
}

// The shipped two-arm config (deploy/configs/robot_twoarm.pbtxt) loads and
// validates, names the two-arm robot, the workbench scene and the head
// camera, and converts into the robot's options field by field.
TEST(TwoArmConfig, ShippedTwoArmConfigLoads) {
  hc::RobotConfig c;
  const std::string path = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/robot_twoarm.pbtxt";
  const auto e = hc::load_robot_config(path, &c);
  ASSERT_FALSE(e) << e->to_string();
  EXPECT_EQ(c.kind(), "twoarm");
  const std::string scene = hc::resolve_relative_to(path, c.sim().scene());
  EXPECT_EQ(scene.substr(scene.size() - 13), "workbench.xml");
  EXPECT_TRUE(std::ifstream(scene).good()) << scene;
  EXPECT_TRUE(c.depth_camera().enabled());
  EXPECT_FALSE(c.depth_camera().has_mount());  // the scene's head_depth camera
  const hemm::twoarm::TwoArmRobotOptions o = hemm::twoarm::two_arm_robot_options(c);
  EXPECT_EQ(o.control.arm[0].stiffness_N_per_m, c.twoarm().stiffness_n_per_m());
  EXPECT_EQ(o.control.arm[1].force_limit_N, c.twoarm().force_limit_n());
  EXPECT_EQ(o.limits.max_target_jump_m, c.twoarm().max_target_jump_m());
  EXPECT_EQ(o.limits.reach_margin_m, c.twoarm().reach_margin_m());
  EXPECT_EQ(o.limits.reach_margin_rad, c.twoarm().reach_margin_rad());
  EXPECT_EQ(o.control.gripper.max_speed_mps, c.twoarm().gripper_approach_speed_mps());
  EXPECT_EQ(o.control.relative_stiffness_ratio, c.twoarm().relative_stiffness_ratio());
  EXPECT_EQ(o.watchdog_ns, int64_t{c.safety().watchdog_ms()} * 1'000'000);
}

// A config file with an unknown kind is refused by the loader, naming the field.
TEST(TwoArmConfig, UnknownKindInAFileIsRefused) {
  const std::string dir = hemm::test::make_temp_dir("twoarm-config");
  const std::string path = dir + "/robot.pbtxt";
  std::ofstream(path) << "kind: \"hexapod\"\n";
  hc::RobotConfig c;
  const auto e = hc::load_robot_config(path, &c);
  ASSERT_TRUE(e);
  EXPECT_NE(e->to_string().find("kind"), std::string::npos) << e->to_string();
}
