#include "robot_side/twoarm/gripper_control.h"

#include <algorithm>
#include <cmath>

namespace hemm::twoarm {

std::optional<std::string> check_target(const GripperSpec& spec, const GripperTarget& t) {
  if (!std::isfinite(t.opening_m) || t.opening_m < 0.0 || t.opening_m > 2.0 * spec.finger_stroke_m)
    return "opening must be finite and in [0, " + std::to_string(2.0 * spec.finger_stroke_m) + "] m";
  if (!std::isfinite(t.force_N) || t.force_N < 0.0 || t.force_N > spec.max_force_N)
    return "grip force must be finite and in [0, " + std::to_string(spec.max_force_N) + "] N";
  return std::nullopt;
}

void gripper_control(const GripperSpec& spec, const GripperGains& g, const GripperTarget& t, const GripperSense& s,
                     GripperState& out) noexcept {
  const double x_d = 0.5 * std::clamp(std::isfinite(t.opening_m) ? t.opening_m : 0.0, 0.0, 2.0 * spec.finger_stroke_m);
  const double f_max = std::clamp(std::isfinite(t.force_N) ? t.force_N : 0.0, 0.0, spec.max_force_N);
  for (std::size_t f = 0; f < 2; ++f) {
    const double u = g.kp_N_per_m * (x_d - s.finger_m[f]) - g.kd_Ns_per_m * s.finger_mps[f];
    // Closing is limited to the grip force; opening to the motor's limit.
    out.finger_force_N[f] = std::clamp(u, -f_max, spec.max_force_N);
  }
  out.opening_m = s.finger_m[0] + s.finger_m[1];
  out.grip_force_N = 0.5 * (s.pad_force_N[0] + s.pad_force_N[1]);
  out.holding = f_max > 0.0 && std::min(s.pad_force_N[0], s.pad_force_N[1]) >= g.grasp_fraction * f_max;
}

}  // namespace hemm::twoarm
