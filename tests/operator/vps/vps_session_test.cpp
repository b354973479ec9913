// A VPS session's summary JSON (hemm-operator --station-json with a VPS
// scene) is proto/report.proto's VpsSession: it reads back, strictly (no
// unknown keys), into that message with every value and array as it was.
#include "operator/vps/vps_session.h"

#include <gtest/gtest.h>

#include <cmath>

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
  // Non-finite numbers print as protobuf's "NaN" and read back as NaN.
  EXPECT_NE(json.find("\"compute_median_us\": \"NaN\""), std::string::npos) << json;
  EXPECT_TRUE(std::isnan(r.compute_median_us()));
}

}  // namespace
}  // namespace hemm::op
