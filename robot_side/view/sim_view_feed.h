// SIMULATION ONLY. What the robot station's live view reads from the
// simulation thread, without putting the view on that thread's critical path:
// at the station's state publication point (state rate), and only when the
// view's interval has passed, the simulation thread copies the MuJoCo state
// (qpos, contacts; SimulatedRobot::view_frame_sim) into its own frame and
// hands it over under a mutex it only try-locks (if the view holds it, the
// frame waits for the next publication); the newest scan of each sensor is
// handed over the same way when scans are taken. Rendering happens on the
// view's thread (robot_view.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <vector>

#include "robot_side/sim/sim_types.h"

namespace hemm::robot {

class SimViewFeed {
 public:
  explicit SimViewFeed(std::int64_t interval_ns = 33'000'000) : interval_ns_(interval_ns) {}
  SimViewFeed(const SimViewFeed&) = delete;
  SimViewFeed& operator=(const SimViewFeed&) = delete;

  // ---- simulation thread ----
  // True if a frame is wanted at simulation time now_ns.
  bool due(std::int64_t now_ns) const noexcept { return now_ns >= next_ns_.load(std::memory_order_relaxed); }
  // Hands `frame` over (swapped: frame gets the previous buffers back); false
  // if the view held the lock (nothing changed then).
  bool publish(SimViewFrame& frame);
  // Keeps the newest scan of each sensor (by name).
  void publish_scans(const std::vector<RangeScanData>& scans);

  // ---- view thread ----
  // The newest frame since the last take, with the newest scans; false if none.
  bool take(SimViewFrame& out);
  void set_interval_ns(std::int64_t ns) noexcept { interval_ns_.store(ns, std::memory_order_relaxed); }

  std::uint64_t frames() const noexcept { return frames_.load(std::memory_order_relaxed); }
  std::uint64_t busy_skips() const noexcept { return busy_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::int64_t> interval_ns_;
  std::atomic<std::int64_t> next_ns_{0};
  std::mutex mu_;
  SimViewFrame slot_;
  std::vector<RangeScanData> scans_;  // newest per sensor
  bool fresh_ = false;
  std::atomic<std::uint64_t> frames_{0}, busy_{0};
};

}  // namespace hemm::robot
