#include "operator/servo/trajectory_recorder.h"

namespace hemm::servo {
namespace {

std::size_t format_with_orientation(const device::TrajectorySample& s, char* buf, std::size_t n) {
  return device::format_trajectory_row(s, true, buf, n);
}
std::size_t format_position_only(const device::TrajectorySample& s, char* buf, std::size_t n) {
  return device::format_trajectory_row(s, false, buf, n);
}

}  // namespace

TrajectoryRecorder make_trajectory_recorder(bool with_orientation, std::size_t capacity) {
  return TrajectoryRecorder(capacity, device::trajectory_csv_header(with_orientation),
                            with_orientation ? &format_with_orientation : &format_position_only);
}

}  // namespace hemm::servo
