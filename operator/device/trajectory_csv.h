// Recorded device trajectories as CSV, one sample a line, positions in metres
// in frame H, t in seconds.
//
// Version 2 (written by the recorder): a header line is required and names
// the end-effectors; per end-effector k a group of 23 columns follows t_s:
//   t_s,ee0_x,ee0_y,ee0_z,ee0_qw,ee0_qx,ee0_qy,ee0_qz,ee0_vx,ee0_vy,ee0_vz,
//   ee0_wx,ee0_wy,ee0_wz,ee0_enabled,ee0_buttons,ee0_inputs,ee0_deadman,
//   ee0_grip,ee0_grip_v,ee0_joy_x,ee0_joy_y,ee0_switch,ee0_attached[,ee1_x,...]
// (pose, linear and angular velocity, enabled 0/1, the handle's button bits,
// which inputs the handle has as kHas* bits, then those inputs: dead-man 0/1,
// grip position [m] and velocity [m/s], joystick axes in [-1, 1], switch 0/1,
// clutch attached 0/1). An input the handle lacks must hold its default
// (0, or attached 1).
//
// Version 1 (older files, still loaded): no end-effector groups,
//   t_s,x,y,z,buttons                      (position only)
//   t_s,x,y,z,qw,qx,qy,qz,buttons          (with orientation)
// with an optional header; one end-effector, no velocities (the replay
// differentiates positions).
//
// Empty lines and lines starting with '#' are skipped. Files are hostile:
// every row is checked (field count, finite numbers, strictly increasing time,
// inside the end-effector's workspace with a small tolerance for end stops
// giving under load, unit quaternions, flags 0/1, joystick range, the file's
// end-effector count against the device's) and the first problem is reported
// as "file:line: message"; on error the output trajectory is left untouched.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "operator/device/haptic_device.h"

namespace hemm::device {

// One line: every end-effector's sample at t_s. A fixed-size value, so the
// servo thread can copy it into a ring without allocating.
struct TrajectorySample {
  double t_s = 0.0;
  int end_effectors = 1;
  std::array<EndEffectorSample, kMaxEndEffectors> ee{};
};

struct Trajectory {
  std::vector<TrajectorySample> samples;  // strictly increasing t_s
  int end_effectors = 1;
  bool has_orientation = true;  // false: a version 1 file without quaternions
  // Velocities recorded (version 2). false (version 1, or built by code
  // without them): the replay differentiates positions.
  bool has_twist = false;
};

struct TrajectoryError {
  std::string file;
  int line = 0;  // 1-based; 0 when not tied to one line
  std::string message;
  std::string to_string() const;  // "file:line: message"
};

// How far outside the workspace box a recorded position may lie [m].
inline constexpr double kTrajectoryWorkspaceTolerance = 0.005;
// Files larger than this are refused before reading.
inline constexpr std::size_t kMaxTrajectoryFileBytes = 256u << 20;
// Columns per end-effector in version 2.
inline constexpr int kTrajectoryColumnsPerEndEffector = 23;

std::optional<TrajectoryError> parse_trajectory_csv(std::string_view text,
                                                    const std::string& file_name,
                                                    const DeviceLimits& limits, Trajectory* out);
std::optional<TrajectoryError> load_trajectory_csv(const std::string& path,
                                                   const DeviceLimits& limits, Trajectory* out);

// The version 2 header line (without newline) for a device with
// `end_effectors` end-effectors (1 .. kMaxEndEffectors).
std::string trajectory_csv_header(int end_effectors);

// Formats one version 2 row (with '\n') of s.end_effectors groups into buf
// without allocating; numbers are written in shortest round-trip form, so
// parsing gives back the same doubles. Returns the number of characters
// written, 0 if buf is too small (kTrajectoryRowMax always suffices) or
// s.end_effectors is out of range.
inline constexpr std::size_t kTrajectoryRowMax = 2048;
std::size_t format_trajectory_row(const TrajectorySample& s, char* buf, std::size_t size);

}  // namespace hemm::device
