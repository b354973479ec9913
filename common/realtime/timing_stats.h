// Deadline statistics of a periodic real-time loop (the operator's 1 kHz
// servo loop, a SIMULATED device's hardware thread, the robot station's
// 1 kHz control loop): log-spaced histograms of wake lateness, compute and
// period, the loop's miss counters, and the ten worst ticks with what ran in
// them. Written by the loop's own thread without allocating, locking or
// making system calls; readable from any thread at any time. Every counter is
// an atomic written by one thread only (plain load + store, no
// read-modify-write), so a reader sees each counter exactly, though not all
// counters of one tick at once: a summary taken while the loop runs may
// straddle a tick (and a worst tick being replaced may read torn).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace hemm::report {
class LatencyHistogram;  // report.pb.h
class ServoTiming;
}  // namespace hemm::report

namespace hemm::rt {

// Durations in ns in log-spaced bins (HdrHistogram-style): bin 0 holds
// [0, 1 us); each octave of microseconds [2^k, 2^(k+1)) us, k = 0..kOctaves-1,
// is split into kSubBins equal bins, so a bin is 1/128 to 1/256 of its value
// wide (8 us just above the 1 ms period: a p99 tells 1.096 from 1.104 ms,
// either side of the 1.1 ms target); the last bin holds everything from
// 2^kOctaves us (~1.05 s) up. The edges are exact integers of ns from 16 us
// up (bin_of is integer arithmetic). ~20 kB a histogram.
class LogHistogram {
 public:
  static constexpr int kOctaves = 20;
  static constexpr int kSubBins = 128;
  static constexpr int kBins = 2 + kOctaves * kSubBins;  // with the [0, 1 us) and overflow bins
  static constexpr std::int64_t kUnitNs = 1000;

  // The bin of a duration (negative: bin 0).
  static int bin_of(std::int64_t ns) noexcept;
  // Bin i covers [lower_ns(i), upper_ns(i)); the overflow bin's upper is +inf.
  static double lower_ns(int i) noexcept;
  static double upper_ns(int i) noexcept;

  // Writer side (one thread). Negative values count as 0.
  void record(std::int64_t ns) noexcept {
    if (ns < 0) ns = 0;
    bump(bins_[static_cast<std::size_t>(bin_of(ns))]);
    bump(count_);
    sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + static_cast<std::uint64_t>(ns), std::memory_order_relaxed);
    if (ns > max_ns_.load(std::memory_order_relaxed)) max_ns_.store(ns, std::memory_order_relaxed);
  }

  std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  std::int64_t max_ns() const noexcept { return max_ns_.load(std::memory_order_relaxed); }
  double mean_ns() const noexcept;
  // The q-quantile (0 <= q <= 1) of the recorded values, in ns: the centre
  // of the bin holding the ceil(q n)-th smallest value (at least the 1st),
  // never above the exact maximum (so also the maximum for the overflow
  // bin); 0 when empty.
  double quantile_ns(double q) const noexcept;
  std::uint64_t bin(int i) const noexcept { return bins_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed); }

 private:
  static void bump(std::atomic<std::uint64_t>& c) noexcept {
    c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
  std::array<std::atomic<std::uint64_t>, kBins> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::uint64_t> sum_ns_{0};
  std::atomic<std::int64_t> max_ns_{0};
};

// One tick among the worst: when it ran, how late it woke, how long its work
// took, and what ran in it (a static name, "" if the loop does not say, and
// the work units it spent, 0: not measured).
struct WorstTick {
  std::uint64_t tick = 0;
  std::int64_t wake_latency_ns = 0;
  std::int64_t compute_ns = 0;
  const char* what = "";
  std::int64_t work = 0;
  // The tick's output came this late after its deadline: the ranking key.
  std::int64_t response_ns() const noexcept { return wake_latency_ns + compute_ns; }
};

// The kSize ticks with the largest response (wake lateness + compute: how
// long after its deadline the tick's output was ready), in a fixed-size
// min-heap: offer() is one comparison with the heap's root while a tick is
// not among them, a sift-down of at most log2(kSize) levels when it is.
// Writer: one thread; no allocation.
class WorstTicks {
 public:
  static constexpr int kSize = 10;
  void offer(const WorstTick& t) noexcept;
  // Reader side: the kept ticks, worst first (allocates).
  std::vector<WorstTick> sorted() const;

 private:
  struct Slot {
    std::atomic<std::uint64_t> tick{0};
    std::atomic<std::int64_t> wake_latency_ns{0}, compute_ns{0}, work{0};
    std::atomic<const char*> what{""};
  };
  WorstTick load(int i) const noexcept;
  void store(int i, const WorstTick& t) noexcept;
  std::array<Slot, kSize> heap_{};
  std::atomic<int> size_{0};
};

struct TimingStats {
  LogHistogram wake_latency;  // actual wake - deadline
  LogHistogram compute;       // wake -> end of the tick's work
  LogHistogram period;        // wake - previous wake
  std::atomic<std::uint64_t> ticks{0};
  std::atomic<std::uint64_t> late_wakes{0};       // wake latency > threshold
  std::atomic<std::uint64_t> overruns{0};         // tick work ended after the next deadline
  std::atomic<std::uint64_t> misses{0};           // ticks with a late wake or an overrun
  std::atomic<std::uint64_t> skipped_periods{0};  // deadlines dropped to catch up
  WorstTicks worst;
};

// What one tick did, for record_tick.
struct TickTiming {
  std::int64_t deadline_ns = 0;   // when it should have woken
  std::int64_t wake_ns = 0;       // when it did
  std::int64_t prev_wake_ns = -1; // the previous tick's wake (-1: the first tick)
  std::int64_t done_ns = 0;       // when its work ended
  std::int64_t period_ns = 0;
  std::int64_t late_wake_threshold_ns = 500'000;
  std::uint64_t tick = 0;
  const char* what = "";
  std::int64_t work = 0;
};
// Records one tick (histograms, worst ticks, late wake, overrun: its work
// ended at or after the next deadline, deadline + period) and counts it.
// Returns whether it was a miss (late wake or overrun). Writer thread only.
bool record_tick(TimingStats& s, const TickTiming& t) noexcept;

// An absolute deadline grid (CLOCK_MONOTONIC, the steady clock): a loop
// waits for each deadline with clock_nanosleep(TIMER_ABSTIME), so sleep
// errors never accumulate. A tick whose work ran past the next deadline
// skips the deadlines already past (counted in TimingStats::skipped_periods),
// keeping the grid, rather than running ticks back to back.
class DeadlineGrid {
 public:
  // The first deadline is one period after origin_ns.
  DeadlineGrid(std::int64_t period_ns, std::int64_t origin_ns) noexcept : period_(period_ns), deadline_(origin_ns) {}
  // Advances to the next deadline and sleeps until it; returns the wake time.
  std::int64_t wait() noexcept;
  std::int64_t deadline() const noexcept { return deadline_; }           // the one just waited for
  std::int64_t next_deadline() const noexcept { return deadline_ + period_; }
  std::int64_t period() const noexcept { return period_; }
  // Ends the tick that woke at `wake` and finished at `done`: records it
  // (record_tick) and skips the deadlines already past. Returns whether it
  // was a miss.
  bool finish(TimingStats& s, std::int64_t wake, std::int64_t done, std::uint64_t tick, const char* what = "",
              std::int64_t work = 0, std::int64_t late_wake_threshold_ns = 500'000) noexcept;

 private:
  std::int64_t period_;
  std::int64_t deadline_;
  std::int64_t prev_wake_ = -1;
};

// Sleeps until t_ns of the steady clock (absolute; restarts on signals).
void sleep_until_ns(std::int64_t t_ns) noexcept;

struct HistogramBin {
  double lower_us = 0, upper_us = 0;  // upper: +inf for the overflow bin
  std::uint64_t count = 0;
};

struct HistogramSummary {
  std::uint64_t count = 0;
  double median_us = 0, p99_us = 0, max_us = 0, mean_us = 0;
  double p999_us = 0;
  std::vector<HistogramBin> bins{};  // the non-empty bins, in order
};

struct TimingSummary {
  std::uint64_t ticks = 0, late_wakes = 0, overruns = 0, misses = 0, skipped_periods = 0;
  HistogramSummary wake_latency, compute, period;
  std::vector<WorstTick> worst;  // worst first
  // The loop's set-up (filled by its owner; summarize leaves them).
  double period_target_us = 0, late_wake_threshold_us = 0;
  bool fifo = false, memory_locked = false, wake_latency_held = false;
  int cpu = -1;
};

HistogramSummary summarize(const LogHistogram& h);
TimingSummary summarize(const TimingStats& s);
// One line for logs: "ticks=... misses=... wake median/p99/max=... us ...".
std::string to_string(const TimingSummary& s);
// The worst ticks on one line ("#123 wake +12 compute 800 us vps work 3456; #...").
std::string worst_ticks_text(const std::vector<WorstTick>& worst);
// As proto/report.proto's messages (the JSON of --station-json through
// config::to_json).
void fill(report::LatencyHistogram* out, const HistogramSummary& h);
void fill(report::ServoTiming* out, const TimingSummary& s);

}  // namespace hemm::rt
