#include "operator/servo/trajectory_recorder.h"

#include <stdexcept>

namespace hemm::servo {

TrajectoryRecorder make_trajectory_recorder(int end_effectors, std::size_t capacity) {
  if (end_effectors < 1 || end_effectors > device::kMaxEndEffectors)
    throw std::invalid_argument("make_trajectory_recorder: end_effectors out of range");
  return TrajectoryRecorder(capacity, device::trajectory_csv_header(end_effectors), &device::format_trajectory_row);
}

RecordingDevice::RecordingDevice(device::HapticDevice& inner, TrajectoryRecorder& recorder, double dt_s)
    : inner_(inner), recorder_(recorder), dt_s_(dt_s), end_effectors_(inner.limits().end_effectors) {
  if (end_effectors_ < 1 || end_effectors_ > device::kMaxEndEffectors ||
      recorder.header() != device::trajectory_csv_header(end_effectors_))
    throw std::invalid_argument("RecordingDevice: the recorder was made for another end-effector count");
}

}  // namespace hemm::servo
