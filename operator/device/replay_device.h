// Plays a recorded trajectory (see trajectory_csv.h) as if it were a device:
// each read() returns the trajectory at the current replay time, linearly
// interpolated (orientation by slerp, buttons from the sample at or before),
// with the velocity of the current segment; each write() records the force
// (it is NOT applied: the trajectory does not react) and advances the replay
// time by one servo period. Replay time starts at the first sample; after the
// last sample the device holds it with zero velocity and finished() is true.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "operator/device/haptic_device.h"
#include "operator/device/trajectory_csv.h"

namespace hemm::device {

struct ForceRecord {
  double t_s = 0.0;  // replay time of the write (relative to the first sample)
  Eigen::Vector3d force_H = Eigen::Vector3d::Zero();
};

class ReplayDevice final : public HapticDevice {
 public:
  // `trajectory` must be non-empty with strictly increasing times (as
  // load_trajectory_csv guarantees); throws std::invalid_argument otherwise.
  // Up to `force_capacity` writes are recorded (storage reserved here);
  // later ones are counted in forces_dropped().
  ReplayDevice(Trajectory trajectory, const DeviceLimits& limits, double dt_s = 0.001,
               std::size_t force_capacity = 600'000);

  void read(DeviceSample& out) noexcept override;
  void write(const Eigen::Vector3d& force_H) noexcept override;
  const DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "replay"; }

  double time_s() const noexcept { return static_cast<double>(ticks_) * dt_s_; }
  bool finished() const noexcept;
  const Trajectory& trajectory() const { return trajectory_; }

  // Safe from any thread: the writer publishes each record before the count.
  std::size_t forces_recorded() const noexcept { return force_count_.load(std::memory_order_acquire); }
  const ForceRecord& force(std::size_t i) const { return forces_[i]; }
  std::uint64_t forces_dropped() const noexcept { return forces_dropped_.load(std::memory_order_relaxed); }

 private:
  Trajectory trajectory_;
  DeviceLimits limits_;
  double dt_s_;
  std::uint64_t ticks_ = 0;
  std::size_t cursor_ = 0;  // segment [cursor_, cursor_ + 1] contains the replay time
  std::vector<ForceRecord> forces_;
  std::atomic<std::size_t> force_count_{0};
  std::atomic<std::uint64_t> forces_dropped_{0};
};

}  // namespace hemm::device
