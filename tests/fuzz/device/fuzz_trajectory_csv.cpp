// Trajectory CSV files are hostile input. The first byte picks the device
// (the Omni's one end-effector or two arms), the rest is the file. A refused
// file must leave the output untouched; an accepted one must hold what the
// format promises (increasing times, positions in the box, unit quaternions,
// joystick in range, the device's end-effector count), and a version 2 file
// must format and parse back to the same trajectory.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "operator/device/trajectory_csv.h"

using namespace hemm::device;

namespace {

DeviceLimits two_arms() {
  DeviceLimits d;
  d.end_effectors = 2;
  d.ee = {phantom_omni_limits().ee[0], phantom_omni_limits().ee[0]};
  d.ee[1].workspace_min_H.x() = 0.0;
  d.ee[1].workspace_max_H.x() = 0.5;
  return d;
}

void check(bool ok) {
  if (!ok) abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const DeviceLimits limits = (data[0] & 1) != 0 ? two_arms() : phantom_omni_limits();
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
  Trajectory t;
  t.samples.resize(1);
  t.samples[0].t_s = -7.0;
  const auto err = parse_trajectory_csv(text, "fuzz.csv", limits, &t);
  if (err) {
    check(t.samples.size() == 1 && t.samples[0].t_s == -7.0);
    check(!err->message.empty());
    return 0;
  }
  check(!t.samples.empty() && t.end_effectors == limits.end_effectors);
  for (std::size_t i = 0; i < t.samples.size(); ++i) {
    const TrajectorySample& s = t.samples[i];
    check(std::isfinite(s.t_s) && (i == 0 || s.t_s > t.samples[i - 1].t_s));
    check(s.end_effectors == t.end_effectors);
    for (int k = 0; k < s.end_effectors; ++k) {
      const EndEffectorSample& e = s.ee[static_cast<std::size_t>(k)];
      check(limits.ee[static_cast<std::size_t>(k)].contains(e.position_H, kTrajectoryWorkspaceTolerance));
      check(std::abs(e.orientation_H.norm() - 1.0) < 1e-9);
      check(e.velocity_H.allFinite() && e.angular_velocity_H.allFinite());
      check(std::abs(e.handle.joystick.x()) <= 1.0 && std::abs(e.handle.joystick.y()) <= 1.0);
    }
  }
  if (!t.has_twist) return 0;  // version 1: nothing to write back
  std::string again = trajectory_csv_header(t.end_effectors) + "\n";
  char row[kTrajectoryRowMax];
  for (const TrajectorySample& s : t.samples) {
    const std::size_t n = format_trajectory_row(s, row, sizeof row);
    check(n > 0);
    again.append(row, n);
  }
  Trajectory u;
  check(!parse_trajectory_csv(again, "again.csv", limits, &u));
  check(u.samples.size() == t.samples.size());
  for (std::size_t i = 0; i < t.samples.size(); ++i) {
    check(u.samples[i].t_s == t.samples[i].t_s);
    for (int k = 0; k < t.end_effectors; ++k) {
      const EndEffectorSample &a = t.samples[i].ee[static_cast<std::size_t>(k)],
                              &b = u.samples[i].ee[static_cast<std::size_t>(k)];
      check(a.position_H == b.position_H && a.orientation_H.coeffs() == b.orientation_H.coeffs());
      check(a.velocity_H == b.velocity_H && a.angular_velocity_H == b.angular_velocity_H);
      check(a.enabled == b.enabled && a.handle.buttons == b.handle.buttons);
      check(handle_input_bits(a.handle) == handle_input_bits(b.handle));
      check(a.handle.grip_position == b.handle.grip_position && a.handle.joystick == b.handle.joystick);
    }
  }
  return 0;
}
