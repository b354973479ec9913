// The shipped telemanipulation config loads and becomes the task's and the
// link's parameters; each bad field is refused by name and changes nothing.
#include "operator/telemanip/telemanip_config.h"

#include <gtest/gtest.h>

#include <string>

#include "common/config/config.h"

namespace tele = hemm::op::telemanip;

namespace {

hemm::device::DeviceLimits config_test_limits() { return hemm::device::rigid_hand_limits(2); }

}  // namespace

TEST(TelemanipConfig, ShippedConfigLoads) {
  hemm::config::OperatorConfig o;
  std::string path = HEMM_SOURCE_DIR;
  path += "/deploy/configs/operator_telemanip.pbtxt";
  auto e = hemm::config::load_operator_config(path, &o);
  ASSERT_FALSE(e) << e->to_string();
  ASSERT_TRUE(o.telemanip().enabled());
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  ASSERT_EQ(tele::telemanip_params(o.telemanip(), 1e-3, config_test_limits(), &tp, &lp), "");
  // The right arm gated by the left hand's dead-man; the clamp per 1 ms step.
  EXPECT_EQ(tp.mapping[0].deadman_ee, 1);
  EXPECT_EQ(tp.mapping[1].deadman_ee, 1);
  EXPECT_NEAR(tp.mapping[0].max_step_m, 1.0e-3, 1e-15);
  EXPECT_NEAR(tp.mapping[0].max_step_rad, 3.0e-3, 1e-15);
  EXPECT_TRUE(tp.mapping[0].R_A_D.isIdentity(1e-15));
  EXPECT_DOUBLE_EQ(lp.rate_hz, 200.0);
}

TEST(TelemanipConfig, BadFieldsAreNamedAndChangeNothing) {
  struct Case {
    const char* field;
    void (*set)(hemm::config::TelemanipConfig*);
  };
  const Case cases[] = {
      {"telemanip.translation_scale", [](hemm::config::TelemanipConfig* c) { c->set_translation_scale(0.0); }},
      {"telemanip.yaw_a_d_deg", [](hemm::config::TelemanipConfig* c) { c->set_yaw_a_d_deg(NAN); }},
      {"telemanip.rotation_scale", [](hemm::config::TelemanipConfig* c) { c->set_rotation_scale(5.0); }},
      {"telemanip.max_speed_mps", [](hemm::config::TelemanipConfig* c) { c->set_max_speed_mps(-1.0); }},
      {"telemanip.command_rate_hz", [](hemm::config::TelemanipConfig* c) { c->set_command_rate_hz(50.0); }},
      {"telemanip.right.deadman_ee", [](hemm::config::TelemanipConfig* c) { c->mutable_right()->set_deadman_ee(2); }},
      {"telemanip.left", [](hemm::config::TelemanipConfig* c) { c->mutable_left()->set_opening_open_m(0.5); }},
      {"telemanip.left.clutch_button", [](hemm::config::TelemanipConfig* c) { c->mutable_left()->set_clutch_button(9); }},
      {"telemanip.right", [](hemm::config::TelemanipConfig* c) { c->mutable_right()->set_force_closed_n(150.0); }},
      {"telemanip.human_script", [](hemm::config::TelemanipConfig* c) { c->set_human_script("dance"); }},
      {"telemanip.mode", [](hemm::config::TelemanipConfig* c) { c->set_mode("Direct"); }},
      {"telemanip.held", [](hemm::config::TelemanipConfig* c) { c->mutable_held()->set_weight_filter_s(0.0); }},
      {"telemanip.held", [](hemm::config::TelemanipConfig* c) { c->mutable_held()->set_stiffness_n_per_m(-300.0); }},
      {"telemanip.held", [](hemm::config::TelemanipConfig* c) { c->mutable_held()->set_coupling_fade_s(NAN); }},
      {"telemanip.direct_fade_s", [](hemm::config::TelemanipConfig* c) {
         c->set_mode("direct");
         c->set_direct_fade_s(0.0);
       }},
  };
  for (const Case& k : cases) {
    hemm::config::TelemanipConfig c;
    c.set_enabled(true);
    k.set(&c);
    tele::TelemanipTaskParams tp;
    tp.budget = 1234;  // a marker: must survive a refusal
    tele::TelemanipLinkParams lp;
    lp.rate_hz = 321.0;
    const std::string e = tele::telemanip_params(c, 1e-3, config_test_limits(), &tp, &lp);
    EXPECT_EQ(e.rfind(k.field, 0), 0u) << k.field << ": " << e;
    EXPECT_EQ(tp.budget, 1234);
    EXPECT_DOUBLE_EQ(lp.rate_hz, 321.0);
  }
  // A one-end-effector device cannot drive two arms.
  hemm::config::TelemanipConfig c;
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  EXPECT_NE(tele::telemanip_params(c, 1e-3, hemm::device::rigid_hand_limits(1), &tp, &lp), "");
}

// The direct mode: no model rendered, each hand's direct parameters from the
// mapping and the device, the passivity block's controller at both the hand
// and the link (the ports' pc_on).
TEST(TelemanipConfig, DirectModeTakesTheMappingTheDeviceAndThePassivityBlock) {
  hemm::config::TelemanipConfig c;
  c.set_enabled(true);
  c.set_mode("direct");
  c.set_yaw_a_d_deg(180.0);
  c.set_translation_scale(2.0);
  c.set_rotation_scale(2.5);
  c.set_direct_fade_s(0.5);
  hemm::config::OperatorPassivityConfig pc;
  pc.set_controller(false);
  const hemm::device::DeviceLimits l = config_test_limits();
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  ASSERT_EQ(tele::telemanip_params(c, 1e-3, l, &tp, &lp, &pc), "");
  EXPECT_EQ(tp.mode, tele::FeedbackMode::kDirect);
  EXPECT_FALSE(tp.render);
  for (int k = 0; k < 2; ++k) {
    const tele::DirectHandParams& d = tp.direct[static_cast<std::size_t>(k)];
    EXPECT_TRUE(d.R_A_D.isApprox(tp.mapping[static_cast<std::size_t>(k)].R_A_D, 1e-15));
    EXPECT_NEAR(d.R_A_D(0, 0), -1.0, 1e-12);
    EXPECT_DOUBLE_EQ(d.translation_scale, 2.0);
    EXPECT_DOUBLE_EQ(d.rotation_scale, 2.5);
    EXPECT_DOUBLE_EQ(tp.mapping[static_cast<std::size_t>(k)].rotation_scale, 2.5);
    EXPECT_DOUBLE_EQ(d.fade_s, 0.5);
    EXPECT_DOUBLE_EQ(d.peak_force_n, l.ee[static_cast<std::size_t>(k)].peak_force);
    EXPECT_EQ(d.renders_torque, l.ee[static_cast<std::size_t>(k)].renders_torque);
    EXPECT_EQ(d.pc_mode, hemm::haptics::tdpa::PcMode::kObserveOnly);
  }
  EXPECT_EQ(lp.pc_mode, hemm::haptics::tdpa::PcMode::kObserveOnly);
  // Without a block: its default, the controller on; the model mode by default.
  c.clear_mode();
  ASSERT_EQ(tele::telemanip_params(c, 1e-3, l, &tp, &lp), "");
  EXPECT_EQ(tp.mode, tele::FeedbackMode::kModel);
  EXPECT_EQ(tp.direct[0].pc_mode, hemm::haptics::tdpa::PcMode::kControl);
  EXPECT_EQ(lp.pc_mode, hemm::haptics::tdpa::PcMode::kControl);
}
