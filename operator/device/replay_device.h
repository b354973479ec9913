// Plays a recorded trajectory (see trajectory_csv.h) as if it were a device
// with the trajectory's end-effectors: each read() returns the trajectory at
// the current replay time, linearly interpolated (orientation by slerp,
// velocities linearly when the file recorded them, else the current segment's
// position difference over its duration; handle inputs and enabled from the
// sample at or before), so replaying at the recording rate reproduces every
// recorded sample exactly. Each write() records the command (it is NOT
// applied: the trajectory does not react) and advances the replay time by
// one servo period. Replay time starts at the first sample; after the last
// sample the device holds it with zero velocity and finished() is true.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "operator/device/haptic_device.h"
#include "operator/device/trajectory_csv.h"

namespace hemm::device {

struct CommandRecord {
  double t_s = 0.0;  // replay time of the write (relative to the first sample)
  DeviceCommand command;  // as commanded
};

class ReplayDevice final : public HapticDevice {
 public:
  // `trajectory` must be non-empty with strictly increasing times (as
  // load_trajectory_csv guarantees) and as many end-effectors as `limits`;
  // throws std::invalid_argument otherwise. Up to `command_capacity` writes
  // are recorded (storage reserved here); later ones are counted in
  // commands_dropped().
  ReplayDevice(Trajectory trajectory, const DeviceLimits& limits, double dt_s = 0.001,
               std::size_t command_capacity = 600'000);

  void read(DeviceSample& out) noexcept override;
  void write(const DeviceCommand& cmd) noexcept override;
  const DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "replay"; }

  double time_s() const noexcept { return static_cast<double>(ticks_) * dt_s_; }
  bool finished() const noexcept;
  const Trajectory& trajectory() const { return trajectory_; }

  // Safe from any thread: the writer publishes each record before the count.
  std::size_t commands_recorded() const noexcept { return command_count_.load(std::memory_order_acquire); }
  // Record i < commands_recorded(); end-effectors beyond the device's are zero.
  CommandRecord command(std::size_t i) const;
  std::uint64_t commands_dropped() const noexcept { return commands_dropped_.load(std::memory_order_relaxed); }

 private:
  Trajectory trajectory_;
  DeviceLimits limits_;
  double dt_s_;
  std::uint64_t ticks_ = 0;
  std::size_t cursor_ = 0;  // segment [cursor_, cursor_ + 1] contains the replay time
  // Only the device's end-effectors are kept: write i fills
  // wrenches_[i * end_effectors, (i + 1) * end_effectors).
  std::vector<double> times_;
  std::vector<EndEffectorCommand> wrenches_;
  std::atomic<std::size_t> command_count_{0};
  std::atomic<std::uint64_t> commands_dropped_{0};
};

}  // namespace hemm::device
