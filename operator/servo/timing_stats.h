// Timing statistics of the servo loop: fixed-size histograms (1 us bins up to
// 5 ms, plus an overflow bin) written by the servo thread without allocating
// or locking, readable from any thread at any time. Every counter is an
// atomic written by one thread only (plain load + store, no read-modify-write),
// so readers see each counter exactly, though not all counters of one tick at
// once; summaries taken while the loop runs may straddle a tick.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

namespace hemm::report {
class ServoTiming;  // report.pb.h
}

namespace hemm::servo {

class LatencyHistogram {
 public:
  static constexpr int kBins = 5000;              // bin i holds [i, i+1) us
  static constexpr std::int64_t kBinWidthNs = 1000;

  // Writer side (one thread). Negative values count as 0.
  void record(std::int64_t ns) noexcept {
    if (ns < 0) ns = 0;
    const std::int64_t b = ns / kBinWidthNs;
    const int i = b >= kBins ? kBins : static_cast<int>(b);
    bump(bins_[i]);
    bump(count_);
    sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + static_cast<std::uint64_t>(ns),
                  std::memory_order_relaxed);
    if (ns > max_ns_.load(std::memory_order_relaxed)) max_ns_.store(ns, std::memory_order_relaxed);
  }

  std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  std::int64_t max_ns() const noexcept { return max_ns_.load(std::memory_order_relaxed); }
  double mean_ns() const noexcept;
  // The q-quantile (0 <= q <= 1) as the centre of its bin, in ns; the exact
  // maximum if it falls in the overflow bin; 0 when empty.
  double quantile_ns(double q) const noexcept;
  std::uint64_t bin(int i) const noexcept { return bins_[i].load(std::memory_order_relaxed); }

 private:
  static void bump(std::atomic<std::uint64_t>& c) noexcept {
    c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
  std::array<std::atomic<std::uint64_t>, kBins + 1> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::uint64_t> sum_ns_{0};
  std::atomic<std::int64_t> max_ns_{0};
};

struct TimingStats {
  LatencyHistogram wake_latency;  // actual wake - deadline
  LatencyHistogram compute;       // wake -> end of the tick's work
  LatencyHistogram period;        // wake - previous wake
  std::atomic<std::uint64_t> ticks{0};
  std::atomic<std::uint64_t> late_wakes{0};       // wake latency > threshold
  std::atomic<std::uint64_t> overruns{0};         // tick work ended after the next deadline
  std::atomic<std::uint64_t> misses{0};           // ticks with a late wake or an overrun
  std::atomic<std::uint64_t> skipped_periods{0};  // deadlines dropped to catch up
};

struct HistogramSummary {
  std::uint64_t count = 0;
  double median_us = 0, p99_us = 0, max_us = 0, mean_us = 0;
};

struct TimingSummary {
  std::uint64_t ticks = 0, late_wakes = 0, overruns = 0, misses = 0, skipped_periods = 0;
  HistogramSummary wake_latency, compute, period;
};

HistogramSummary summarize(const LatencyHistogram& h);
TimingSummary summarize(const TimingStats& s);
// One line for logs: "ticks=... misses=... wake median/p99/max=... us ...".
std::string to_string(const TimingSummary& s);
// The summary as the "timing" object of the operator's run reports
// (proto/report.proto's ServoTiming).
void fill(report::ServoTiming* out, const TimingSummary& s);

}  // namespace hemm::servo
