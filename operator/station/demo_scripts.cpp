#include "operator/station/demo_scripts.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "operator/device/haptic_device.h"

namespace hemm::op {
namespace {
// B (x forward, y left, z up) -> H (x right, y up, z towards the user).
Eigen::Vector3d h_from_b(double xb, double yb, double zb) { return {-yb, zb, -xb}; }

constexpr double kExplorationScale = 50.0;  // exploration: 4 m over the Omni's 0.08 m

// Inverse of math::dead_band_saturate: the stylus offset that commands the
// fraction a in [-1, 1] of the axis' maximum (0 stays at the centre).
double offset_for_fraction(double a, double dead_band, double saturation) {
  if (!(std::abs(a) > 0.0)) return 0.0;
  const double m = dead_band + std::min(1.0, std::abs(a)) * (saturation - dead_band);
  return a < 0.0 ? -m : m;
}

}  // namespace

std::string validate(const NavGoalParams& p) {
  if (std::string e = math::validate(p.nav); !e.empty()) return "nav: " + e;
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!pos(p.stop_distance) || !pos(p.pass_radius) || !pos(p.k_distance) || !pos(p.v_cruise) ||
      !pos(p.k_heading) || !pos(p.omega_cruise) || !pos(p.turn_in_place) || !pos(p.max_offset) || !pos(p.hand_speed))
    return "stop_distance, pass_radius, gains, cruise speeds, turn_in_place, max_offset, hand_speed must be > 0";
  if (!(std::isfinite(p.tolerance) && p.tolerance >= p.stop_distance)) return "tolerance must be >= stop_distance";
  if (!(std::isfinite(p.v_min) && p.v_min >= 0.0 && p.v_min <= p.v_cruise)) return "need 0 <= v_min <= v_cruise";
  if (!(std::isfinite(p.reverse_range) && p.reverse_range >= 0.0)) return "reverse_range must be >= 0";
  if (!pos(p.rearm_release_s) || !(std::isfinite(p.rearm_retry_s) && p.rearm_retry_s > p.rearm_release_s))
    return "need 0 < rearm_release_s < rearm_retry_s";
  return {};
}

NavHandTarget hand_target_for_goal(const OperatorView& view, const Eigen::Vector2d& goal_W, const NavGoalParams& p,
                                   bool final_goal, bool was_arrived) noexcept {
  NavHandTarget out;
  if (!view.valid || view.mode != math::Mode::kNavigation || !math::is_finite(view.T_W_R) || !goal_W.allFinite())
    return out;  // nothing sensible to steer by: hands off (centre)
  const Eigen::Vector2d d_W = goal_W - Eigen::Vector2d(view.T_W_R.x, view.T_W_R.y);
  const double dist = d_W.norm();
  out.distance = dist;
  if (final_goal && (dist < p.stop_distance || (was_arrived && dist < p.tolerance))) {
    out.arrived = true;
    return out;
  }
  double e = math::wrap_angle(std::atan2(d_W.y(), d_W.x()) - view.T_W_R.theta);
  double dir = 1.0;
  if (final_goal && std::abs(e) > 0.5 * std::numbers::pi && dist < p.reverse_range) {
    dir = -1.0;  // close behind: back up, steering the robot's back onto the goal
    e = math::wrap_angle(e - std::numbers::pi);
  }
  out.heading_error = e;
  const double cut = std::clamp(1.0 - std::abs(e) / p.turn_in_place, 0.0, 1.0);
  const double speed = final_goal ? std::clamp(p.k_distance * dist, p.v_min, p.v_cruise) : p.v_cruise;
  const double v = dir * speed * cut;
  const double omega = std::clamp(p.k_heading * e, -p.omega_cruise, p.omega_cruise);
  const double x_B = std::clamp(offset_for_fraction(v / p.nav.v_max, p.nav.dead_band, p.nav.saturation),
                                -p.max_offset, p.max_offset);
  const double y_B = std::clamp(offset_for_fraction(omega / p.nav.omega_max, p.nav.dead_band, p.nav.saturation),
                                -p.max_offset, p.max_offset);
  out.position_H = h_from_b(x_B, y_B, 0.0);
  return out;
}

NavGoalHand::NavGoalHand(std::shared_ptr<const OperatorView> view, std::vector<Eigen::Vector2d> route_W,
                         const NavGoalParams& p)
    : view_(std::move(view)), route_(std::move(route_W)), p_(p) {
  if (!view_) throw std::invalid_argument("NavGoalHand: null view");
  if (route_.empty()) throw std::invalid_argument("NavGoalHand: empty route");
  for (std::size_t i = 0; i < route_.size(); ++i)
    if (!route_[i].allFinite()) throw std::invalid_argument("NavGoalHand: non-finite goal " + std::to_string(i));
  if (std::string e = validate(p_); !e.empty()) throw std::invalid_argument("NavGoalHand: " + e);
}

device::HandTarget NavGoalHand::at(double t_s) const noexcept {
  const OperatorView& v = *view_;
  if (v.resyncs != resyncs_seen_) {
    // The robot restarted (and its W with it): the route starts again from
    // where the robot now is, not from where the old one had got to.
    resyncs_seen_ = v.resyncs;
    index_ = 0;
    arrived_ = false;
  }
  // Intermediate goals are passed (not stopped at) inside pass_radius.
  while (index_ + 1 < route_.size() && v.valid && math::is_finite(v.T_W_R) &&
         (route_[index_] - Eigen::Vector2d(v.T_W_R.x, v.T_W_R.y)).norm() < p_.pass_radius)
    ++index_;
  const bool final_goal = index_ + 1 == route_.size();
  last_ = hand_target_for_goal(v, route_[index_], p_, final_goal, arrived_);
  if (last_.arrived && !arrived_) {
    ++arrivals_;
    if (first_arrival_s_ < 0.0 && std::isfinite(t_s)) first_arrival_s_ = t_s;
  }
  arrived_ = last_.arrived;
  // A hand moves at a finite speed: step toward the wanted position.
  double dt = started_ && std::isfinite(t_s) ? t_s - t_prev_ : 0.0;
  dt = std::clamp(dt, 0.0, 0.1);
  if (std::isfinite(t_s)) t_prev_ = t_s;
  started_ = true;
  const Eigen::Vector3d step = last_.position_H - position_H_;
  const double max_step = p_.hand_speed * dt;
  const double n = step.norm();
  position_H_ += n > max_step ? Eigen::Vector3d(step * (max_step / n)) : step;
  device::HandTarget out;
  out.position_H = position_H_;
  // The dead-man: held, but let go briefly when the robot waits to be re-armed.
  if (v.valid && (v.robot_safety & wire::SAFETY_REARM) != 0 && std::isfinite(t_s) && t_s >= next_rearm_s_) {
    release_until_s_ = t_s + p_.rearm_release_s;
    next_rearm_s_ = t_s + p_.rearm_retry_s;
  }
  out.deadman = !(std::isfinite(t_s) && t_s < release_until_s_);
  return out;
}

std::vector<Eigen::Vector2d> default_nav_goal_route() { return {{2.2, 0.0}, {2.45, -1.6}}; }
Eigen::Vector2d nav_to_wall_target() { return {4.5, 1.6}; }
std::vector<Eigen::Vector2d> default_probe_line() { return {{1.42, -0.8}, {1.42, -1.6}}; }

std::vector<std::string> demo_script_names() { return {"idle", "nav-to-wall", "probe-cylinder", "nav-to-goal"}; }

DemoScript make_demo_script(std::string_view name, const DemoScriptOptions& o) {
  DemoScript d;
  if (!o.route_W.empty() && name != "nav-to-goal" && name != "nav-to-wall")
    throw std::invalid_argument("a goal route is for nav-to-goal or nav-to-wall");
  if (name == "nav-to-wall" && o.route_W.size() > 1)
    throw std::invalid_argument("nav-to-wall takes one goal (a point behind the wall)");
  if (!o.probe_line_W.empty()) {
    if (name != "probe-cylinder") throw std::invalid_argument("a probe line is for probe-cylinder");
    if (o.probe_line_W.size() != 2) throw std::invalid_argument("a probe line is two points");
    // The probe goes only where the SIMULATED Omni's stylus can take it at
    // the exploration scale: a point beyond would be probed at the box's
    // edge instead, silently somewhere else.
    const device::DeviceLimits omni_device = device::phantom_omni_limits();
    const device::EndEffectorLimits& omni = omni_device.ee[0];
    for (const Eigen::Vector2d& q : o.probe_line_W) {
      if (!q.allFinite()) throw std::invalid_argument("probe line points must be finite");
      if (!omni.contains(h_from_b(q.x() / kExplorationScale, q.y() / kExplorationScale, 0.0))) {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "probe line point (%.2f, %.2f) is beyond what exploration reaches with the SIMULATED Omni "
                      "(%.2f m ahead or behind, %.2f m to either side of the robot's start)",
                      q.x(), q.y(), -omni.workspace_min_H.z() * kExplorationScale,
                      omni.workspace_max_H.x() * kExplorationScale);
        throw std::invalid_argument(buf);
      }
    }
  }
  if (name == "idle") {
    d.hand = std::make_shared<device::HoldScript>(Eigen::Vector3d::Zero());
    d.mode = math::Mode::kExploration;
  } else if (name == "nav-to-wall") {
    // The operator steers for a point behind wall_mid_n and keeps pushing.
    d.view = std::make_shared<OperatorView>();
    auto hand = std::make_shared<const NavGoalHand>(
        d.view, o.route_W.empty() ? std::vector<Eigen::Vector2d>{nav_to_wall_target()} : o.route_W);
    d.nav_goal = hand;
    d.hand = hand;
    d.mode = math::Mode::kNavigation;
    d.duration_s = 14.0;
  } else if (name == "probe-cylinder") {
    auto b = [](double xw, double yw) { return h_from_b(xw / kExplorationScale, yw / kExplorationScale, 0.0); };
    std::vector<device::Waypoint> w;
    w.push_back({0.0, Eigen::Vector3d::Zero(), 0});
    w.push_back({1.0, Eigen::Vector3d::Zero(), 0});
    // Default: 8 cm west of the bin's centre line, so the proxy slides round its side.
    const std::vector<Eigen::Vector2d> line = o.probe_line_W.empty() ? default_probe_line() : o.probe_line_W;
    w.push_back({3.0, b(line[0].x(), line[0].y()), 0});
    w.push_back({9.0, b(line[1].x(), line[1].y()), 0});
    w.push_back({15.0, b(line[0].x(), line[0].y()), 0});
    w.push_back({17.0, Eigen::Vector3d::Zero(), 0});
    d.hand = std::make_shared<device::WaypointScript>(std::move(w));
    d.mode = math::Mode::kExploration;
    d.duration_s = 17.0;
  } else if (name == "nav-to-goal") {
    d.view = std::make_shared<OperatorView>();
    auto hand = std::make_shared<const NavGoalHand>(d.view, o.route_W.empty() ? default_nav_goal_route() : o.route_W);
    d.nav_goal = hand;
    d.hand = hand;
    d.mode = math::Mode::kNavigation;
    d.duration_s = 25.0;
  }
  return d;
}

math::ScaledMap probe3d_map_of(const OperatorTaskParams& p) {
  // As OperatorServoTask maps the stylus for the point probe (operator_task.cpp).
  return {p.probe3d_range / math::horizontal_half_extent(p.workspace), p.workspace.centre_B, p.probe3d_origin_R};
}

std::shared_ptr<const device::WaypointScript> make_hand3_script(const ExploreRoute3& r, const math::Pose2& start_W,
                                                                const math::ScaledMap& m) {
  std::vector<device::Waypoint> w;
  w.reserve(r.keys.size());
  for (const Route3Key& k : r.keys) w.push_back({k.t_s, route3_point_H(k.p_W, start_W, m), 0, false});
  return std::make_shared<const device::WaypointScript>(std::move(w));
}

std::shared_ptr<const device::WaypointScript> load_hand3_route(const std::string& scene_path, const std::string& name,
                                                               const OperatorTaskParams& task) {
  if (!task.probe_3d)
    throw std::invalid_argument("probe_3d.hand3_script: the 3-DoF route needs the point probe (probe_3d { enabled: "
                                "true tool: \"point\" })");
  SceneExploration x;
  if (auto e = load_scene_exploration(scene_path, &x)) throw std::invalid_argument("probe_3d.hand3_route: " + *e);
  const ExploreRoute3* r = x.find3(name);
  if (r == nullptr)
    throw std::invalid_argument("probe_3d.hand3_script: no route '" + name + "' in " + scene_path +
                                " (its explore3 routes: " + x.route3_names() + ")");
  const math::ScaledMap m = probe3d_map_of(task);
  if (auto e = check_route3_reach(*r, x.start_W, m, device::phantom_omni_limits().ee[0], scene_path))
    throw std::invalid_argument("probe_3d.hand3_script: " + *e);
  return make_hand3_script(*r, x.start_W, m);
}

}  // namespace hemm::op
