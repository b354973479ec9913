// A TEST DOUBLE, not a simulation: a device with two end-effectors that
// render force and torque, whose state is a closed-form function of the tick
// (the number of previous writes), so tests can compare what the servo loop,
// the logs and the replay report against exact values:
//  - end-effector 0 circles about c0 in the x-y plane at angular rate w and
//    turns about z with it; joystick handle with a dead-man (pressed), axes
//    (0.5 sin, 0.5 cos), buttons counting up every 100 ticks;
//  - end-effector 1 bobs along z about c1; grip handle with a clutch: grip
//    opening follows (1 + sin) / 2 * 0.02 m; it is disabled (brakes) during
//    ticks [kDisabledFrom, kDisabledTo).
// write() does what the device-layer contract asks of a backend: non-finite
// wrenches become zero (counted), peaks are clamped, a disabled end-effector
// gets no wrench. Applied wrenches go into preallocated storage (no
// allocation on the servo thread).
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "operator/device/haptic_device.h"

namespace hemm::test {

class TwoHandDevice final : public device::HapticDevice {
 public:
  static constexpr double kW = 2.0 * std::numbers::pi;  // rad/s
  static constexpr double kRadius = 0.05;   // m
  static constexpr double kBob = 0.03;      // m
  static constexpr std::uint64_t kDisabledFrom = 300, kDisabledTo = 400;

  explicit TwoHandDevice(std::size_t capacity, double dt_s = 0.001) : dt_s_(dt_s), applied_(capacity) {
    limits_.end_effectors = 2;
    for (auto& l : limits_.ee) {
      l.workspace_min_H = Eigen::Vector3d(-0.5, -0.5, -0.5);
      l.workspace_max_H = Eigen::Vector3d(0.5, 0.5, 0.5);
      l.max_continuous_force = 20.0;
      l.peak_force = 40.0;
      l.max_stiffness = 3000.0;
      l.renders_torque = true;
      l.peak_torque = 3.0;
      l.max_rotational_stiffness = 20.0;
      l.peak_grip_force = 5.0;
    }
  }

  static Eigen::Vector3d c0() { return {-0.2, 0.0, 0.1}; }
  static Eigen::Vector3d c1() { return {0.2, 0.0, 0.1}; }

  // The state at tick k (what read() returns after k writes).
  device::DeviceSample expected(std::uint64_t k) const {
    const double t = static_cast<double>(k) * dt_s_;
    const double s = std::sin(kW * t), c = std::cos(kW * t);
    device::DeviceSample out;
    out.end_effectors = 2;
    device::EndEffectorSample& a = out.ee[0];
    a.position_H = c0() + kRadius * Eigen::Vector3d(c, s, 0);
    a.velocity_H = kRadius * kW * Eigen::Vector3d(-s, c, 0);
    a.orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(kW * t, Eigen::Vector3d::UnitZ()));
    a.angular_velocity_H = Eigen::Vector3d(0, 0, kW);
    a.handle.buttons = static_cast<std::uint32_t>(k / 100) & 3u;
    a.handle.has_deadman = true;
    a.handle.deadman = true;
    a.handle.has_joystick = true;
    a.handle.joystick = Eigen::Vector2d(0.5 * s, 0.5 * c);
    a.handle.switch_on = (k / 250) % 2 == 1;
    device::EndEffectorSample& b = out.ee[1];
    b.position_H = c1() + Eigen::Vector3d(0, 0, kBob * s);
    b.velocity_H = Eigen::Vector3d(0, 0, kBob * kW * c);
    b.handle.has_grip = true;
    b.handle.grip_position = 0.01 * (1.0 + s);
    b.handle.grip_velocity = 0.01 * kW * c;
    b.handle.has_clutch = true;
    b.handle.attached = true;
    b.enabled = k < kDisabledFrom || k >= kDisabledTo;
    return out;
  }

  void read(device::DeviceSample& out) noexcept override {
    const std::int64_t t_ns = out.t_ns;
    out = expected(writes_);  // Eigen fixed-size values: no allocation
    out.t_ns = t_ns;
  }

  void write(const device::DeviceCommand& cmd) noexcept override {
    device::DeviceCommand c = cmd;
    nonfinite_ += static_cast<std::uint64_t>(device::zero_nonfinite_wrenches(c, 2));
    const device::DeviceSample now = expected(writes_);
    for (std::size_t k = 0; k < 2; ++k) {
      if (!now.ee[k].enabled) c.ee[k] = device::EndEffectorCommand{};
      device::clamp_to_peak(c.ee[k], limits_.ee[k]);
    }
    if (writes_ < applied_.size()) applied_[writes_] = c;
    ++writes_;
  }

  const device::DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "test-double-two-hands"; }

  // After the loop stopped.
  std::uint64_t writes() const { return writes_; }
  std::uint64_t nonfinite() const { return nonfinite_; }
  const device::DeviceCommand& applied(std::size_t tick) const { return applied_[tick]; }

 private:
  double dt_s_;
  device::DeviceLimits limits_;
  std::vector<device::DeviceCommand> applied_;
  std::uint64_t writes_ = 0;
  std::uint64_t nonfinite_ = 0;
};

}  // namespace hemm::test
