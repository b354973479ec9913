#pragma once
// The workspace maps of HEMM Eq. 1:
//   E_T_H = V_T_B * B_T_H   exploration (multi-scale linear map, sensor-dependent)
//   N_T_H = N_T_B * B_T_H   navigation  (stylus -> (v, omega) -> wheel speeds)
//   M_T_H = M_T_B * B_T_H   manipulation (stylus -> arm target in R, clamped to reach)
// B_T_H is given by the device: the stylus tip p_B in the device base frame B.
//
// Convention for B (the device layer converts the vendor's axes into it): axes
// aligned with the robot frame R when the operator faces forward: x forward
// (away from the operator), y left, z up. So the map B -> R is a pure scale
// plus an offset, and R -> W is the robot's planar pose T_W_R.
#include <algorithm>
#include <string>

#include <Eigen/Core>

#include "common/math/frames.h"

namespace hemm::math {

// The device's reachable box in B. Default: PHANToM Omni, 160 W x 120 H x 70 D mm.
struct DeviceWorkspace {
  Eigen::Vector3d size{0.070, 0.160, 0.120};  // x depth, y width, z height [m]
  Eigen::Vector3d centre_B{0.0, 0.0, 0.0};
};

// Half of the larger horizontal extent: the stylus travel that the map scales
// onto the sensor's range.
inline double horizontal_half_extent(const DeviceWorkspace& ws) {
  return 0.5 * std::max(ws.size.x(), ws.size.y());
}

// Isotropic scaled map B -> R: p_R = origin_R + scale * (p_B - centre_B).
// Isotropic so that shapes (and so surface normals and force directions) are
// not distorted between the device and the world.
struct ScaledMap {
  double scale = 1.0;  // world metres per device metre
  Eigen::Vector3d centre_B = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_R = Eigen::Vector3d::Zero();
};

inline Eigen::Vector3d map_point(const ScaledMap& m, const Eigen::Vector3d& p_B) {
  return m.origin_R + m.scale * (p_B - m.centre_B);
}
inline Eigen::Vector3d unmap_point(const ScaledMap& m, const Eigen::Vector3d& p_R) {
  return m.centre_B + (p_R - m.origin_R) / m.scale;
}

// Empty string when usable; otherwise what is wrong.
std::string validate(const ScaledMap& m);

// ---------------------------------------------------------------- exploration
// V_T_B: the device's horizontal half extent maps onto the active sensor's
// range (laser 10 m -> scale 125 for the Omni, sonar 5 m -> 62.5, arm 0.5 m ->
// 6.25), centred on the robot (robot_centre_R, usually the base origin).
struct ExplorationMap {
  ScaledMap map;
  double sensor_range = 0.0;
};
ExplorationMap make_exploration_map(const DeviceWorkspace& ws, double sensor_range_m,
                                    const Eigen::Vector3d& robot_centre_R = Eigen::Vector3d::Zero());

// Exploration point in R and in W (T_W_R: robot pose).
inline Eigen::Vector3d exploration_point_R(const ExplorationMap& e, const Eigen::Vector3d& p_B) {
  return map_point(e.map, p_B);
}
inline Eigen::Vector3d exploration_point_W(const ExplorationMap& e, const Pose2& T_W_R,
                                           const Eigen::Vector3d& p_B) {
  return apply(T_W_R, map_point(e.map, p_B));
}

// ---------------------------------------------------------------- navigation
// N_T_B: stylus displacement from centre_B -> (v, omega). Forward x drives v,
// lateral y (left positive) drives omega (counter-clockwise positive). Each
// axis has a dead band and saturates: for displacement u,
//   a(u) = sign(u) * clamp((|u| - dead_band) / (saturation - dead_band), 0, 1),
//   v = v_max * a(dx), omega = omega_max * a(dy).
// Wheel speeds of the differential (skid-steer) base with track width W:
//   left = v - omega W / 2, right = v + omega W / 2,
// both scaled down by one common factor when one exceeds wheel_speed_max, so
// the path curvature the operator asked for is kept.
struct NavigationMap {
  Eigen::Vector3d centre_B = Eigen::Vector3d::Zero();
  double dead_band = 0.008;       // m of stylus travel
  double saturation = 0.035;      // m of stylus travel at which the command saturates
  double v_max = 0.7;             // m/s (Pioneer 3-AT top speed)
  double omega_max = 1.4;         // rad/s
  double track_width = 0.40;      // m
  double wheel_speed_max = 0.7;   // m/s
  // The navigation point (the proxy in navigation mode): where the operator
  // wants to go, in R, scaled like exploration so walls are felt ahead.
  ScaledMap point_map;
};
std::string validate(const NavigationMap& n);
NavigationMap make_navigation_map(const DeviceWorkspace& ws, double look_ahead_range_m);

struct BaseCommand {
  double v = 0.0;      // m/s forward
  double omega = 0.0;  // rad/s counter-clockwise
};
struct WheelSpeeds {
  double left = 0.0;   // m/s
  double right = 0.0;  // m/s
};

// Dead band + saturation on one axis, result in [-1, 1].
double dead_band_saturate(double u, double dead_band, double saturation);
BaseCommand navigation_command(const NavigationMap& n, const Eigen::Vector3d& p_B);
WheelSpeeds wheel_speeds(const NavigationMap& n, const BaseCommand& cmd);

// ---------------------------------------------------------------- manipulation
// M_T_B (the Cartesian part): the stylus maps onto a box centred at
// workspace_centre_R (in front of the arm base), scaled so the device's
// horizontal half extent spans `reach`; the target is then clamped into the
// ball of radius `reach` around the arm base (joint 1). Eq. 2-4 (the arm's
// kinematics) live in common/kinematics.
struct ManipulationMap {
  ScaledMap map;
  Eigen::Vector3d arm_base_R = Eigen::Vector3d::Zero();
  double reach = 0.5;  // m, Pioneer2 Arm
};
ManipulationMap make_manipulation_map(const DeviceWorkspace& ws, const Eigen::Vector3d& arm_base_R,
                                      const Eigen::Vector3d& workspace_centre_R, double reach_m);

struct ManipulationTarget {
  Eigen::Vector3d p_R = Eigen::Vector3d::Zero();
  bool clamped = false;
};
ManipulationTarget manipulation_target(const ManipulationMap& m, const Eigen::Vector3d& p_B);

// ---------------------------------------------------------------- mode switching
// The same virtual proxy serves all three modes; only the map from the stylus
// to the proxy's goal point changes. At a switch we RE-ANCHOR (we do not ramp):
// an offset in B is added to the stylus so that, right after the switch, the
// device-side spring vector (proxy_W - device_W) / scale is exactly what it was
// before it. The force k * that vector is therefore continuous across the
// switch. Afterwards the offset relaxes to zero at a bounded stylus-space
// speed, so the point moves continuously and the force changes at a bounded
// rate (<= k * relax_speed per second) until the new mode's natural map holds.
enum class Mode { kExploration, kNavigation, kManipulation };

struct ModeAnchor {
  Eigen::Vector3d offset_B = Eigen::Vector3d::Zero();
};

// The goal point in W of a map with an anchor offset.
inline Eigen::Vector3d anchored_point_W(const ScaledMap& m, const ModeAnchor& a, const Pose2& T_W_R,
                                        const Eigen::Vector3d& p_B) {
  return apply(T_W_R, map_point(m, p_B + a.offset_B));
}

// Anchor for the new map such that (proxy_W - point_W_new) / new.scale equals
// (proxy_W - device_W_old) / scale_old.
ModeAnchor reanchor_at_switch(const ScaledMap& new_map, const Pose2& T_W_R, const Eigen::Vector3d& p_B,
                              const Eigen::Vector3d& proxy_W, const Eigen::Vector3d& device_W_old,
                              double scale_old);

// Moves the offset toward zero by at most max_speed * dt (device metres).
void relax_anchor(ModeAnchor& a, double max_speed, double dt);

// A force computed in W (device newtons) expressed in B (axes aligned with R).
inline Eigen::Vector3d force_W_to_B(const Pose2& T_W_R, const Eigen::Vector3d& F_W) {
  return rotate(Pose2{0.0, 0.0, -T_W_R.theta}, F_W);
}

}  // namespace hemm::math
