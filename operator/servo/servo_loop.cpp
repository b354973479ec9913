#include "operator/servo/servo_loop.h"

#include <pthread.h>

#include <stdexcept>

#include "common/clock/steady_clock.h"

namespace hemm::servo {
namespace {

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
  if (auto why = rt::check_cpu(config_.cpu)) throw std::invalid_argument("ServoLoop: cpu: " + *why);
  if (const char* why = device::check_limits(device.limits()))
    throw std::invalid_argument(std::string("ServoLoop: device limits: ") + why);
  if (log_ != nullptr && log_->header() != servo_log_header(end_effectors_))
    throw std::invalid_argument("ServoLoop: the log was made for another end-effector count than the device's " +
                                std::to_string(end_effectors_));
}

ServoLoop::~ServoLoop() { stop(); }

void ServoLoop::release_process_realtime() noexcept {
  if (locked_memory_) rt::unlock_memory();
  locked_memory_ = false;
  rt::release_cpu_wake_latency(wake_latency_fd_);
  wake_latency_fd_ = -1;
}

RealtimeStatus ServoLoop::start() {
  if (thread_.joinable()) throw std::logic_error("ServoLoop: already running");
  RealtimeStatus status;
  if (config_.lock_memory) locked_memory_ = rt::lock_memory(&status);
  if (config_.realtime) wake_latency_fd_ = rt::hold_cpu_wake_latency(&status);
  // The device first: a SIMULATED one may start its hardware thread (below
  // the servo's priority, not pinned: the servo's CPU is the servo's).
  device::HardwareStart how;
  how.mode = config_.simulated_hardware;
  how.realtime.fifo = config_.realtime;
  how.realtime.fifo_priority = config_.fifo_priority > 1 ? config_.fifo_priority - 1 : 1;
  try {
    device_.start(how, &status.warnings);
  } catch (...) {
    release_process_realtime();
    throw;
  }
  stop_.store(false, std::memory_order_relaxed);
  go_.store(false, std::memory_order_relaxed);
  try {
    thread_ = std::thread([this] { thread_main(); });
  } catch (...) {
    device_.stop();
    release_process_realtime();
    throw;
  }
  pthread_setname_np(thread_.native_handle(), "hemm-servo");
  rt::apply_thread_realtime(thread_, rt::RealtimeRequest{config_.realtime, config_.fifo_priority, config_.cpu},
                            &status);
  for (std::string& w : rt::system_checks(status.fifo, status.pinned ? status.cpu : -1))
    status.warnings.push_back(std::move(w));
  last_status_ = status;
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
  device_.stop();
  release_process_realtime();
}

TimingSummary ServoLoop::summary() const {
  TimingSummary t = summarize(*stats_);
  t.period_target_us = static_cast<double>(config_.period_ns) * 1e-3;
  t.late_wake_threshold_us = static_cast<double>(config_.late_wake_threshold_ns) * 1e-3;
  t.fifo = last_status_.fifo;
  t.memory_locked = last_status_.memory_locked;
  t.wake_latency_held = last_status_.wake_latency_held;
  t.cpu = last_status_.pinned ? last_status_.cpu : -1;
  if (const device::SimulatedHardwareStats* hw = device_.simulated_hardware()) {
    SimulatedHardwareSummary h;
    h.device = std::string(device_.name());
    h.mode = device::to_string(device::HardwareMode::kThreaded);  // only a threaded start makes these
    h.timing = summarize(hw->timing);
    h.sample_age = summarize(hw->sample_age);
    h.commands_new = hw->commands_new.load(std::memory_order_relaxed);
    h.commands_held = hw->commands_held.load(std::memory_order_relaxed);
    t.hardware = std::move(h);
  }
  return t;
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
  out.renderer = "";
  out.work = 0;
}

void ServoLoop::thread_main() noexcept {
  go_.wait(false, std::memory_order_acquire);
  if (config_.prefault_stack) prefault_stack();
  task_.on_servo_start();

  TimingStats& st = *stats_;
  device::DeviceSample sample;
  TickOutput out;
  ServoLogRecord rec;
  rt::DeadlineGrid grid(config_.period_ns, steady_now_ns());
  std::uint64_t tick = 0;

  while (!stop_.load(std::memory_order_acquire)) {
    const std::int64_t wake = grid.wait();
    const std::int64_t latency = wake - grid.deadline();

    device_.read(sample);
    sample.t_ns = wake;
    sample.end_effectors = end_effectors_;
    const ModelSnapshot* snap = snapshots_.acquire();
    const ModelSnapshot& model = snap != nullptr ? *snap : empty_snapshot_;

    prepare_tick_output(sample, tick, out);
    out.deadline_ns = grid.next_deadline();
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

    // Timing (single writer): histograms, worst ticks, misses; skips the
    // deadlines already past after an overrun.
    grid.finish(st, wake, done, tick, out.renderer, out.work, config_.late_wake_threshold_ns);
    ++tick;
  }
  task_.on_servo_stop();
}

}  // namespace hemm::servo
