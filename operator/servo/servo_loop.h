// The operator station's 1 kHz servo loop (DESIGN.md principle 2: the servo
// thread is sacred). One thread wakes on an absolute deadline grid
// (clock_nanosleep TIMER_ABSTIME, CLOCK_MONOTONIC) and each tick:
//   reads the device (every end-effector) -> takes the newest model snapshot
//   -> ServoTask::tick -> writes the command (one wrench per end-effector) ->
//   puts the setpoint into a newest-wins mailbox for the network thread ->
//   pushes a log record into a ring -> records timing.
// Inside the loop there is no allocation, no lock, no logging and no system
// call but the sleep (clock_gettime goes through the vDSO). Real-time setup
// (SCHED_FIFO, mlockall, CPU pinning: common/realtime/realtime_setup.h) is
// tried in start() and reported in a RealtimeStatus for the caller to log,
// with the machine's checks (RT throttling, an unisolated pinned CPU, the
// frequency governor); anything refused falls back to a normal thread. A
// tick that ends after the next deadline is an overrun: the missed deadlines
// are skipped (counted), keeping the original grid, rather than run back to
// back. Every tick's wake lateness, compute and period go into log-spaced
// histograms, and the ten worst ticks are kept with what ran in them (the
// task's TickOutput::renderer and work).
//
// The device: start() starts it (HapticDevice::start) before the servo
// thread, with ServoConfig::simulated_hardware: a SIMULATED device then runs
// its hardware on a thread of its own (threaded) or inside write() (lock-step,
// for deterministic tests); stop() stops it after the servo thread.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "common/concurrency/newest_mailbox.h"
#include "common/realtime/realtime_setup.h"
#include "operator/device/haptic_device.h"
#include "operator/device/simulated_hardware.h"
#include "operator/servo/servo_log.h"
#include "operator/servo/snapshot_channel.h"
#include "operator/servo/timing_stats.h"

namespace hemm::servo {

// Base of the immutable model snapshots the model thread publishes for the
// servo thread. The operator's local model derives from it; its tick casts.
struct ModelSnapshot {
  virtual ~ModelSnapshot() = default;
  std::int64_t stamp_ns = 0;  // steady-clock time the model data stands for
  std::uint64_t version = 0;  // 0: the empty snapshot used before any publish
};
using ModelChannel = SnapshotChannel<ModelSnapshot>;

// What the servo thread hands the network side each tick (frame H):
// end-effector 0's pose, velocity and buttons unless the task says otherwise.
struct ServoSetpoint {
  std::int64_t t_ns = 0;
  std::uint64_t tick = 0;
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity_H = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;
  std::uint32_t mode = 0;
};

// Where the task put an end-effector's proxy and interaction point (frame H),
// for the log.
struct RenderPoints {
  Eigen::Vector3d proxy_position_H = Eigen::Vector3d::Zero();
  Eigen::Vector3d interaction_point_H = Eigen::Vector3d::Zero();
};

// Filled by the task. Before tick() the loop resets it: a zero wrench on every
// end-effector, the setpoint copied from end-effector 0 of the device sample,
// proxy and interaction point of each end-effector at its position, mode 0,
// publish_setpoint true, renderer "" and work 0; and it sets deadline_ns.
struct TickOutput {
  device::DeviceCommand command;  // written to the device after the tick
  ServoSetpoint setpoint;
  bool publish_setpoint = true;
  std::array<RenderPoints, device::kMaxEndEffectors> points{};  // logged
  std::uint32_t mode = 0;                                       // logged
  // What ran this tick, for the worst-ticks report: a static name of the
  // renderer ("proxy2d", "point_probe", "tool6", "vps", ...; "" none) and
  // the work units it spent (0: not measured).
  const char* renderer = "";
  std::int64_t work = 0;
  // The next deadline (steady-clock ns): the tick's work must end before it.
  std::int64_t deadline_ns = 0;
};

// The TickOutput the loop hands the task each tick, reset as described above
// (replays of recorded sessions start each tick from the same); deadline_ns
// is left to the caller.
void prepare_tick_output(const device::DeviceSample& sample, std::uint64_t tick, TickOutput& out) noexcept;

class ServoTask {
 public:
  virtual ~ServoTask() = default;
  // On the servo thread, before the first tick and after the last.
  virtual void on_servo_start() noexcept {}
  virtual void on_servo_stop() noexcept {}
  // The force law. Runs at 1 kHz on the servo thread: must not allocate,
  // lock, log, block or make system calls. `in` has in.end_effectors valid
  // end-effectors (the device's count); `model` is the newest published
  // snapshot (version 0 before the first publish).
  virtual void tick(const device::DeviceSample& in, const ModelSnapshot& model,
                    TickOutput& out) noexcept = 0;
};

struct ServoConfig {
  std::int64_t period_ns = 1'000'000;
  bool realtime = true;  // try SCHED_FIFO
  int fifo_priority = 80;
  // mlockall(MCL_CURRENT | MCL_FUTURE), only with CAP_IPC_LOCK or an unlimited
  // RLIMIT_MEMLOCK (a finite limit would make later allocations fail);
  // skipped under sanitizers.
  bool lock_memory = true;
  // Pin the servo thread to this CPU if >= 0 (-1: not pinned); the loop's
  // constructor refuses a CPU this process may not run on (rt::check_cpu).
  int cpu = -1;
  bool prefault_stack = true;  // touch kStackPrefaultBytes of stack before the loop
  std::int64_t late_wake_threshold_ns = 500'000;  // a later wake is a deadline miss
  // How a SIMULATED device runs its hardware (device/simulated_hardware.h):
  // lock-step here (deterministic tests); hemm-operator's configs run it
  // threaded (servo.simulated_hardware). Its thread gets SCHED_FIFO one
  // priority below the servo's when realtime, and no pinning.
  device::HardwareMode simulated_hardware = device::HardwareMode::kLockStep;
};

inline constexpr std::size_t kStackPrefaultBytes = 256 * 1024;

using RealtimeStatus = rt::RealtimeStatus;

class ServoLoop {
 public:
  // All references must outlive the loop. `log` may be null (no log); it
  // must be made for the device's end-effector count (make_servo_logger).
  // Throws std::invalid_argument on a bad config (also a CPU to pin to that
  // this process may not run on), bad device limits or a log for another
  // end-effector count.
  ServoLoop(device::HapticDevice& device, ServoTask& task, ModelChannel& snapshots,
            const ServoConfig& config, ServoLogger* log = nullptr);
  ~ServoLoop();
  ServoLoop(const ServoLoop&) = delete;
  ServoLoop& operator=(const ServoLoop&) = delete;

  // Starts the device (HapticDevice::start) and the servo thread. Throws
  // std::logic_error if already running. May be called again after stop();
  // statistics keep accumulating.
  RealtimeStatus start();
  // Stops and joins the servo thread, then stops the device; undoes mlockall
  // if start() did it. Idempotent.
  void stop();
  bool running() const noexcept { return thread_.joinable(); }

  const TimingStats& stats() const noexcept { return *stats_; }
  // The loop's timing with its set-up (period, threshold, the real-time
  // status of the last start) and, if the device ran its simulated hardware
  // threaded, that thread's timing beside it.
  TimingSummary summary() const;
  // Consumer side (one thread, e.g. the network thread).
  NewestMailbox<ServoSetpoint>& setpoints() noexcept { return setpoints_; }
  // From the network side: copied into each log record.
  void set_link_stats(std::int64_t rtt_ns, std::int64_t offset_ns) noexcept {
    link_rtt_ns_.store(rtt_ns, std::memory_order_relaxed);
    link_offset_ns_.store(offset_ns, std::memory_order_relaxed);
  }
  const ServoConfig& config() const noexcept { return config_; }

 private:
  void thread_main() noexcept;

  device::HapticDevice& device_;
  ServoTask& task_;
  ModelChannel& snapshots_;
  ServoConfig config_;
  ServoLogger* log_;
  int end_effectors_;  // the device's, fixed for the loop's life
  std::unique_ptr<TimingStats> stats_;  // ~120 kB: on the heap, allocated here
  NewestMailbox<ServoSetpoint> setpoints_;
  ModelSnapshot empty_snapshot_;
  std::atomic<std::int64_t> link_rtt_ns_{-1}, link_offset_ns_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> go_{false};
  void release_process_realtime() noexcept;  // undoes start()'s mlockall and wake-latency hold
  bool locked_memory_ = false;
  int wake_latency_fd_ = -1;  // rt::hold_cpu_wake_latency while running (realtime)
  RealtimeStatus last_status_;  // of the last start()
  std::thread thread_;
};

}  // namespace hemm::servo
