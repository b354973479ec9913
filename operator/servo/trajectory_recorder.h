// Records what a device reports, in the trajectory CSV format that
// ReplayDevice plays (operator/device/trajectory_csv.h). The servo thread only
// pushes samples into a preallocated ring (never blocks; overflow is counted);
// the recorder's writer thread formats and writes them.
#pragma once

#include <cstddef>

#include "operator/device/haptic_device.h"
#include "operator/device/trajectory_csv.h"
#include "operator/servo/csv_logger.h"

namespace hemm::servo {

using TrajectoryRecorder = CsvLogger<device::TrajectorySample>;

// A recorder for either CSV layout (with or without the quaternion columns).
TrajectoryRecorder make_trajectory_recorder(bool with_orientation, std::size_t capacity = 16384);

// Wraps a device: every read() is passed through and also pushed to the
// recorder, stamped t_s = (number of previous reads) * dt_s, i.e. servo ticks
// on the servo grid, so a replay at the same rate reproduces it sample for
// sample. write() goes to the wrapped device unchanged.
class RecordingDevice final : public device::HapticDevice {
 public:
  RecordingDevice(device::HapticDevice& inner, TrajectoryRecorder& recorder, double dt_s = 0.001)
      : inner_(inner), recorder_(recorder), dt_s_(dt_s) {}

  void read(device::DeviceSample& out) noexcept override {
    inner_.read(out);
    device::TrajectorySample s;
    s.t_s = static_cast<double>(reads_++) * dt_s_;
    s.position_H = out.position_H;
    s.orientation_H = out.orientation_H;
    s.buttons = out.buttons;
    recorder_.push(s);
  }
  void write(const Eigen::Vector3d& force_H) noexcept override { inner_.write(force_H); }
  const device::DeviceLimits& limits() const noexcept override { return inner_.limits(); }
  std::string_view name() const noexcept override { return inner_.name(); }

 private:
  device::HapticDevice& inner_;
  TrajectoryRecorder& recorder_;
  double dt_s_;
  std::uint64_t reads_ = 0;
};

}  // namespace hemm::servo
