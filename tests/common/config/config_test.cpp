#include "common/config/config.h"

#include <gtest/gtest.h>

#include "config_operator.pb.h"
#include "config_robot.pb.h"

namespace hemm::config {
namespace {

TEST(ConfigTest, EmptyTextGivesSchemaDefaults) {
  RobotConfig c;
  auto err = parse_text_config("", "robot.pbtxt", &validate_robot_config, &c);
  ASSERT_FALSE(err) << err->to_string();
  EXPECT_EQ(c.net().session_port(), 47000u);
  EXPECT_EQ(c.safety().watchdog_ms(), 250u);
  EXPECT_EQ(c.laser().beams(), 181u);
}

TEST(ConfigTest, ParsesNestedValues) {
  OperatorConfig c;
  auto err = parse_text_config("net { robot_address: \"10.0.0.2\" session_port: 5000 }\n", "op.pbtxt",
                               &validate_operator_config, &c);
  ASSERT_FALSE(err) << err->to_string();
  EXPECT_EQ(c.net().robot_address(), "10.0.0.2");
  EXPECT_EQ(c.net().session_port(), 5000u);
}

TEST(ConfigTest, SyntaxErrorReportsFileLineAndLeavesOutputUnchanged) {
  RobotConfig c;
  c.mutable_net()->set_session_port(1234);
  auto err = parse_text_config("net {\n  session_port: 5\n  bogus_field: 3\n}\n", "robot.pbtxt",
                               &validate_robot_config, &c);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->file, "robot.pbtxt");
  EXPECT_EQ(err->line, 3);
  EXPECT_NE(err->message.find("bogus_field"), std::string::npos) << err->message;
  EXPECT_EQ(c.net().session_port(), 1234u);
}

TEST(ConfigTest, TypeErrorReportsLine) {
  RobotConfig c;
  auto err = parse_text_config("sim {\n  timestep_s: \"fast\"\n}\n", "r.pbtxt", &validate_robot_config, &c);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->line, 2);
}

TEST(ConfigTest, SemanticErrorReportsFieldAndItsLine) {
  RobotConfig c;
  auto err = parse_text_config("link { station_name: \"r\" }\nnet {\n  state_rate_hz: 50\n}\n", "r.pbtxt",
                               &validate_robot_config, &c);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "net.state_rate_hz");
  EXPECT_EQ(err->line, 3);
  EXPECT_EQ(err->column, 3);
  EXPECT_NE(err->to_string().find("r.pbtxt:3:3: net.state_rate_hz:"), std::string::npos) << err->to_string();
  EXPECT_FALSE(c.has_net());
}

TEST(ConfigTest, OperatorDeviceTypeIsChecked) {
  OperatorConfig c;
  auto err = parse_text_config("device { type: \"phantom\" }", "o.pbtxt", &validate_operator_config, &c);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "device.type");
  EXPECT_EQ(err->line, 1);
}

TEST(ConfigTest, RuleBrokenByDefaultHasNoLine) {
  // heartbeat 400 ms with the default 500 ms link timeout breaks the 2x rule;
  // the offending field (link_timeout_ms) was never written.
  OperatorConfig c;
  auto err = parse_text_config("link { heartbeat_period_ms: 400 }", "o.pbtxt", &validate_operator_config, &c);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "link.link_timeout_ms");
  EXPECT_EQ(err->line, 1);  // located at the enclosing "link" block
}

TEST(ConfigTest, MissingFileIsAnError) {
  RobotConfig c;
  auto err = load_robot_config("/nonexistent/robot.pbtxt", &c);
  ASSERT_TRUE(err);
  EXPECT_NE(err->message.find("cannot open"), std::string::npos);
}

TEST(ConfigTest, ShippedConfigsLoad) {
  const std::string src = HEMM_SOURCE_DIR;
  RobotConfig r;
  auto e1 = load_robot_config(src + "/deploy/configs/robot.pbtxt", &r);
  EXPECT_FALSE(e1) << e1->to_string();
  OperatorConfig o;
  auto e2 = load_operator_config(src + "/deploy/configs/operator.pbtxt", &o);
  EXPECT_FALSE(e2) << e2->to_string();
}

TEST(ConfigTest, ShippedProbe3dConfigsLoadAndBadValuesAreNamed) {
  const std::string src = HEMM_SOURCE_DIR;
  RobotConfig r;
  auto e1 = load_robot_config(src + "/deploy/configs/robot_depth.pbtxt", &r);
  EXPECT_FALSE(e1) << e1->to_string();
  EXPECT_TRUE(r.depth_camera().enabled());
  OperatorConfig o;
  auto e2 = load_operator_config(src + "/deploy/configs/operator_probe3d.pbtxt", &o);
  EXPECT_FALSE(e2) << e2->to_string();
  EXPECT_TRUE(o.probe_3d().enabled());
  RobotConfig rb;
  auto e3 = parse_text_config("depth_camera {\n  mount: \"roof\"\n}\n", "r.pbtxt", &validate_robot_config, &rb);
  ASSERT_TRUE(e3);
  EXPECT_EQ(e3->field, "depth_camera.mount");
  EXPECT_FALSE(rb.has_depth_camera());
  OperatorConfig ob;
  // A probe larger than the voxmap's distance layers would sink into the far field.
  auto e4 = parse_text_config("probe_3d { probe_radius_m: 0.05 }", "o.pbtxt", &validate_operator_config, &ob);
  ASSERT_TRUE(e4);
  EXPECT_EQ(e4->field, "probe_3d.probe_radius_m");
  // The voxmap's region of interest: "probe" (default) or "robot", and a sane cube.
  EXPECT_EQ(o.probe_3d().roi(), "probe");
  OperatorConfig oc;
  auto e5 = parse_text_config("probe_3d { roi: \"tool\" }", "o.pbtxt", &validate_operator_config, &oc);
  ASSERT_TRUE(e5);
  EXPECT_EQ(e5->field, "probe_3d.roi");
  EXPECT_FALSE(oc.has_probe_3d());
  auto e6 = parse_text_config("probe_3d { roi_size_m: 0.05 }", "o.pbtxt", &validate_operator_config, &oc);
  ASSERT_TRUE(e6);
  EXPECT_EQ(e6->field, "probe_3d.roi_size_m");
  auto e7 = parse_text_config("probe_3d { roi: \"robot\" roi_size_m: 0.3 }", "o.pbtxt", &validate_operator_config, &oc);
  EXPECT_FALSE(e7) << e7->to_string();
}

TEST(ConfigTest, ShippedExplore3dConfigLoadsAndTheToolNeedsItsDevice) {
  const std::string src = HEMM_SOURCE_DIR;
  OperatorConfig o;
  auto e = load_operator_config(src + "/deploy/configs/operator_explore3d.pbtxt", &o);
  EXPECT_FALSE(e) << e->to_string();
  EXPECT_EQ(o.probe_3d().tool(), "pointshell");
  EXPECT_EQ(o.device().type(), "sim-hand6");
  OperatorConfig ob;
  // The 6-DoF tool with the 3-DoF Omni (the default device): refused, naming the device.
  auto e1 = parse_text_config("probe_3d { enabled: true tool: \"pointshell\" }", "o.pbtxt", &validate_operator_config, &ob);
  ASSERT_TRUE(e1);
  EXPECT_EQ(e1->field, "device.type");
  EXPECT_FALSE(ob.has_probe_3d());
  // The rigid hand without the tool: refused; the bimanual device's right arm may hold it.
  auto e1b = parse_text_config("device { type: \"sim-hand6\" }", "o.pbtxt", &validate_operator_config, &ob);
  ASSERT_TRUE(e1b);
  EXPECT_EQ(e1b->field, "device.type");
  OperatorConfig obm;
  auto e1c = parse_text_config("device { type: \"sim-bimanual\" } probe_3d { enabled: true tool: \"pointshell\" }",
                               "o.pbtxt", &validate_operator_config, &obm);
  EXPECT_FALSE(e1c) << e1c->to_string();
  OperatorConfig os;
  auto e1d = load_operator_config(src + "/deploy/configs/operator_explore3d_bimanual.pbtxt", &os);
  EXPECT_FALSE(e1d) << e1d->to_string();
  EXPECT_EQ(os.device().type(), "sim-bimanual");
  auto e2 = parse_text_config("probe_3d { enabled: true tool: \"stick\" }", "o.pbtxt", &validate_operator_config, &ob);
  ASSERT_TRUE(e2);
  EXPECT_EQ(e2->field, "probe_3d.tool");
  auto e3 = parse_text_config(
      "device { type: \"sim-hand6\" } probe_3d { enabled: true tool: \"pointshell\" tool_work_budget: 5 }", "o.pbtxt",
      &validate_operator_config, &ob);
  ASSERT_TRUE(e3);
  EXPECT_EQ(e3->field, "probe_3d.tool_work_budget");
  // The 6-DoF tool's time budget: the shipped configs set it; negative or
  // absurd values are refused.
  EXPECT_EQ(os.probe_3d().tool_tick_budget_us(), 200.0);
  EXPECT_TRUE(os.probe_3d().has_tool_tick_budget_us());
  for (const char* bad : {"tool_tick_budget_us: -1", "tool_tick_budget_us: nan", "tool_tick_budget_us: 1e9"}) {
    auto e4 = parse_text_config(std::string("device { type: \"sim-hand6\" } probe_3d { enabled: true tool: "
                                            "\"pointshell\" ") + bad + " }",
                                "o.pbtxt", &validate_operator_config, &ob);
    ASSERT_TRUE(e4) << bad;
    EXPECT_EQ(e4->field, "probe_3d.tool_tick_budget_us") << bad;
  }
  auto e4m = parse_text_config(
      "device { type: \"sim-hand6\" } probe_3d { enabled: true tool: \"pointshell\" tool_tick_margin_us: -3 }",
      "o.pbtxt", &validate_operator_config, &ob);
  ASSERT_TRUE(e4m);
  EXPECT_EQ(e4m->field, "probe_3d.tool_tick_margin_us");
  // The SIMULATED hand's route: a scene file and a route name (the route
  // itself is read when the station starts, explore_route_test).
  EXPECT_EQ(o.probe_3d().tool_hand_route(), "../scenes/home.xml");
  for (const char* bad : {"tool_hand_route: \"\"", "tool_hand_script: \"\""}) {
    auto e4r = parse_text_config(std::string("device { type: \"sim-hand6\" } probe_3d { enabled: true tool: "
                                             "\"pointshell\" ") + bad + " }",
                                 "o.pbtxt", &validate_operator_config, &ob);
    ASSERT_TRUE(e4r) << bad;
    EXPECT_EQ(e4r->field, std::string(bad).substr(0, std::string(bad).find(':')).insert(0, "probe_3d.")) << bad;
  }
  // SIMULATION ONLY start arm pose: five finite angles or none.
  RobotConfig ra;
  auto e5 = parse_text_config("sim { start_arm_q: [0, 1.2, -0.8, 0] }", "r.pbtxt", &validate_robot_config, &ra);
  ASSERT_TRUE(e5);
  EXPECT_EQ(e5->field, "sim.start_arm_q");
  EXPECT_EQ(ra.sim().start_arm_q_size(), 0);
  auto e6 = parse_text_config("sim { start_arm_q: [0, 1.2, -0.8, 0, nan] }", "r.pbtxt", &validate_robot_config, &ra);
  ASSERT_TRUE(e6);
  EXPECT_EQ(e6->field, "sim.start_arm_q");
  EXPECT_FALSE(parse_text_config("sim { start_arm_q: [0, 1.2, -0.8, 0, 0.4] }", "r.pbtxt", &validate_robot_config, &ra));
  EXPECT_EQ(ra.sim().start_arm_q_size(), 5);
}

TEST(ConfigTest, ResolveRelative) {
  EXPECT_EQ(resolve_relative_to("/a/b/c.pbtxt", "k.key"), "/a/b/k.key");
  EXPECT_EQ(resolve_relative_to("/a/b/c.pbtxt", "/k.key"), "/k.key");
  EXPECT_EQ(resolve_relative_to("/a/b/c.pbtxt", "../s/x.xml"), "/a/s/x.xml");
  EXPECT_EQ(resolve_relative_to("/a/b/c.pbtxt", ""), "");
}

}  // namespace
}  // namespace hemm::config
