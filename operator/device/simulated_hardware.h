// Where a SIMULATED device's hardware runs (DESIGN.md, "Threads of the
// operator station"): what stands in for hardware (the Omni's mechanism and
// the hand holding it; the bimanual device's MuJoCo plant and its human) runs
// either
//  - HardwareMode::kThreaded: on a thread of its own at its own period, as a
//    real device's controller runs on its own board; it exchanges timestamped
//    samples and commands with the device backend's read() / write() on the
//    servo thread through newest-wins mailboxes (common/concurrency), as a
//    driver would, so the servo tick measures hemm's own work only and never
//    waits on the simulation. The shipped configurations run this way
//    (servo.simulated_hardware "threaded", the default); or
//  - HardwareMode::kLockStep: stepped one servo period inside every write(),
//    on the calling thread: deterministic and tick-locked, for the tests and
//    benchmarks that replay a run exactly (the servo tick then includes the
//    simulation's cost). A device is in lock-step until the servo loop starts
//    it threaded, and again after it stops.
// The hardware thread keeps its own deadline statistics (its period, its step
// compute, late steps: common/realtime), reported beside the servo loop's.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/realtime/realtime_setup.h"
#include "common/realtime/timing_stats.h"

namespace hemm::device {

enum class HardwareMode { kLockStep, kThreaded };
const char* to_string(HardwareMode m) noexcept;  // "lock-step" / "threaded"

// How the servo loop starts a device (HapticDevice::start).
struct HardwareStart {
  HardwareMode mode = HardwareMode::kLockStep;
  rt::RealtimeRequest realtime;  // the hardware thread's (SCHED_FIFO below the servo's priority)
};

struct SimulatedHardwareStats {
  rt::TimingStats timing;                  // the hardware thread's loop (writer: that thread)
  rt::LogHistogram sample_age;             // servo wake - newest sample's stamp (writer: the servo thread)
  std::atomic<std::uint64_t> commands_new{0};   // steps that took a new command (hardware thread)
  std::atomic<std::uint64_t> commands_held{0};  // steps that held the last one
  // Hardware thread: one step took a new command (true) or held the last.
  void took_command(bool fresh) noexcept {
    std::atomic<std::uint64_t>& c = fresh ? commands_new : commands_held;
    c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
};

// The thread a SIMULATED device's hardware runs on (kThreaded): step(now_ns)
// every period_ns on its own absolute deadline grid (now_ns: its wake time),
// timed into stats().timing with `what` as the worst ticks' name. step must
// not block (it may be slow: a late step is counted, the grid kept).
class SimulatedHardwareThread {
 public:
  SimulatedHardwareThread() : stats_(std::make_unique<SimulatedHardwareStats>()) {}
  ~SimulatedHardwareThread() { stop(); }
  SimulatedHardwareThread(const SimulatedHardwareThread&) = delete;
  SimulatedHardwareThread& operator=(const SimulatedHardwareThread&) = delete;

  // Throws std::logic_error if running, std::invalid_argument on a period
  // outside [100 us, 1 s]; what of the thread's real-time set-up was refused
  // goes into the status' warnings.
  rt::RealtimeStatus start(std::int64_t period_ns, const rt::RealtimeRequest& realtime, const char* what,
                           std::function<void(std::int64_t now_ns)> step);
  void stop() noexcept;  // joins; idempotent
  bool running() const noexcept { return thread_.joinable(); }
  SimulatedHardwareStats& stats() noexcept { return *stats_; }
  const SimulatedHardwareStats& stats() const noexcept { return *stats_; }

 private:
  std::unique_ptr<SimulatedHardwareStats> stats_;  // ~16 kB of histograms
  std::function<void(std::int64_t)> step_;
  std::atomic<bool> stop_{false}, go_{false};
  std::thread thread_;
};

}  // namespace hemm::device
