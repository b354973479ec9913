// The robot config's two-arm block (proto/config_robot.proto kind, twoarm):
// the defaults validate; each bad value is refused naming its field.
#include <gtest/gtest.h>

#include "common/config/config.h"
#include "config_robot.pb.h"

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
  };
  for (const auto& [text, field] : cases) {
    SCOPED_TRACE(text);
    const auto issues = fields_refused(text);
    ASSERT_EQ(issues.size(), 1u);
    EXPECT_EQ(issues[0].rfind(field, 0), 0u) << issues[0];
  }
}
