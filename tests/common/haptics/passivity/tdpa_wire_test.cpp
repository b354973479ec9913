// The TDPA's edge: PassivityPort out and back, hostile ports refused with
// the output untouched, and the configs' passivity blocks.
#include "common/haptics/passivity/tdpa_wire.h"

#include <limits>

#include <gtest/gtest.h>

#include "common/config/config.h"
#include "config_operator.pb.h"
#include "config_robot.pb.h"
#include "wire.pb.h"

namespace {

namespace td = hemm::haptics::tdpa;

TEST(TdpaWire, PortRoundTripAndHostilePorts) {
  td::ArmSide s;
  s.in_J << 1, 2, 3, 4, 5, 6;
  s.out_J << 0.5, 0, 0, 0, 0, 0.25;
  s.dissipated_J << 0.1, 0.2, 0, 0, 0, 0;
  s.pc_active_ticks = 17;
  hemm::wire::PassivityPort port;
  td::fill(&port, 1, s, td::PcMode::kControl);
  EXPECT_EQ(port.index(), 1u);
  EXPECT_TRUE(port.pc_on());
  EXPECT_EQ(port.pc_active_ticks(), 17u);
  EXPECT_DOUBLE_EQ(port.dissipated_j(), 0.3);
  ASSERT_EQ(port.energy_out_j_size(), 6);
  EXPECT_EQ(port.energy_out_j(5), 0.25);
  td::Vec6 e = td::Vec6::Constant(-7);
  std::string why;
  ASSERT_TRUE(td::read_energy_in(port, &e, &why)) << why;
  EXPECT_EQ(e, s.in_J);

  const td::Vec6 before = td::Vec6::Constant(-7);
  for (int bad = 0; bad < 3; ++bad) {
    hemm::wire::PassivityPort p = port;
    if (bad == 0) p.mutable_energy_in_j()->RemoveLast();
    if (bad == 1) p.set_energy_in_j(2, std::numeric_limits<double>::infinity());
    if (bad == 2) p.set_energy_in_j(4, -1.0);
    td::Vec6 out = before;
    why.clear();
    EXPECT_FALSE(td::read_energy_in(p, &out, &why)) << bad;
    EXPECT_FALSE(why.empty());
    EXPECT_EQ(out, before);
  }
}

TEST(TdpaWire, ConfigBlocks) {
  hemm::config::OperatorPassivityConfig c;
  // The config's defaults are the documented thresholds.
  const td::ModeThresholds t = td::thresholds_from(c), d;
  EXPECT_DOUBLE_EQ(t.max_direct_rtt_s, d.max_direct_rtt_s);
  EXPECT_DOUBLE_EQ(t.max_direct_loss, d.max_direct_loss);
  EXPECT_DOUBLE_EQ(t.hysteresis, d.hysteresis);
  EXPECT_EQ(td::pc_mode_from(c), td::PcMode::kControl);
  c.set_controller(false);
  EXPECT_EQ(td::pc_mode_from(c), td::PcMode::kObserveOnly);
  // Bad values are refused by the operator config's validator, field by field.
  hemm::config::OperatorConfig op;
  EXPECT_TRUE(hemm::config::validate_operator_config(op).empty());
  op.mutable_passivity()->set_max_direct_rtt_ms(-1);
  op.mutable_passivity()->set_max_direct_loss(1.5);
  op.mutable_passivity()->set_hysteresis(std::numeric_limits<double>::quiet_NaN());
  const auto issues = hemm::config::validate_operator_config(op);
  ASSERT_EQ(issues.size(), 3u);
  EXPECT_EQ(issues[0].field, "passivity.max_direct_rtt_ms");
  EXPECT_EQ(issues[1].field, "passivity.max_direct_loss");
  EXPECT_EQ(issues[2].field, "passivity.hysteresis");
  hemm::config::RobotPassivityConfig r;
  EXPECT_EQ(td::pc_mode_from(r), td::PcMode::kControl);
}

}  // namespace
