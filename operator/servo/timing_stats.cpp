#include "operator/servo/timing_stats.h"

#include <cmath>
#include <cstdio>

#include "report.pb.h"

namespace hemm::servo {

double LatencyHistogram::mean_ns() const noexcept {
  const std::uint64_t n = count();
  return n == 0 ? 0.0
                : static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) /
                      static_cast<double>(n);
}

double LatencyHistogram::quantile_ns(double q) const noexcept {
  // Sum the bins rather than trusting count_: while the writer runs they may
  // disagree by a tick.
  std::uint64_t total = 0;
  for (const auto& b : bins_) total += b.load(std::memory_order_relaxed);
  if (total == 0) return 0.0;
  q = q < 0.0 ? 0.0 : (q > 1.0 ? 1.0 : q);
  std::uint64_t rank = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(total)));
  if (rank == 0) rank = 1;
  std::uint64_t cum = 0;
  for (int i = 0; i <= kBins; ++i) {
    cum += bins_[i].load(std::memory_order_relaxed);
    if (cum >= rank) {
      if (i == kBins) return static_cast<double>(max_ns());
      return (static_cast<double>(i) + 0.5) * static_cast<double>(kBinWidthNs);
    }
  }
  return static_cast<double>(max_ns());
}

HistogramSummary summarize(const LatencyHistogram& h) {
  HistogramSummary s;
  s.count = h.count();
  s.median_us = h.quantile_ns(0.5) * 1e-3;
  s.p99_us = h.quantile_ns(0.99) * 1e-3;
  s.max_us = static_cast<double>(h.max_ns()) * 1e-3;
  s.mean_us = h.mean_ns() * 1e-3;
  return s;
}

TimingSummary summarize(const TimingStats& s) {
  TimingSummary t;
  t.ticks = s.ticks.load(std::memory_order_relaxed);
  t.late_wakes = s.late_wakes.load(std::memory_order_relaxed);
  t.overruns = s.overruns.load(std::memory_order_relaxed);
  t.misses = s.misses.load(std::memory_order_relaxed);
  t.skipped_periods = s.skipped_periods.load(std::memory_order_relaxed);
  t.wake_latency = summarize(s.wake_latency);
  t.compute = summarize(s.compute);
  t.period = summarize(s.period);
  return t;
}

std::string to_string(const TimingSummary& s) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "ticks=%llu misses=%llu (late_wakes=%llu overruns=%llu skipped_periods=%llu) "
                "wake median/p99/max=%.1f/%.1f/%.1f us compute median/p99/max=%.1f/%.1f/%.1f us "
                "period median/p99/max=%.1f/%.1f/%.1f us",
                static_cast<unsigned long long>(s.ticks), static_cast<unsigned long long>(s.misses),
                static_cast<unsigned long long>(s.late_wakes),
                static_cast<unsigned long long>(s.overruns),
                static_cast<unsigned long long>(s.skipped_periods), s.wake_latency.median_us,
                s.wake_latency.p99_us, s.wake_latency.max_us, s.compute.median_us, s.compute.p99_us,
                s.compute.max_us, s.period.median_us, s.period.p99_us, s.period.max_us);
  return buf;
}

namespace {
void fill(report::LatencyHistogram* j, const HistogramSummary& h) {
  j->set_count(h.count);
  j->set_median(h.median_us);
  j->set_p99(h.p99_us);
  j->set_max(h.max_us);
  j->set_mean(h.mean_us);
}
}  // namespace

void fill(report::ServoTiming* t, const TimingSummary& s) {
  t->set_ticks(s.ticks);
  t->set_misses(s.misses);
  t->set_overruns(s.overruns);
  t->set_late_wakes(s.late_wakes);
  t->set_skipped_periods(s.skipped_periods);
  fill(t->mutable_period_us(), s.period);
  fill(t->mutable_wake_latency_us(), s.wake_latency);
  fill(t->mutable_compute_us(), s.compute);
}

}  // namespace hemm::servo
