// Records what a device reports, in the trajectory CSV format (version 2:
// every end-effector's pose, twist and handle inputs) that ReplayDevice plays
// (operator/device/trajectory_csv.h). The servo thread only pushes samples
// into a preallocated ring (never blocks; overflow is counted); the
// recorder's writer thread formats and writes them.
#pragma once

#include <cstddef>

#include "operator/device/haptic_device.h"
#include "operator/device/trajectory_csv.h"
#include "operator/servo/csv_logger.h"

namespace hemm::servo {

using TrajectoryRecorder = CsvLogger<device::TrajectorySample>;

// A recorder for a device with `end_effectors` end-effectors.
TrajectoryRecorder make_trajectory_recorder(int end_effectors = 1, std::size_t capacity = 16384);

// Wraps a device: every read() is passed through and also pushed to the
// recorder, stamped t_s = (number of previous reads) * dt_s, i.e. servo ticks
// on the servo grid, so a replay at the same rate reproduces it sample for
// sample. write() goes to the wrapped device unchanged.
class RecordingDevice final : public device::HapticDevice {
 public:
  // Throws std::invalid_argument if the recorder was made for another
  // end-effector count than the device's.
  RecordingDevice(device::HapticDevice& inner, TrajectoryRecorder& recorder, double dt_s = 0.001);

  void read(device::DeviceSample& out) noexcept override {
    inner_.read(out);
    device::TrajectorySample s;
    s.t_s = static_cast<double>(reads_++) * dt_s_;
    s.end_effectors = end_effectors_;
    s.ee = out.ee;
    recorder_.push(s);
  }
  void write(const device::DeviceCommand& cmd) noexcept override { inner_.write(cmd); }
  const device::DeviceLimits& limits() const noexcept override { return inner_.limits(); }
  std::string_view name() const noexcept override { return inner_.name(); }

 private:
  device::HapticDevice& inner_;
  TrajectoryRecorder& recorder_;
  double dt_s_;
  int end_effectors_;
  std::uint64_t reads_ = 0;
};

}  // namespace hemm::servo
