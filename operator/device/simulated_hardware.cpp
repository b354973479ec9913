#include "operator/device/simulated_hardware.h"

#include <pthread.h>

#include <stdexcept>

#include "common/clock/steady_clock.h"

namespace hemm::device {

const char* to_string(HardwareMode m) noexcept { return m == HardwareMode::kThreaded ? "threaded" : "lock-step"; }

rt::RealtimeStatus SimulatedHardwareThread::start(std::int64_t period_ns, const rt::RealtimeRequest& realtime,
                                                  const char* what, std::function<void(std::int64_t)> step) {
  if (thread_.joinable()) throw std::logic_error("SimulatedHardwareThread: already running");
  if (period_ns < 100'000 || period_ns > 1'000'000'000)
    throw std::invalid_argument("SimulatedHardwareThread: period must be in [100 us, 1 s]");
  step_ = std::move(step);
  stop_.store(false, std::memory_order_relaxed);
  go_.store(false, std::memory_order_relaxed);
  thread_ = std::thread([this, period_ns, what] {
    go_.wait(false, std::memory_order_acquire);
    rt::DeadlineGrid grid(period_ns, steady_now_ns());
    std::uint64_t k = 0;
    while (!stop_.load(std::memory_order_acquire)) {
      const std::int64_t wake = grid.wait();
      step_(wake);
      grid.finish(stats_->timing, wake, steady_now_ns(), k++, what);
    }
  });
  pthread_setname_np(thread_.native_handle(), "hemm-sim-hw");
  rt::RealtimeStatus status;
  rt::apply_thread_realtime(thread_, realtime, &status);
  go_.store(true, std::memory_order_release);
  go_.notify_one();
  return status;
}

void SimulatedHardwareThread::stop() noexcept {
  if (!thread_.joinable()) return;
  stop_.store(true, std::memory_order_release);
  go_.store(true, std::memory_order_release);
  go_.notify_one();
  thread_.join();
}

}  // namespace hemm::device
