// A VPS session's summary JSON (hemm-operator --station-json with a VPS
// scene) is proto/report.proto's VpsSession: it reads back, strictly (no
// unknown keys), into that message with every value and array as it was.
#include "operator/vps/vps_session.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/config/config.h"
#include "operator/vps/vps_config.h"
#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::op {
namespace {

TEST(VpsSessionJson, ReadsBackIntoTheVpsSessionReport) {
  VpsSessionSummary s;
  s.device = "replay";
  s.end_effectors = 2;
  s.objects = 2;
  s.model_bytes = 5'000'000'000ULL;  // past 32 bits
  s.timing.ticks = 2300;
  s.timing.misses = 1;
  s.vps_compute.p99_us = 123.456789012;  // the old writer kept 9 digits
  s.stats.max_work = 912;
  s.stats.max_penetration[2] = 4e-4;
  s.stats.energy_J[1] = -2.5e-7;
  s.coupling_k[0] = 1500.0;
  s.final_rel_01 = {0.001, -0.002, 0.015};
  s.final_object_W[1] = {0.5, 0.25, 1.0 / 3.0};
  s.log_dropped = 3;
  s.log_failed = true;
  s.timing.compute.median_us = std::nan("");  // a summary of nothing
  s.budget.params.tick_ns = 200'000;
  s.budget.stats.ticks = 2300;
  s.budget.stats.stopped_early = 230;
  s.budget.stats.levels[4] = 2070;
  s.budget.stats.levels[2] = 230;
  s.budget.stats.ns_per_unit = 31.25;
  s.budget.calibration.samples = 72;
  const std::string json = to_json(s);
  const report::VpsSession r = test::read_report_json<report::VpsSession>(json);
  EXPECT_EQ(r.device(), "replay");
  EXPECT_EQ(r.objects(), 2);
  EXPECT_EQ(r.model_bytes(), 5'000'000'000ULL);
  EXPECT_EQ(r.ticks(), 2300u);
  EXPECT_EQ(r.misses(), 1u);
  EXPECT_EQ(r.vps_p99_us(), 123.456789012);
  EXPECT_EQ(r.max_work(), 912);
  ASSERT_EQ(r.max_penetration_m_size(), 3);
  EXPECT_EQ(r.max_penetration_m(2), 4e-4);
  ASSERT_EQ(r.energy_j_size(), 2);
  EXPECT_EQ(r.energy_j(1), -2.5e-7);
  EXPECT_EQ(r.coupling_k(0), 1500.0);
  ASSERT_EQ(r.final_rel_01_m_size(), 3);
  EXPECT_EQ(r.final_rel_01_m(2), 0.015);
  EXPECT_EQ(r.final_object1_w(2), 1.0 / 3.0);
  EXPECT_EQ(r.log_dropped(), 3u);
  EXPECT_TRUE(r.log_failed());
  const report::WorkBudget& b = r.budget();
  EXPECT_EQ(b.tick_budget_us(), 200.0);
  EXPECT_EQ(b.work_cap(), 0);  // no cap in units
  EXPECT_EQ(b.stopped_early(), 230u);
  EXPECT_DOUBLE_EQ(b.stopped_early_share(), 0.1);
  ASSERT_EQ(b.levels_completed_size(), vps::kMaxShellLevels + 1);
  EXPECT_EQ(b.levels_completed(2), 230u);
  EXPECT_EQ(b.levels_completed(4), 2070u);
  EXPECT_EQ(b.ns_per_unit(), 31.25);
  EXPECT_EQ(b.calibration_samples(), 72);
  EXPECT_NE(to_string(s).find("230 of 2300 ticks stopped early (10.0 %)"), std::string::npos) << to_string(s);
  // Non-finite numbers print as protobuf's "NaN" and read back as NaN.
  EXPECT_NE(json.find("\"compute_median_us\": \"NaN\""), std::string::npos) << json;
  EXPECT_TRUE(std::isnan(r.compute_median_us()));
}

TEST(VpsConfig, ShippedConfigsRunTheTimeCriticalBudgetAndBadBudgetsAreRefused) {
  for (const char* name : {"operator_vps_peg", "operator_vps_assembly", "operator_vps_omni", "operator_vps_peg_bimanual",
                           "operator_vps_assembly_bimanual"}) {
    const std::string path = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/" + name + ".pbtxt";
    config::OperatorConfig cfg;
    ASSERT_FALSE(config::load_operator_config(path, &cfg)) << path;
    const VpsSetup setup = vps_setup(cfg, path);
    EXPECT_EQ(setup.task.tick_budget_ns, 120'000) << name;
    EXPECT_EQ(setup.task.tick_margin_ns, 100'000) << name;
    EXPECT_EQ(setup.task.budget, vps::kUnlimitedWork) << name;
  }
  // Without the fields: the proto's defaults, a time budget all the same.
  config::OperatorConfig cfg;
  ASSERT_FALSE(config::load_operator_config(std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator_vps_peg.pbtxt", &cfg));
  cfg.mutable_vps()->clear_tick_budget_us();
  EXPECT_EQ(vps_setup(cfg, "x.pbtxt").task.tick_budget_ns, 120'000);
  auto refused = [](config::OperatorConfig c, const std::string& field) {
    try {
      vps_setup(c, "x.pbtxt");
      ADD_FAILURE() << field << ": no error";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field + ":", 0), 0u) << e.what();
    }
  };
  config::OperatorConfig bad = cfg;
  bad.mutable_vps()->set_tick_budget_us(-1);
  refused(bad, "vps.tick_budget_us");
  bad.mutable_vps()->set_tick_budget_us(std::nan(""));
  refused(bad, "vps.tick_budget_us");
  bad = cfg;
  bad.mutable_vps()->set_tick_margin_us(1e9);
  refused(bad, "vps.tick_margin_us");
  bad = cfg;
  bad.mutable_vps()->set_work_budget(-5);
  refused(bad, "vps.work_budget");
}

}  // namespace
}  // namespace hemm::op
