// The robot stations' 1 kHz control-loop pacing, one piece for the mobile
// robot's RobotStation and the two-arm TwoArmStation: absolute deadlines of
// the steady clock (step k simulates [anchor + k dt, anchor + (k+1) dt] and
// runs once that interval is over, so no state is stamped later than it is
// sent), the skip ahead after a stall longer than max_catch_up_ns (catching
// up step by step would only replay the past faster than real time), and the
// lateness counters and tick histograms. Allocation-free, no lock, no log:
// the caller's control thread owns it; the counters are atomics any thread
// reads.
#pragma once

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <utility>

#include "common/clock/steady_clock.h"
#include "common/realtime/realtime_setup.h"
#include "common/realtime/timing_stats.h"

namespace hemm::robot {

// Written by the control thread, read by statistics() on any thread.
struct PacingCounters {
  std::atomic<uint64_t> late_steps{0};  // steps started more than one period after their deadline
  std::atomic<uint64_t> resyncs{0};     // skips ahead after a stall
  std::atomic<uint64_t> lateness_n{0};
  std::atomic<int64_t> max_lateness_ns{0}, lateness_sum_ns{0};
  rt::TimingStats timing;  // wake, compute and period histograms (record_tick)

  double mean_lateness_ns() const noexcept {
    const uint64_t n = lateness_n.load();
    return n ? static_cast<double>(lateness_sum_ns.load()) / static_cast<double>(n) : 0.0;
  }
};

// Starts the control thread running `body` with the real-time request
// (SCHED_FIFO, CPU pin, the CPU wake-latency hold while FIFO: released by
// rt::release_cpu_wake_latency(*wake_latency_fd) after the join), gathers
// the system's warnings into `status` and logs them and the outcome
// (event=control_thread, with kind=<log_kind> unless it is empty).
template <class Body>
void start_control_thread(std::thread& thread, Body body, const rt::RealtimeRequest& request,
                          rt::RealtimeStatus* status, int* wake_latency_fd, const char* log_kind) {
  *status = rt::RealtimeStatus{};
  if (request.fifo) *wake_latency_fd = rt::hold_cpu_wake_latency(status);
  thread = std::thread(std::move(body));
  rt::apply_thread_realtime(thread, request, status);
  for (std::string& w : rt::system_checks(status->fifo, status->pinned ? request.cpu : -1))
    status->warnings.push_back(std::move(w));
  for (const std::string& w : status->warnings) spdlog::warn("event=control_realtime warning=\"{}\"", w);
  const int cpu = status->pinned ? status->cpu : -1;
  if (*log_kind) {
    spdlog::info("event=control_thread kind={} fifo={} cpu={}", log_kind, status->fifo, cpu);
  } else {
    spdlog::info("event=control_thread fifo={} cpu={}", status->fifo, cpu);
  }
}

// The loop's timing summary as both stations report it.
inline rt::TimingSummary pacing_summary(const PacingCounters& c, int64_t period_ns, int64_t late_wake_threshold_ns,
                                        const rt::RealtimeStatus& status) {
  rt::TimingSummary s = rt::summarize(c.timing);
  s.period_target_us = static_cast<double>(period_ns) * 1e-3;
  s.late_wake_threshold_us = static_cast<double>(late_wake_threshold_ns) * 1e-3;
  s.fifo = status.fifo;
  s.wake_latency_held = status.wake_latency_held;
  s.cpu = status.pinned ? status.cpu : -1;
  return s;
}

class ControlPacer {
 public:
  ControlPacer(int64_t period_ns, int64_t max_catch_up_ns, int64_t late_wake_threshold_ns, int64_t anchor_ns) noexcept
      : dt_(period_ns), max_catch_up_ns_(max_catch_up_ns), anchor_(anchor_ns) {
    tick_.period_ns = period_ns;
    tick_.late_wake_threshold_ns = late_wake_threshold_ns;
  }

  // Sleeps until the next step's deadline and counts its lateness. Returns
  // the lateness when it skipped ahead after a stall (then anchor_ns() is
  // now less one period: the caller moves its clock there), else 0.
  int64_t wait(PacingCounters& c) noexcept {
    int64_t resync_late = 0;
    const int64_t deadline = anchor_ + (k_ + 1) * dt_;
    rt::sleep_until_ns(deadline);
    tick_.deadline_ns = deadline;
    tick_.wake_ns = steady_now_ns();
    int64_t late = tick_.wake_ns - deadline;
    if (late > max_catch_up_ns_) {
      anchor_ = steady_now_ns() - dt_;
      k_ = 0;
      c.resyncs.fetch_add(1, std::memory_order_relaxed);
      resync_late = late;
    }
    if (late > dt_) c.late_steps.fetch_add(1, std::memory_order_relaxed);
    if (late > c.max_lateness_ns.load(std::memory_order_relaxed)) c.max_lateness_ns.store(late);
    late = std::max<int64_t>(late, 0);
    c.lateness_sum_ns.fetch_add(late, std::memory_order_relaxed);
    c.lateness_n.fetch_add(1, std::memory_order_relaxed);
    return resync_late;
  }

  // One step done (paced or not): the next deadline is one period later.
  void stepped() noexcept { ++k_; }

  // After a paced step's work: records the tick (what it did: "step",
  // "state", ...).
  void record(PacingCounters& c) noexcept {
    tick_.done_ns = steady_now_ns();
    rt::record_tick(c.timing, tick_);
    tick_.prev_wake_ns = tick_.wake_ns;
    ++tick_.tick;
  }

  void set_what(const char* what) noexcept { tick_.what = what; }
  int64_t anchor_ns() const noexcept { return anchor_; }

 private:
  int64_t dt_;
  int64_t max_catch_up_ns_;
  int64_t anchor_;
  int64_t k_ = 0;  // steps since the anchor
  rt::TickTiming tick_;
};

}  // namespace hemm::robot
