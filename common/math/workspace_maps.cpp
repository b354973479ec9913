#include "common/math/workspace_maps.h"

#include <algorithm>
#include <cmath>

#include "common/math/finite.h"

namespace hemm::math {

std::string validate(const ScaledMap& m) {
  if (!std::isfinite(m.scale) || m.scale <= 0.0) return "scale must be finite and > 0";
  if (!finite3(m.centre_B) || !finite3(m.origin_R)) return "centre_B/origin_R must be finite";
  return {};
}

ExplorationMap make_exploration_map(const DeviceWorkspace& ws, double sensor_range_m,
                                    const Eigen::Vector3d& robot_centre_R) {
  ExplorationMap e;
  e.sensor_range = sensor_range_m;
  e.map.scale = sensor_range_m / horizontal_half_extent(ws);
  e.map.centre_B = ws.centre_B;
  e.map.origin_R = robot_centre_R;
  return e;
}

std::string validate(const NavigationMap& n) {
  if (!finite3(n.centre_B)) return "centre_B must be finite";
  if (!(n.dead_band >= 0.0) || !(n.saturation > n.dead_band) || !std::isfinite(n.saturation))
    return "need 0 <= dead_band < saturation";
  if (!(n.v_max > 0.0) || !(n.omega_max > 0.0) || !(n.track_width > 0.0) || !(n.wheel_speed_max > 0.0) ||
      !std::isfinite(n.v_max + n.omega_max + n.track_width + n.wheel_speed_max))
    return "v_max, omega_max, track_width, wheel_speed_max must be finite and > 0";
  return validate(n.point_map);
}

NavigationMap make_navigation_map(const DeviceWorkspace& ws, double look_ahead_range_m) {
  NavigationMap n;
  n.centre_B = ws.centre_B;
  n.point_map.scale = look_ahead_range_m / horizontal_half_extent(ws);
  n.point_map.centre_B = ws.centre_B;
  return n;
}

double dead_band_saturate(double u, double dead_band, double saturation) {
  if (!std::isfinite(u)) return 0.0;  // a broken reading commands nothing
  if (!(saturation > dead_band)) return std::abs(u) > dead_band ? (u < 0.0 ? -1.0 : 1.0) : 0.0;
  const double a = std::clamp((std::abs(u) - dead_band) / (saturation - dead_band), 0.0, 1.0);
  return u < 0.0 ? -a : a;
}

BaseCommand navigation_command(const NavigationMap& n, const Eigen::Vector3d& p_B) {
  const Eigen::Vector3d d = p_B - n.centre_B;
  return {n.v_max * dead_band_saturate(d.x(), n.dead_band, n.saturation),
          n.omega_max * dead_band_saturate(d.y(), n.dead_band, n.saturation)};
}

WheelSpeeds wheel_speeds(const NavigationMap& n, const BaseCommand& cmd) {
  WheelSpeeds w{cmd.v - 0.5 * cmd.omega * n.track_width, cmd.v + 0.5 * cmd.omega * n.track_width};
  const double peak = std::max(std::abs(w.left), std::abs(w.right));
  if (peak > n.wheel_speed_max) {
    const double f = n.wheel_speed_max / peak;
    w.left *= f;
    w.right *= f;
  }
  return w;
}

ManipulationMap make_manipulation_map(const DeviceWorkspace& ws, const Eigen::Vector3d& arm_base_R,
                                      const Eigen::Vector3d& workspace_centre_R, double reach_m) {
  ManipulationMap m;
  m.arm_base_R = arm_base_R;
  m.reach = reach_m;
  m.map.scale = reach_m / horizontal_half_extent(ws);
  m.map.centre_B = ws.centre_B;
  m.map.origin_R = workspace_centre_R;
  return m;
}

ManipulationTarget manipulation_target(const ManipulationMap& m, const Eigen::Vector3d& p_B) {
  ManipulationTarget t;
  t.p_R = map_point(m.map, p_B);
  const Eigen::Vector3d d = t.p_R - m.arm_base_R;
  const double r = d.norm();
  if (r > m.reach) {
    t.p_R = m.arm_base_R + d * (m.reach / r);
    t.clamped = true;
  }
  return t;
}

ModeAnchor reanchor_at_switch(const ScaledMap& new_map, const Pose2& T_W_R, const Eigen::Vector3d& p_B,
                              const Eigen::Vector3d& proxy_W, const Eigen::Vector3d& device_W_old,
                              double scale_old) {
  const Eigen::Vector3d want_W = proxy_W + (new_map.scale / scale_old) * (device_W_old - proxy_W);
  // Into R: the inverse planar pose (z passes through).
  const Eigen::Vector3d want_R = apply(inverse(T_W_R), want_W);
  ModeAnchor a;
  a.offset_B = (want_R - new_map.origin_R) / new_map.scale + new_map.centre_B - p_B;
  return a;
}

void relax_anchor(ModeAnchor& a, double max_speed, double dt) {
  const double step = max_speed * dt;
  const double n = a.offset_B.norm();
  if (!(step > 0.0)) return;
  if (n <= step) {
    a.offset_B.setZero();
  } else {
    a.offset_B *= (n - step) / n;
  }
}

}  // namespace hemm::math
