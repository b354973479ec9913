#include "operator/servo/timing_stats.h"

#include <gtest/gtest.h>

namespace hemm::servo {
namespace {

TEST(LatencyHistogram, QuantilesAreBinCentresOfTheRankedSample) {
  LatencyHistogram h;
  EXPECT_EQ(h.quantile_ns(0.5), 0.0);
  // 100 samples: 1..100 us (each in bin i = value/1us).
  for (int i = 1; i <= 100; ++i) h.record(i * 1000 + 300);
  EXPECT_EQ(h.count(), 100u);
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.5), 50'500.0);   // 50th smallest: 50.3 us -> bin 50
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.99), 99'500.0);  // 99th smallest
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.0), 1'500.0);
  EXPECT_EQ(h.max_ns(), 100'300);
  EXPECT_DOUBLE_EQ(h.mean_ns(), 50'500.0 + 300.0);
}

TEST(LatencyHistogram, OverflowReportsExactMaxAndNegativesCountAsZero) {
  LatencyHistogram h;
  h.record(-5);
  h.record(7'000'000);  // 7 ms: beyond the 5 ms range
  EXPECT_EQ(h.bin(0), 1u);
  EXPECT_EQ(h.bin(LatencyHistogram::kBins), 1u);
  EXPECT_DOUBLE_EQ(h.quantile_ns(1.0), 7'000'000.0);
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.5), 500.0);
}

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
  EXPECT_DOUBLE_EQ(t.period.median_us, 1000.5);
  EXPECT_DOUBLE_EQ(t.period.max_us, 1000.0);
  EXPECT_NE(to_string(t).find("misses=2"), std::string::npos);
}

}  // namespace
}  // namespace hemm::servo
