// The deadline statistics of the real-time loops against closed forms: the
// log-spaced bins' edges and the bin of known values, quantiles of a known
// sample, the worst-ten tracker on a known permutation, the miss counting and
// the deadline grid's skipping, and the writer side allocating nothing.
#include "common/realtime/timing_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "common/clock/steady_clock.h"
#include "report.pb.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::rt {
namespace {

using H = LogHistogram;

TEST(LogHistogram, BinsAreOneHundredTwentyEightPerOctaveOfMicroseconds) {
  EXPECT_EQ(H::kBins, 2 + 20 * 128);
  EXPECT_EQ(H::bin_of(-5), 0);
  EXPECT_EQ(H::bin_of(0), 0);
  EXPECT_EQ(H::bin_of(999), 0);
  EXPECT_EQ(H::bin_of(1000), 1);
  // [1, 2) us in 128 bins of 7.8125 ns: the second starts at 1007.8125 ns.
  EXPECT_EQ(H::bin_of(1007), 1);
  EXPECT_EQ(H::bin_of(1008), 2);
  EXPECT_DOUBLE_EQ(H::lower_ns(2), 1007.8125);
  EXPECT_EQ(H::bin_of(1999), 128);
  EXPECT_EQ(H::bin_of(2000), 129);
  // 1 ms: octave [512, 1024) us of 4 us bins; 1000 us is in [1000, 1004).
  EXPECT_EQ(H::bin_of(1'000'000), 1 + 9 * 128 + 122);
  EXPECT_DOUBLE_EQ(H::lower_ns(1 + 9 * 128 + 122), 1'000'000.0);
  EXPECT_DOUBLE_EQ(H::upper_ns(1 + 9 * 128 + 122), 1'004'000.0);
  // 1.1 ms (the period target): octave [1024, 2048) us of 8 us bins, so
  // 1095.999 us and 1.1 ms fall in neighbouring bins [1088, 1096), [1096, 1104).
  EXPECT_EQ(H::bin_of(1'095'999), 1 + 10 * 128 + 8);
  EXPECT_EQ(H::bin_of(1'100'000), 1 + 10 * 128 + 9);
  EXPECT_DOUBLE_EQ(H::lower_ns(1 + 10 * 128 + 9), 1'096'000.0);
  // The last regular bin ends at 2^20 us; then the overflow bin.
  EXPECT_EQ(H::bin_of((1000LL << 20) - 1), H::kBins - 2);
  EXPECT_EQ(H::bin_of(1000LL << 20), H::kBins - 1);
  EXPECT_EQ(H::bin_of(1'000'000'000'000LL), H::kBins - 1);
  EXPECT_TRUE(std::isinf(H::upper_ns(H::kBins - 1)));
  // Every bin from 16 us up has integer edges, holds its lower edge and the
  // nanosecond before its upper one, and is 1/256 to 1/128 of its value wide.
  for (int i = 1 + 4 * 128; i < H::kBins - 1; ++i) {
    const double lo = H::lower_ns(i), hi = H::upper_ns(i);
    ASSERT_EQ(lo, std::floor(lo)) << i;
    EXPECT_EQ(H::bin_of(static_cast<std::int64_t>(lo)), i);
    EXPECT_EQ(H::bin_of(static_cast<std::int64_t>(hi) - 1), i);
    EXPECT_GE((hi - lo) / lo, 1.0 / 256 - 1e-12);
    EXPECT_LE((hi - lo) / lo, 1.0 / 128 + 1e-12);
  }
}

TEST(LogHistogram, QuantilesOfAKnownSampleAreTheirBinsCentres) {
  H h;
  EXPECT_EQ(h.quantile_ns(0.5), 0.0);
  for (int i = 1; i <= 1000; ++i) h.record(i * 1000LL);  // 1 us .. 1 ms
  EXPECT_EQ(h.count(), 1000u);
  // 500th smallest = 500 us, in [500, 502) us.
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.5), 501'000.0);
  // 990th smallest = 990 us, in [988, 992) us.
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.99), 990'000.0);
  // The smallest: 1 us, in [1, 1.0078125) us.
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.0), 1003.90625);
  // The largest, 1 ms, in [1000, 1004) us: the centre would be above the
  // maximum, so the maximum.
  EXPECT_DOUBLE_EQ(h.quantile_ns(1.0), 1'000'000.0);
  EXPECT_EQ(h.max_ns(), 1'000'000);
  EXPECT_DOUBLE_EQ(h.mean_ns(), 500'500.0);
}

TEST(LogHistogram, AQuantileIsNeverAboveTheMaximumAndOverflowIsTheMaximum) {
  H h;
  h.record(5000);  // in [5000, 5031.25): the centre would be 5015.625
  EXPECT_DOUBLE_EQ(h.quantile_ns(0.5), 5000.0);
  H o;
  o.record(100);
  o.record(3'000'000'000LL);  // 3 s: the overflow bin
  EXPECT_EQ(o.bin(0), 1u);
  EXPECT_EQ(o.bin(H::kBins - 1), 1u);
  EXPECT_DOUBLE_EQ(o.quantile_ns(1.0), 3e9);
  EXPECT_DOUBLE_EQ(o.quantile_ns(0.5), 500.0);  // [0, 1 us): centre 0.5 us
}

TEST(WorstTicks, KeepsTheTenLargestResponsesWorstFirst) {
  WorstTicks w;
  EXPECT_TRUE(w.sorted().empty());
  static const char* kNames[3] = {"proxy2d", "vps", "tool6"};
  // Responses (wake + compute) 0..99 us in the order i * 37 mod 100.
  for (std::uint64_t i = 0; i < 100; ++i) {
    const std::int64_t r = static_cast<std::int64_t>((i * 37) % 100) * 1000;
    w.offer(WorstTick{i, r / 4, r - r / 4, kNames[i % 3], static_cast<std::int64_t>(i)});
  }
  const std::vector<WorstTick> v = w.sorted();
  ASSERT_EQ(v.size(), 10u);
  for (std::size_t k = 0; k < v.size(); ++k) {
    const std::int64_t want = (99 - static_cast<std::int64_t>(k)) * 1000;
    EXPECT_EQ(v[k].response_ns(), want) << k;
    // The tick i with i * 37 = want (mod 100): i = want * 73 (mod 100), 37 * 73 = 2701.
    const std::uint64_t tick = static_cast<std::uint64_t>((want / 1000) * 73 % 100);
    EXPECT_EQ(v[k].tick, tick);
    EXPECT_STREQ(v[k].what, kNames[tick % 3]);
    EXPECT_EQ(v[k].work, static_cast<std::int64_t>(tick));
    EXPECT_EQ(v[k].wake_latency_ns, want / 4);
  }
}

TEST(WorstTicks, FewerThanTenAreAllKeptAndTiesKeepTheFirst) {
  WorstTicks w;
  w.offer({1, 0, 5, "a", 0});
  w.offer({2, 0, 9, "b", 0});
  w.offer({3, 0, 7, "", 0});
  std::vector<WorstTick> v = w.sorted();
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(v[0].tick, 2u);
  EXPECT_EQ(v[1].tick, 3u);
  EXPECT_EQ(v[2].tick, 1u);
  WorstTicks t;
  for (std::uint64_t i = 0; i < 20; ++i) t.offer({i, 0, 100, "", 0});
  v = t.sorted();
  ASSERT_EQ(v.size(), 10u);
  for (std::size_t k = 0; k < 10; ++k) EXPECT_EQ(v[k].tick, k);  // equal responses do not displace
}

TEST(RecordTick, CountsLateWakesOverrunsAndMisses) {
  TimingStats s;
  TickTiming t;
  t.period_ns = 1'000'000;
  t.late_wake_threshold_ns = 500'000;
  t.deadline_ns = 0;
  t.wake_ns = 10'000;
  t.done_ns = 60'000;
  EXPECT_FALSE(record_tick(s, t));  // on time
  t.prev_wake_ns = t.wake_ns;
  t.deadline_ns = 1'000'000;
  t.wake_ns = 1'600'000;  // 600 us late
  t.done_ns = 1'700'000;
  EXPECT_TRUE(record_tick(s, t));
  t.prev_wake_ns = t.wake_ns;
  t.deadline_ns = 2'000'000;
  t.wake_ns = 2'010'000;
  t.done_ns = 3'000'000;  // ends at the next deadline: an overrun
  EXPECT_TRUE(record_tick(s, t));
  const TimingSummary sum = summarize(s);
  EXPECT_EQ(sum.ticks, 3u);
  EXPECT_EQ(sum.late_wakes, 1u);
  EXPECT_EQ(sum.overruns, 1u);
  EXPECT_EQ(sum.misses, 2u);
  EXPECT_EQ(sum.period.count, 2u);  // the first tick has no period
  EXPECT_EQ(sum.wake_latency.max_us, 600.0);
  EXPECT_EQ(sum.compute.max_us, 990.0);
  ASSERT_EQ(sum.worst.size(), 3u);
  EXPECT_EQ(sum.worst[0].response_ns(), 1'000'000);  // 10 us late + 990 us
  // The non-empty bins add up to the count.
  std::uint64_t n = 0;
  for (const HistogramBin& b : sum.compute.bins) n += b.count;
  EXPECT_EQ(n, 3u);
}

TEST(DeadlineGrid, AnOverrunSkipsTheDeadlinesAlreadyPastKeepingTheGrid) {
  TimingStats s;
  DeadlineGrid g(1'000'000, 0);
  EXPECT_EQ(g.deadline(), 0);
  EXPECT_EQ(g.next_deadline(), 1'000'000);
  // Woke on time, worked until 2.5 periods later: deadlines 1 and 2 ms are past.
  EXPECT_TRUE(g.finish(s, 10, 2'500'000, 0, "vps", 42));
  EXPECT_EQ(g.deadline(), 2'000'000);
  EXPECT_EQ(g.next_deadline(), 3'000'000);
  EXPECT_EQ(s.skipped_periods.load(), 2u);
  EXPECT_EQ(s.overruns.load(), 1u);
  const std::vector<WorstTick> w = s.worst.sorted();
  ASSERT_EQ(w.size(), 1u);
  EXPECT_STREQ(w[0].what, "vps");
  EXPECT_EQ(w[0].work, 42);
}

TEST(DeadlineGrid, WaitsForAbsoluteDeadlines) {
  const std::int64_t t0 = steady_now_ns();
  DeadlineGrid g(2'000'000, t0);
  TimingStats s;
  for (int k = 0; k < 5; ++k) {
    const std::int64_t wake = g.wait();
    EXPECT_GE(wake, t0 + (k + 1) * 2'000'000);  // never early
    g.finish(s, wake, wake, static_cast<std::uint64_t>(k));
  }
  EXPECT_EQ(s.ticks.load(), 5u);
}

TEST(TimingStats, TheWriterSideAllocatesNothing) {
  TimingStats s;
  DeadlineGrid g(1'000'000, 0);
  test::count_allocations_on_this_thread(true);
  std::int64_t wake = 0;
  for (int k = 0; k < 20'000; ++k) {
    wake += 1'000'000 + (k % 97) * 1000;
    g.finish(s, wake, wake + (k * 7919) % 400'000, static_cast<std::uint64_t>(k), "proxy2d", k);
  }
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(test::counted_allocations(), 0u);
  EXPECT_EQ(test::counted_frees(), 0u);
  EXPECT_EQ(s.ticks.load(), 20'000u);
  EXPECT_EQ(s.worst.sorted().size(), 10u);
}

TEST(TimingSummary, FillsTheReportWithBinsAndWorstTicks) {
  TimingStats s;
  TickTiming a;
  a.period_ns = 1'000'000;
  a.wake_ns = 5'000;
  a.done_ns = 105'000;
  a.what = "point_probe";
  a.work = 7;
  record_tick(s, a);
  TickTiming b = a;
  b.tick = 1;
  b.prev_wake_ns = a.wake_ns;
  b.deadline_ns = 1'000'000;
  b.wake_ns = 1'003'000;
  b.done_ns = 1'050'000;
  b.what = "";
  b.work = 0;
  record_tick(s, b);
  TimingSummary t = summarize(s);
  t.period_target_us = 1000;
  t.cpu = 1;
  t.fifo = true;
  report::ServoTiming r;
  fill(&r, t);
  EXPECT_EQ(r.ticks(), 2u);
  EXPECT_EQ(r.cpu(), 1);
  EXPECT_TRUE(r.fifo());
  EXPECT_EQ(r.period_target_us(), 1000.0);
  ASSERT_EQ(r.worst_ticks_size(), 2);
  EXPECT_EQ(r.worst_ticks(0).renderer(), "point_probe");
  EXPECT_EQ(r.worst_ticks(0).work(), 7);
  EXPECT_EQ(r.worst_ticks(0).compute_us(), 100.0);
  EXPECT_EQ(r.worst_ticks(0).wake_latency_us(), 5.0);
  // compute: 100 us and 47 us, two bins.
  ASSERT_EQ(r.compute_us().bin_count_size(), 2);
  EXPECT_EQ(r.compute_us().bin_lower_size(), 2);
  EXPECT_EQ(r.compute_us().bin_upper_size(), 2);
  EXPECT_LE(r.compute_us().bin_lower(0), 47.0);
  EXPECT_GT(r.compute_us().bin_upper(0), 47.0);
  EXPECT_LE(r.compute_us().bin_lower(1), 100.0);
  EXPECT_GT(r.compute_us().bin_upper(1), 100.0);
  EXPECT_EQ(r.compute_us().bin_count(0) + r.compute_us().bin_count(1), 2u);
  EXPECT_NE(worst_ticks_text(t.worst).find("#0 wake +5 compute 100 us point_probe work 7"), std::string::npos)
      << worst_ticks_text(t.worst);
}

}  // namespace
}  // namespace hemm::rt
