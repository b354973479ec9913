#include "operator/servo/servo_loop.h"

#include <linux/capability.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace hemm::servo {
namespace {

std::int64_t now_ns() noexcept {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);  // vDSO: no kernel entry
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void sleep_until(std::int64_t t_ns) noexcept {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

// Touches the stack pages the loop may use so the first ticks take no page
// faults (with mlockall they then stay resident).
__attribute__((noinline)) void prefault_stack() noexcept {
  volatile unsigned char buf[kStackPrefaultBytes];
  for (std::size_t i = 0; i < sizeof buf; i += 4096) buf[i] = 0;
}

void copy3(const Eigen::Vector3d& v, double* out) noexcept {
  out[0] = v.x();
  out[1] = v.y();
  out[2] = v.z();
}

std::string errno_text(int e) { return std::strerror(e); }

#ifndef HEMM_SANITIZE
// mlockall(MCL_FUTURE) under a finite RLIMIT_MEMLOCK is a trap: it succeeds
// while the process is small and then makes later mappings (thread stacks,
// large allocations anywhere in the process) fail. Lock only when nothing
// limits it: CAP_IPC_LOCK in the calling thread's effective set, or an
// unlimited RLIMIT_MEMLOCK.
bool memory_lock_unlimited(std::string* why) {
  __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct caps[2]{};
  if (syscall(SYS_capget, &hdr, caps) == 0 &&
      (caps[CAP_TO_INDEX(CAP_IPC_LOCK)].effective & CAP_TO_MASK(CAP_IPC_LOCK)) != 0)
    return true;
  rlimit lim{};
  if (getrlimit(RLIMIT_MEMLOCK, &lim) == 0 && lim.rlim_cur == RLIM_INFINITY) return true;
  *why = "mlockall skipped: no CAP_IPC_LOCK and RLIMIT_MEMLOCK is " +
         std::to_string(static_cast<unsigned long long>(lim.rlim_cur)) +
         " bytes (locking future memory would make later allocations fail)";
  return false;
}
#endif

}  // namespace

ServoLoop::ServoLoop(device::HapticDevice& device, ServoTask& task, ModelChannel& snapshots,
                     const ServoConfig& config, ServoLogger* log)
    : device_(device),
      task_(task),
      snapshots_(snapshots),
      config_(config),
      log_(log),
      stats_(std::make_unique<TimingStats>()) {
  if (config_.period_ns < 100'000 || config_.period_ns > 1'000'000'000)
    throw std::invalid_argument("ServoLoop: period_ns must be in [100 us, 1 s]");
  if (config_.late_wake_threshold_ns <= 0)
    throw std::invalid_argument("ServoLoop: late_wake_threshold_ns must be > 0");
}

ServoLoop::~ServoLoop() { stop(); }

RealtimeStatus ServoLoop::start() {
  if (thread_.joinable()) throw std::logic_error("ServoLoop: already running");
  RealtimeStatus status;
  if (config_.lock_memory) {
#ifdef HEMM_SANITIZE
    // The sanitizers reserve terabytes of shadow memory: locking it all fails
    // or takes the machine down.
    status.warnings.push_back("mlockall skipped: sanitizer build");
#else
    std::string why;
    if (!memory_lock_unlimited(&why)) {
      status.warnings.push_back(why);
    } else if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      status.memory_locked = true;
      locked_memory_ = true;
    } else {
      status.warnings.push_back("mlockall failed (" + errno_text(errno) +
                                "): servo memory may page out");
    }
#endif
  }
  stop_.store(false, std::memory_order_relaxed);
  go_.store(false, std::memory_order_relaxed);
  try {
    thread_ = std::thread([this] { thread_main(); });
  } catch (...) {
    if (locked_memory_) {
      munlockall();
      locked_memory_ = false;
    }
    throw;
  }
  pthread_setname_np(thread_.native_handle(), "hemm-servo");
  if (config_.realtime) {
    sched_param sp{};
    const int lo = sched_get_priority_min(SCHED_FIFO), hi = sched_get_priority_max(SCHED_FIFO);
    sp.sched_priority = config_.fifo_priority < lo ? lo : (config_.fifo_priority > hi ? hi : config_.fifo_priority);
    const int rc = pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &sp);
    if (rc == 0) {
      status.fifo = true;
    } else {
      status.warnings.push_back("SCHED_FIFO refused (" + errno_text(rc) +
                                "): servo runs as a normal thread");
    }
  }
  if (config_.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (config_.cpu < CPU_SETSIZE) CPU_SET(config_.cpu, &set);
    const int rc = pthread_setaffinity_np(thread_.native_handle(), sizeof set, &set);
    if (rc == 0 && config_.cpu < CPU_SETSIZE) {
      status.pinned = true;
    } else {
      status.warnings.push_back("pinning to CPU " + std::to_string(config_.cpu) + " failed (" +
                                errno_text(rc == 0 ? EINVAL : rc) + ")");
    }
  }
  // Release the thread only once its scheduling is set up.
  go_.store(true, std::memory_order_release);
  go_.notify_one();
  return status;
}

void ServoLoop::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true, std::memory_order_release);
  go_.store(true, std::memory_order_release);  // in case start() threw before releasing it
  go_.notify_one();
  thread_.join();
  if (locked_memory_) {
    munlockall();
    locked_memory_ = false;
  }
}

void ServoLoop::thread_main() noexcept {
  go_.wait(false, std::memory_order_acquire);
  if (config_.prefault_stack) prefault_stack();
  task_.on_servo_start();

  TimingStats& st = *stats_;
  const std::int64_t period = config_.period_ns;
  device::DeviceSample sample;
  TickOutput out;
  ServoLogRecord rec;
  std::int64_t deadline = now_ns();
  std::int64_t prev_wake = -1;
  std::uint64_t tick = 0;

  while (!stop_.load(std::memory_order_acquire)) {
    deadline += period;
    sleep_until(deadline);
    const std::int64_t wake = now_ns();
    const std::int64_t latency = wake - deadline;

    device_.read(sample);
    sample.t_ns = wake;
    const ModelSnapshot* snap = snapshots_.acquire();
    const ModelSnapshot& model = snap != nullptr ? *snap : empty_snapshot_;

    out.force_H.setZero();
    out.setpoint.t_ns = wake;
    out.setpoint.tick = tick;
    out.setpoint.position_H = sample.position_H;
    out.setpoint.orientation_H = sample.orientation_H;
    out.setpoint.velocity_H = sample.velocity_H;
    out.setpoint.buttons = sample.buttons;
    out.setpoint.mode = 0;
    out.publish_setpoint = true;
    out.proxy_position_H = sample.position_H;
    out.interaction_point_H = sample.position_H;
    out.mode = 0;
    task_.tick(sample, model, out);
    device_.write(out.force_H);
    if (out.publish_setpoint) setpoints_.put(out.setpoint);

    const std::int64_t done = now_ns();
    if (log_ != nullptr) {
      rec.t_ns = wake;
      rec.tick = tick;
      rec.wake_latency_ns = latency;
      rec.compute_ns = done - wake;
      copy3(sample.position_H, rec.device_position);
      copy3(sample.velocity_H, rec.device_velocity);
      copy3(out.proxy_position_H, rec.proxy_position);
      copy3(out.interaction_point_H, rec.interaction_point);
      copy3(out.force_H, rec.force);
      rec.buttons = sample.buttons;
      rec.mode = out.mode;
      rec.model_age_ns = snap != nullptr ? wake - model.stamp_ns : -1;
      rec.model_version = model.version;
      rec.link_rtt_ns = link_rtt_ns_.load(std::memory_order_relaxed);
      rec.link_offset_ns = link_offset_ns_.load(std::memory_order_relaxed);
      log_->push(rec);
    }

    // Timing: single writer, so plain load+store on the atomics.
    st.wake_latency.record(latency);
    st.compute.record(done - wake);
    if (prev_wake >= 0) st.period.record(wake - prev_wake);
    prev_wake = wake;
    const bool late = latency > config_.late_wake_threshold_ns;
    const bool overrun = done >= deadline + period;
    if (late) st.late_wakes.store(st.late_wakes.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    if (overrun) {
      st.overruns.store(st.overruns.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      // Skip the deadlines already past, staying on the grid.
      const std::int64_t k = (done - deadline) / period;
      deadline += k * period;
      st.skipped_periods.store(st.skipped_periods.load(std::memory_order_relaxed) +
                                   static_cast<std::uint64_t>(k),
                               std::memory_order_relaxed);
    }
    if (late || overrun)
      st.misses.store(st.misses.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    ++tick;
    st.ticks.store(tick, std::memory_order_release);
  }
  task_.on_servo_stop();
}

}  // namespace hemm::servo
