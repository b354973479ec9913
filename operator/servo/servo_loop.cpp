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

#include "common/clock/steady_clock.h"

namespace hemm::servo {
namespace {

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

void log_end_effector(const device::EndEffectorSample& in, const RenderPoints& points,
                      const device::EndEffectorCommand& cmd, ServoLogEndEffector& e) noexcept {
  copy3(in.position_H, e.position);
  e.orientation[0] = in.orientation_H.w();
  e.orientation[1] = in.orientation_H.x();
  e.orientation[2] = in.orientation_H.y();
  e.orientation[3] = in.orientation_H.z();
  copy3(in.velocity_H, e.velocity);
  copy3(in.angular_velocity_H, e.angular_velocity);
  copy3(points.proxy_position_H, e.proxy_position);
  copy3(points.interaction_point_H, e.interaction_point);
  copy3(cmd.force_H, e.force);
  copy3(cmd.torque_H, e.torque);
  e.grip_force = cmd.grip_force;
  const device::HandleInputs& h = in.handle;
  e.buttons = h.buttons;
  e.inputs = device::handle_input_bits(h);
  e.enabled = in.enabled ? 1 : 0;
  e.deadman = h.deadman ? 1 : 0;
  e.switch_on = h.switch_on ? 1 : 0;
  e.attached = h.attached ? 1 : 0;
  e.grip_position = h.grip_position;
  e.grip_velocity = h.grip_velocity;
  e.joystick[0] = h.joystick.x();
  e.joystick[1] = h.joystick.y();
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
      end_effectors_(device.limits().end_effectors),
      stats_(std::make_unique<TimingStats>()) {
  if (config_.period_ns < 100'000 || config_.period_ns > 1'000'000'000)
    throw std::invalid_argument("ServoLoop: period_ns must be in [100 us, 1 s]");
  if (config_.late_wake_threshold_ns <= 0)
    throw std::invalid_argument("ServoLoop: late_wake_threshold_ns must be > 0");
  if (const char* why = device::check_limits(device.limits()))
    throw std::invalid_argument(std::string("ServoLoop: device limits: ") + why);
  if (log_ != nullptr && log_->header() != servo_log_header(end_effectors_))
    throw std::invalid_argument("ServoLoop: the log was made for another end-effector count than the device's " +
                                std::to_string(end_effectors_));
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

void prepare_tick_output(const device::DeviceSample& sample, std::uint64_t tick, TickOutput& out) noexcept {
  const device::EndEffectorSample& ee0 = sample.ee[0];
  out.command = device::DeviceCommand{};
  out.setpoint.t_ns = sample.t_ns;
  out.setpoint.tick = tick;
  out.setpoint.position_H = ee0.position_H;
  out.setpoint.orientation_H = ee0.orientation_H;
  out.setpoint.velocity_H = ee0.velocity_H;
  out.setpoint.buttons = ee0.handle.buttons;
  out.setpoint.mode = 0;
  out.publish_setpoint = true;
  for (int i = 0; i < sample.end_effectors; ++i) {
    const Eigen::Vector3d& p = sample.ee[static_cast<std::size_t>(i)].position_H;
    out.points[static_cast<std::size_t>(i)] = RenderPoints{p, p};
  }
  out.mode = 0;
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
  std::int64_t deadline = steady_now_ns();
  std::int64_t prev_wake = -1;
  std::uint64_t tick = 0;

  while (!stop_.load(std::memory_order_acquire)) {
    deadline += period;
    sleep_until(deadline);
    const std::int64_t wake = steady_now_ns();
    const std::int64_t latency = wake - deadline;

    device_.read(sample);
    sample.t_ns = wake;
    sample.end_effectors = end_effectors_;
    const ModelSnapshot* snap = snapshots_.acquire();
    const ModelSnapshot& model = snap != nullptr ? *snap : empty_snapshot_;

    prepare_tick_output(sample, tick, out);
    task_.tick(sample, model, out);
    device_.write(out.command);
    if (out.publish_setpoint) setpoints_.publish(out.setpoint);

    const std::int64_t done = steady_now_ns();
    if (log_ != nullptr) {
      rec.t_ns = wake;
      rec.tick = tick;
      rec.wake_latency_ns = latency;
      rec.compute_ns = done - wake;
      rec.end_effectors = end_effectors_;
      for (int i = 0; i < end_effectors_; ++i) {
        const auto k = static_cast<std::size_t>(i);
        log_end_effector(sample.ee[k], out.points[k], out.command.ee[k], rec.ee[k]);
      }
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
