// Recorded device trajectories as CSV, one sample a line:
//   t_s,x,y,z,buttons                      (position only)
//   t_s,x,y,z,qw,qx,qy,qz,buttons          (with orientation)
// Positions in metres in frame H, t in seconds, buttons an unsigned bit mask.
// An optional header line (exactly one of the two above) comes first; empty
// lines and lines starting with '#' are skipped. Files are hostile: every row
// is checked (field count, finite numbers, strictly increasing time, inside the
// device workspace with a small tolerance for end stops giving under load,
// unit quaternions) and the first problem is reported as "file:line: message";
// on error the output trajectory is left untouched.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "operator/device/haptic_device.h"

namespace hemm::device {

struct TrajectorySample {
  double t_s = 0.0;
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  std::uint32_t buttons = 0;
};

struct Trajectory {
  std::vector<TrajectorySample> samples;  // strictly increasing t_s
  bool has_orientation = false;
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

std::optional<TrajectoryError> parse_trajectory_csv(std::string_view text,
                                                    const std::string& file_name,
                                                    const DeviceLimits& limits, Trajectory* out);
std::optional<TrajectoryError> load_trajectory_csv(const std::string& path,
                                                   const DeviceLimits& limits, Trajectory* out);

// The header line (without newline) for either layout.
const char* trajectory_csv_header(bool with_orientation);

// Formats one row (with '\n') into buf without allocating; numbers are written
// in shortest round-trip form, so parsing gives back the same doubles. Returns
// the number of characters written, 0 if buf is too small (256 always suffices).
std::size_t format_trajectory_row(const TrajectorySample& s, bool with_orientation, char* buf,
                                  std::size_t size);

}  // namespace hemm::device
