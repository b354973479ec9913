#include "robot_side/control/base_control.h"

#include <algorithm>
#include <cmath>

#include "common/math/frames.h"

namespace hemm::robot {
namespace {
double toward(double current, double target, double max_delta) {
  return current + std::clamp(target - current, -max_delta, max_delta);
}
double finite_or_zero(double x) { return std::isfinite(x) ? x : 0.0; }
}  // namespace

BaseSetpoint slew_setpoint(const BaseLimits& l, const BaseSetpoint& cur, double v_cmd, double omega_cmd, double dt) {
  const double v_t = std::clamp(finite_or_zero(v_cmd), -l.max_speed, l.max_speed);
  const double w_t = std::clamp(finite_or_zero(omega_cmd), -l.max_yaw_rate, l.max_yaw_rate);
  dt = std::max(0.0, finite_or_zero(dt));
  return {toward(cur.v, v_t, l.max_accel * dt), toward(cur.omega, w_t, l.max_yaw_accel * dt)};
}

WheelSpeeds wheel_speeds(const SkidSteerGeometry& g, const BaseSetpoint& s) {
  const double half = 0.5 * g.effective_track() * s.omega;
  return {s.v - half, s.v + half};
}

BaseSetpoint body_motion(const SkidSteerGeometry& g, const WheelSpeeds& w) {
  return {0.5 * (w.left + w.right), (w.right - w.left) / g.effective_track()};
}

void integrate_odometry(const SkidSteerGeometry& g, const WheelSpeeds& measured, double dt, Odometry& o) {
  const BaseSetpoint b = body_motion(g, measured);
  if (!std::isfinite(b.v) || !std::isfinite(b.omega) || !std::isfinite(dt)) return;
  // Exact for constant speeds over the period: the chord of the arc,
  // 2 sin(d/2) / d times the path length, along the mid-period heading.
  const double half = 0.5 * b.omega * dt;
  const double chord = std::abs(half) > 1e-9 ? std::sin(half) / half : 1.0;
  const double mid = o.theta + half;
  o.x += b.v * dt * chord * std::cos(mid);
  o.y += b.v * dt * chord * std::sin(mid);
  o.theta = math::wrap_angle(o.theta + b.omega * dt);
  o.v = b.v;
  o.omega = b.omega;
}

}  // namespace hemm::robot
