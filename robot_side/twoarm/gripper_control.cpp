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

namespace {

// The most each finger may press: the target's, within the gripper's range (0 if not finite).
double grip_force_limit(const GripperSpec& spec, const GripperTarget& t) noexcept {
  return std::clamp(std::isfinite(t.force_N) ? t.force_N : 0.0, 0.0, spec.max_force_N);
}

}  // namespace

void gripper_control(const GripperSpec& spec, const GripperGains& g, const GripperTarget& t, const GripperSense& s,
                     GripperState& out) noexcept {
  const double x_d = 0.5 * std::clamp(std::isfinite(t.opening_m) ? t.opening_m : 0.0, 0.0, 2.0 * spec.finger_stroke_m);
  const double f_max = grip_force_limit(spec, t);
  // Approach speed: until both pads touch, each finger sees at most the
  // error whose P force the damping balances at max_speed, so it moves at
  // most that fast and one pad pushes the object with at most that force;
  // once both touch (a grasp), the whole error (the grip force). Both, not
  // each: the fingers are coupled, and a first pad at full force drove the
  // second into the object at 0.17 m/s. Stateless: nothing to carry between ticks.
  const bool grasping = s.pad_force_N[0] > g.contact_N && s.pad_force_N[1] > g.contact_N;
  for (std::size_t f = 0; f < 2; ++f) {
    double e = x_d - s.finger_m[f];
    if (g.max_speed_mps > 0.0 && !grasping) {
      const double e_max = g.max_speed_mps * g.kd_Ns_per_m / g.kp_N_per_m;
      e = std::clamp(e, -e_max, e_max);
    }
    const double u = g.kp_N_per_m * e - g.kd_Ns_per_m * s.finger_mps[f];
    // Closing is limited to the grip force; opening to the motor's limit.
    out.finger_force_N[f] = std::clamp(u, -f_max, spec.max_force_N);
  }
  out.opening_m = s.finger_m[0] + s.finger_m[1];
  out.grip_force_N = 0.5 * (s.pad_force_N[0] + s.pad_force_N[1]);
  out.holding = gripper_holding(spec, g, t, s);
}

bool gripper_holding(const GripperSpec& spec, const GripperGains& g, const GripperTarget& t,
                     const GripperSense& s) noexcept {
  const double f_max = grip_force_limit(spec, t);
  return f_max > 0.0 && std::min(s.pad_force_N[0], s.pad_force_N[1]) >= g.grasp_fraction * f_max;
}

}  // namespace hemm::twoarm
