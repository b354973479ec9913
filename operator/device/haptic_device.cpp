#include "operator/device/haptic_device.h"

#include <algorithm>
#include <cmath>

namespace hemm::device {

void HapticDevice::start(const HardwareStart&, std::vector<std::string>*) {}

bool wrench_is_finite(const EndEffectorCommand& c) noexcept {
  return c.force_H.allFinite() && c.torque_H.allFinite() && std::isfinite(c.grip_force);
}

int zero_nonfinite_wrenches(DeviceCommand& cmd, int end_effectors) noexcept {
  int zeroed = 0;
  const int n = std::clamp(end_effectors, 0, kMaxEndEffectors);
  for (int i = 0; i < n; ++i) {
    EndEffectorCommand& c = cmd.ee[static_cast<std::size_t>(i)];
    if (!wrench_is_finite(c)) {
      c = EndEffectorCommand{};
      ++zeroed;
    }
  }
  return zeroed;
}

namespace {
void clamp_norm(Eigen::Vector3d& v, double max_norm) noexcept {
  const double n2 = v.squaredNorm();
  if (n2 > max_norm * max_norm) v *= max_norm / std::sqrt(n2);
}
}  // namespace

void clamp_to_peak(EndEffectorCommand& c, const EndEffectorLimits& l) noexcept {
  clamp_norm(c.force_H, l.peak_force);
  if (l.renders_torque) {
    clamp_norm(c.torque_H, l.peak_torque);
  } else {
    c.torque_H.setZero();
  }
  c.grip_force = std::clamp(c.grip_force, 0.0, l.peak_grip_force);
}

const char* check_limits(const EndEffectorLimits& l) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!l.workspace_min_H.allFinite() || !l.workspace_max_H.allFinite() ||
      !(l.workspace_min_H.array() < l.workspace_max_H.array()).all())
    return "workspace box must be finite with min < max";
  if (!pos(l.peak_force) || !pos(l.max_continuous_force) || l.max_continuous_force > l.peak_force)
    return "need 0 < max_continuous_force <= peak_force";
  if (!pos(l.max_stiffness)) return "max_stiffness must be finite and > 0";
  if (l.renders_torque && (!pos(l.peak_torque) || !pos(l.max_rotational_stiffness)))
    return "a torque-rendering end-effector needs peak_torque > 0 and max_rotational_stiffness > 0";
  if (!nonneg(l.peak_torque) || !nonneg(l.max_rotational_stiffness) || !nonneg(l.peak_grip_force) ||
      !nonneg(l.max_linear_speed))
    return "torque, rotational stiffness, grip force and speed limits must be finite and >= 0";
  return nullptr;
}

const char* check_limits(const DeviceLimits& d) {
  if (d.end_effectors < 1 || d.end_effectors > kMaxEndEffectors)
    return "end_effectors must be in [1, kMaxEndEffectors]";
  for (int i = 0; i < d.end_effectors; ++i)
    if (const char* why = check_limits(d.ee[static_cast<std::size_t>(i)])) return why;
  return nullptr;
}

DeviceLimits rigid_hand_limits(int end_effectors) {
  DeviceLimits d;
  d.end_effectors = end_effectors;
  for (auto& l : d.ee) {
    l.workspace_min_H = Eigen::Vector3d::Constant(-1.0);
    l.workspace_max_H = Eigen::Vector3d::Constant(1.0);
    l.max_continuous_force = 150.0;
    l.peak_force = 150.0;
    l.max_stiffness = 5000.0;
    l.renders_torque = true;
    l.peak_torque = 25.0;
    l.max_rotational_stiffness = 300.0;
    l.max_linear_speed = 1.5;
  }
  return d;
}

}  // namespace hemm::device
