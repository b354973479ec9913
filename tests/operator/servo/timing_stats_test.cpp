// The servo loop's timing summary: the loop's figures (common/realtime, tested
// there against closed forms) and, beside them, a SIMULATED device's hardware
// thread's, in the log line and in proto/report.proto's ServoTiming.
#include "operator/servo/timing_stats.h"

#include <gtest/gtest.h>

#include "report.pb.h"

namespace hemm::servo {
namespace {

TEST(TimingStats, SummaryCopiesCountersAndConvertsToMicroseconds) {
  TimingStats s;
  s.ticks = 10;
  s.misses = 2;
  s.late_wakes = 1;
  s.overruns = 1;
  s.skipped_periods = 3;
  for (int i = 0; i < 10; ++i) s.period.record(1'000'000);
  const TimingSummary t = summarize(s);
  EXPECT_EQ(t.ticks, 10u);
  EXPECT_EQ(t.misses, 2u);
  EXPECT_EQ(t.skipped_periods, 3u);
  // 1 ms lies in the log-spaced bin [1000, 1004) us (its centre, 1002, is
  // above the maximum, so the quantiles are the maximum).
  EXPECT_DOUBLE_EQ(t.period.median_us, 1000.0);
  EXPECT_DOUBLE_EQ(t.period.max_us, 1000.0);
  ASSERT_EQ(t.period.bins.size(), 1u);
  EXPECT_EQ(t.period.bins[0].lower_us, 1000.0);
  EXPECT_EQ(t.period.bins[0].upper_us, 1004.0);
  EXPECT_EQ(t.period.bins[0].count, 10u);
  EXPECT_NE(to_string(t).find("misses=2"), std::string::npos);
  EXPECT_EQ(to_string(t).find("simulated hardware"), std::string::npos);
  EXPECT_FALSE(t.hardware);
}

TEST(TimingStats, TheSimulatedHardwareIsReportedBesideTheLoop) {
  TimingStats loop, hw;
  for (int i = 0; i < 4; ++i) loop.compute.record(20'000);
  loop.ticks = 4;
  for (int i = 0; i < 3; ++i) hw.compute.record(45'000);
  hw.ticks = 3;
  hw.misses = 1;
  TimingSummary t = summarize(loop);
  SimulatedHardwareSummary h;
  h.device = "simulated-bimanual-lwr";
  h.mode = "threaded";
  h.timing = summarize(hw);
  h.commands_new = 2;
  h.commands_held = 1;
  t.hardware = h;
  const std::string line = to_string(t);
  EXPECT_NE(line.find("simulated hardware (simulated-bimanual-lwr, threaded): steps=3 misses=1"), std::string::npos)
      << line;
  report::ServoTiming r;
  fill(&r, t);
  EXPECT_EQ(r.ticks(), 4u);
  ASSERT_TRUE(r.has_simulated_hardware());
  EXPECT_EQ(r.simulated_hardware().device(), "simulated-bimanual-lwr");
  EXPECT_EQ(r.simulated_hardware().mode(), "threaded");
  EXPECT_EQ(r.simulated_hardware().timing().ticks(), 3u);
  EXPECT_EQ(r.simulated_hardware().timing().misses(), 1u);
  EXPECT_EQ(r.simulated_hardware().timing().compute_us().max(), 45.0);
  EXPECT_EQ(r.simulated_hardware().commands_new(), 2u);
  EXPECT_EQ(r.simulated_hardware().commands_held(), 1u);
  report::ServoTiming none;
  fill(&none, summarize(loop));
  EXPECT_FALSE(none.has_simulated_hardware());
}

}  // namespace
}  // namespace hemm::servo
