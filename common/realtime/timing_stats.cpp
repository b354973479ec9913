#include "common/realtime/timing_stats.h"

#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <limits>

#include "common/clock/steady_clock.h"
#include "report.pb.h"

namespace hemm::rt {

// ---------------------------------------------------------------- LogHistogram

int LogHistogram::bin_of(std::int64_t ns) noexcept {
  if (ns < kUnitNs) return 0;
  const auto us = static_cast<std::uint64_t>(ns / kUnitNs);  // >= 1
  const int k = 63 - __builtin_clzll(us);                      // floor(log2(ns / 1 us))
  if (k >= kOctaves) return kBins - 1;
  const std::int64_t base = kUnitNs << k;
  const auto j = static_cast<int>(((ns - base) * kSubBins) / base);
  return 1 + k * kSubBins + j;
}

double LogHistogram::lower_ns(int i) noexcept {
  if (i <= 0) return 0.0;
  if (i >= kBins - 1) return std::ldexp(static_cast<double>(kUnitNs), kOctaves);
  const int k = (i - 1) / kSubBins, j = (i - 1) % kSubBins;
  return std::ldexp(static_cast<double>(kUnitNs) * (kSubBins + j) / kSubBins, k);
}

double LogHistogram::upper_ns(int i) noexcept {
  if (i >= kBins - 1) return std::numeric_limits<double>::infinity();
  return lower_ns(i + 1);
}

double LogHistogram::mean_ns() const noexcept {
  const std::uint64_t n = count();
  return n == 0 ? 0.0 : static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / static_cast<double>(n);
}

double LogHistogram::quantile_ns(double q) const noexcept {
  // Sum the bins rather than trusting count_: while the writer runs they may
  // disagree by a tick.
  std::uint64_t total = 0;
  for (const auto& b : bins_) total += b.load(std::memory_order_relaxed);
  if (total == 0) return 0.0;
  q = q < 0.0 ? 0.0 : (q > 1.0 ? 1.0 : q);
  std::uint64_t rank = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(total)));
  if (rank == 0) rank = 1;
  const double max = static_cast<double>(max_ns());
  std::uint64_t cum = 0;
  for (int i = 0; i < kBins; ++i) {
    cum += bin(i);
    if (cum >= rank) {
      if (i == kBins - 1) return max;
      return std::min(0.5 * (lower_ns(i) + upper_ns(i)), max);
    }
  }
  return max;
}

// ---------------------------------------------------------------- WorstTicks

WorstTick WorstTicks::load(int i) const noexcept {
  const Slot& s = heap_[static_cast<std::size_t>(i)];
  WorstTick t;
  t.tick = s.tick.load(std::memory_order_relaxed);
  t.wake_latency_ns = s.wake_latency_ns.load(std::memory_order_relaxed);
  t.compute_ns = s.compute_ns.load(std::memory_order_relaxed);
  t.what = s.what.load(std::memory_order_relaxed);
  t.work = s.work.load(std::memory_order_relaxed);
  return t;
}

void WorstTicks::store(int i, const WorstTick& t) noexcept {
  Slot& s = heap_[static_cast<std::size_t>(i)];
  s.tick.store(t.tick, std::memory_order_relaxed);
  s.wake_latency_ns.store(t.wake_latency_ns, std::memory_order_relaxed);
  s.compute_ns.store(t.compute_ns, std::memory_order_relaxed);
  s.what.store(t.what != nullptr ? t.what : "", std::memory_order_relaxed);
  s.work.store(t.work, std::memory_order_relaxed);
}

void WorstTicks::offer(const WorstTick& t) noexcept {
  int n = size_.load(std::memory_order_relaxed);
  const std::int64_t key = t.response_ns();
  auto key_at = [this](int i) {
    const Slot& s = heap_[static_cast<std::size_t>(i)];
    return s.wake_latency_ns.load(std::memory_order_relaxed) + s.compute_ns.load(std::memory_order_relaxed);
  };
  if (n < kSize) {
    // Sift up from the new leaf.
    int i = n;
    while (i > 0) {
      const int parent = (i - 1) / 2;
      if (key_at(parent) <= key) break;
      store(i, load(parent));
      i = parent;
    }
    store(i, t);
    size_.store(n + 1, std::memory_order_release);
    return;
  }
  if (key <= key_at(0)) return;  // not among the worst: the common case, one comparison
  // Replace the root (the least bad kept) and sift down.
  int i = 0;
  for (;;) {
    const int l = 2 * i + 1, r = l + 1;
    int smallest = i;
    std::int64_t smallest_key = key;
    if (l < n && key_at(l) < smallest_key) {
      smallest = l;
      smallest_key = key_at(l);
    }
    if (r < n && key_at(r) < smallest_key) smallest = r;
    if (smallest == i) break;
    store(i, load(smallest));
    i = smallest;
  }
  store(i, t);
}

std::vector<WorstTick> WorstTicks::sorted() const {
  const int n = size_.load(std::memory_order_acquire);
  std::vector<WorstTick> v;
  v.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) v.push_back(load(i));
  std::sort(v.begin(), v.end(), [](const WorstTick& a, const WorstTick& b) {
    return a.response_ns() != b.response_ns() ? a.response_ns() > b.response_ns() : a.tick < b.tick;
  });
  return v;
}

// ---------------------------------------------------------------- recording

namespace {
void bump(std::atomic<std::uint64_t>& c, std::uint64_t by = 1) noexcept {
  c.store(c.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
}
}  // namespace

bool record_tick(TimingStats& s, const TickTiming& t) noexcept {
  const std::int64_t latency = t.wake_ns - t.deadline_ns;
  const std::int64_t compute = t.done_ns - t.wake_ns;
  s.wake_latency.record(latency);
  s.compute.record(compute);
  if (t.prev_wake_ns >= 0) s.period.record(t.wake_ns - t.prev_wake_ns);
  s.worst.offer(WorstTick{t.tick, latency, compute, t.what, t.work});
  const bool late = latency > t.late_wake_threshold_ns;
  const bool overrun = t.done_ns >= t.deadline_ns + t.period_ns;
  if (late) bump(s.late_wakes);
  if (overrun) bump(s.overruns);
  if (late || overrun) bump(s.misses);
  s.ticks.store(s.ticks.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  return late || overrun;
}

void sleep_until_ns(std::int64_t t_ns) noexcept {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

std::int64_t DeadlineGrid::wait() noexcept {
  deadline_ += period_;
  sleep_until_ns(deadline_);
  return steady_now_ns();
}

bool DeadlineGrid::finish(TimingStats& s, std::int64_t wake, std::int64_t done, std::uint64_t tick, const char* what,
                          std::int64_t work, std::int64_t late_wake_threshold_ns) noexcept {
  TickTiming t;
  t.deadline_ns = deadline_;
  t.wake_ns = wake;
  t.prev_wake_ns = prev_wake_;
  t.done_ns = done;
  t.period_ns = period_;
  t.late_wake_threshold_ns = late_wake_threshold_ns;
  t.tick = tick;
  t.what = what;
  t.work = work;
  prev_wake_ = wake;
  const bool miss = record_tick(s, t);
  if (done >= deadline_ + period_) {
    // Skip the deadlines already past, staying on the grid.
    const std::int64_t k = (done - deadline_) / period_;
    deadline_ += k * period_;
    bump(s.skipped_periods, static_cast<std::uint64_t>(k));
  }
  return miss;
}

// ---------------------------------------------------------------- summaries

HistogramSummary summarize(const LogHistogram& h) {
  HistogramSummary s;
  s.count = h.count();
  s.median_us = h.quantile_ns(0.5) * 1e-3;
  s.p99_us = h.quantile_ns(0.99) * 1e-3;
  s.p999_us = h.quantile_ns(0.999) * 1e-3;
  s.max_us = static_cast<double>(h.max_ns()) * 1e-3;
  s.mean_us = h.mean_ns() * 1e-3;
  for (int i = 0; i < LogHistogram::kBins; ++i) {
    const std::uint64_t n = h.bin(i);
    if (n == 0) continue;
    const bool overflow = i == LogHistogram::kBins - 1;
    s.bins.push_back({LogHistogram::lower_ns(i) * 1e-3, overflow ? s.max_us : LogHistogram::upper_ns(i) * 1e-3, n});
  }
  return s;
}

TimingSummary summarize(const TimingStats& s) {
  TimingSummary t;
  t.ticks = s.ticks.load(std::memory_order_acquire);
  t.late_wakes = s.late_wakes.load(std::memory_order_relaxed);
  t.overruns = s.overruns.load(std::memory_order_relaxed);
  t.misses = s.misses.load(std::memory_order_relaxed);
  t.skipped_periods = s.skipped_periods.load(std::memory_order_relaxed);
  t.wake_latency = summarize(s.wake_latency);
  t.compute = summarize(s.compute);
  t.period = summarize(s.period);
  t.worst = s.worst.sorted();
  return t;
}

std::string to_string(const TimingSummary& s) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "ticks=%llu misses=%llu (late_wakes=%llu overruns=%llu skipped_periods=%llu) "
                "wake median/p99/max=%.1f/%.1f/%.1f us compute median/p99/max=%.1f/%.1f/%.1f us "
                "period median/p99/max=%.1f/%.1f/%.1f us",
                static_cast<unsigned long long>(s.ticks), static_cast<unsigned long long>(s.misses),
                static_cast<unsigned long long>(s.late_wakes), static_cast<unsigned long long>(s.overruns),
                static_cast<unsigned long long>(s.skipped_periods), s.wake_latency.median_us, s.wake_latency.p99_us,
                s.wake_latency.max_us, s.compute.median_us, s.compute.p99_us, s.compute.max_us, s.period.median_us,
                s.period.p99_us, s.period.max_us);
  return buf;
}

std::string worst_ticks_text(const std::vector<WorstTick>& worst) {
  std::string out;
  char buf[160];
  for (const WorstTick& w : worst) {
    std::snprintf(buf, sizeof buf, "%s#%llu wake %+.0f compute %.0f us", out.empty() ? "" : "; ",
                  static_cast<unsigned long long>(w.tick), static_cast<double>(w.wake_latency_ns) * 1e-3,
                  static_cast<double>(w.compute_ns) * 1e-3);
    out += buf;
    if (w.what != nullptr && *w.what != '\0') out += std::string(" ") + w.what;
    if (w.work != 0) out += " work " + std::to_string(w.work);
  }
  return out.empty() ? "none" : out;
}

void fill(report::LatencyHistogram* j, const HistogramSummary& h) {
  j->set_count(h.count);
  j->set_median(h.median_us);
  j->set_p99(h.p99_us);
  j->set_max(h.max_us);
  j->set_mean(h.mean_us);
  j->set_p999(h.p999_us);
  for (const HistogramBin& b : h.bins) {
    j->add_bin_lower(b.lower_us);
    j->add_bin_upper(b.upper_us);
    j->add_bin_count(b.count);
  }
}

void fill(report::ServoTiming* t, const TimingSummary& s) {
  t->set_ticks(s.ticks);
  t->set_misses(s.misses);
  t->set_overruns(s.overruns);
  t->set_late_wakes(s.late_wakes);
  t->set_skipped_periods(s.skipped_periods);
  fill(t->mutable_period_us(), s.period);
  fill(t->mutable_wake_latency_us(), s.wake_latency);
  fill(t->mutable_compute_us(), s.compute);
  t->set_period_target_us(s.period_target_us);
  t->set_late_wake_threshold_us(s.late_wake_threshold_us);
  t->set_fifo(s.fifo);
  t->set_memory_locked(s.memory_locked);
  t->set_wake_latency_held(s.wake_latency_held);
  t->set_cpu(s.cpu);
  for (const WorstTick& w : s.worst) {
    report::WorstTick* r = t->add_worst_ticks();
    r->set_tick(w.tick);
    r->set_wake_latency_us(static_cast<double>(w.wake_latency_ns) * 1e-3);
    r->set_compute_us(static_cast<double>(w.compute_ns) * 1e-3);
    r->set_renderer(w.what != nullptr ? w.what : "");
    r->set_work(w.work);
  }
}

}  // namespace hemm::rt
