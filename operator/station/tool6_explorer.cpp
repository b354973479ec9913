#include "operator/station/tool6_explorer.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/cache.h"
#include "common/haptics/vps/voxmap.h"
#include "common/haptics/vps/voxmap_surface.h"
#include "operator/station/explore_route.h"
#include "operator/station/operator_task.h"

namespace hemm::op {

std::string validate(const Tool6Params& p) {
  if (std::string e = vps::validate(p.geometry); !e.empty()) return e;
  if (!(std::isfinite(p.contact_stiffness) && p.contact_stiffness > 0 && p.contact_stiffness <= 1e10))
    return "contact stiffness must be in (0, 1e10] N/m^3";
  if (p.budget < 1) return "work budget must be >= 1";
  if (!(p.inferred_stiffness_scale > 0 && p.inferred_stiffness_scale <= 1))
    return "inferred stiffness scale must be in (0, 1]";
  if (p.tick_budget_ns < 0 || p.tick_budget_ns > 100'000'000 || p.tick_margin_ns < 0 ||
      p.tick_margin_ns > 100'000'000)
    return "tick budget and margin must be in [0, 100 ms]";
  if (!(p.calibration_voxel >= 1e-3 && p.calibration_voxel <= 0.1) || p.calibration_layers < 1 ||
      p.calibration_layers > 20)
    return "calibration voxel must be in [1, 100] mm, layers in [1, 20]";
  if (!p.origin_R.allFinite() || p.origin_R.norm() > 5.0) return "origin must be finite, within 5 m of the robot";
  if (!(p.period_s > 0 && p.period_s <= 0.01)) return "period must be in (0, 10 ms]";
  if (!(p.limits.peak_force > 0 && p.limits.max_stiffness > 0))
    return "the device's end-effector 0 must report a peak force and a stiffness";
  if (!p.T_H_D.matrix().allFinite() || !p.T_H_D.linear().isUnitary(1e-9) || p.T_H_D.linear().determinant() < 0 ||
      p.T_H_D.translation().norm() > 5.0)
    return "the device frame in H must be a rigid transform within 5 m";
  if (!p.R_E_P.allFinite() || !p.R_E_P.isUnitary(1e-9) || p.R_E_P.determinant() < 0)
    return "the tool's grasp R_E_P must be a rotation";
  return {};
}

Eigen::Isometry3d robot_pose3(const math::Pose2& T_W_R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(T_W_R.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(T_W_R.x, T_W_R.y, 0.0);
  return T;
}

Tool6Explorer::Tool6Explorer(const Tool6Params& p) : p_(p) {
  if (std::string e = validate(p); !e.empty()) throw std::invalid_argument("tool6: " + e);
  if (auto e = vps::make_probe_tool(p.geometry, &tool_)) throw std::invalid_argument("tool6: " + e->message);
  vps::CouplingDeviceLimits d;
  d.dt = p.period_s;
  d.peak_force = p.limits.peak_force;
  d.max_stiffness = p.limits.max_stiffness;
  if (p.limits.max_linear_speed > 0) d.max_speed = std::min(d.max_speed, p.limits.max_linear_speed);
  d.renders_torque = p.limits.renders_torque;
  d.peak_torque = p.limits.peak_torque;
  d.max_rot_stiffness = p.limits.max_rotational_stiffness;
  params_.coupling = vps::design_coupling(tool_.mass, tool_.inertia_com, d).params;
  params_.contact.stiffness = p.contact_stiffness;
  params_.contact.inferred_stiffness_scale = p.inferred_stiffness_scale;
  params_.budget = p.budget;
  vps::init_tool_state(tool_, &state_);
  vps::TimeBudgetParams tb;
  tb.tick_ns = p.tick_budget_ns;
  tb.margin_ns = p.tick_margin_ns;
  tb.max_work = p.budget;
  if (tb.tick_ns > 0) {
    // No live voxmap yet: the tool against a table-sized box of the live
    // voxmap's resolution stands in for it until the ticks measure their own.
    calibration_ = vps::calibrate_work_rate_on_box({0.3, 0.3, 0.1}, p.calibration_voxel, p.calibration_layers,
                                                   tool_.shell, params_.contact, tb.rate, 24, &steady_now_ns);
  }
  budget_ = vps::TickWorkBudget(tb, calibration_.rate);
}

void Tool6Explorer::tick(const device::EndEffectorSample& s, const math::Pose2& T_W_R, const vps::Voxmap* vm,
                         std::uint64_t voxmap_build, std::int64_t deadline_ns) noexcept {
  valid_ = s.position_H.allFinite() && s.orientation_H.coeffs().allFinite() && s.orientation_H.norm() > 0.5;
  // The sample is in the device's frame (D, the HapticDevice API's "H").
  const Eigen::Isometry3d T_W_D = robot_pose3(T_W_R) * Eigen::Translation3d(p_.origin_R) * p_.T_H_D;
  R_W_D_ = T_W_D.linear();
  if (valid_) {
    Eigen::Isometry3d T_D_P = Eigen::Isometry3d::Identity();
    T_D_P.linear() = s.orientation_H.normalized().toRotationMatrix() * p_.R_E_P;
    T_D_P.translation() = s.position_H;
    goal_W_ = T_W_D * T_D_P;
  }
  if (!s.enabled) vm = nullptr;  // a detached hand: the tool follows the device, nothing displayed
  // The pair state is of one build: a new build at the old one's address is
  // still new (forgetting the pointer makes probe_tool_tick start again).
  if (vm != nullptr && voxmap_build != voxmap_build_) state_.voxmap = nullptr;
  voxmap_build_ = voxmap_build;
  Eigen::Isometry3d goal = goal_W_;
  if (!valid_) goal.translation().x() = NAN;  // the tool keeps its pose, zero wrench
  if (vm == nullptr || !valid_) {  // nothing evaluated
    vps::probe_tool_tick(params_, tool_, vm, goal, &state_);
    return;
  }
  params_.budget = budget_.begin(steady_now_ns(), deadline_ns);
  vps::probe_tool_tick(params_, tool_, vm, goal, &state_);
  const int levels = state_.contact.levels_completed;
  budget_.end(steady_now_ns(), work(), levels, levels >= tool_.shell.levels);
  // How much of what is displayed came from inferred voxels (run totals).
  if (state_.contact.contacts > 0) {
    const double felt = state_.device.force.norm();
    ++contact_ticks_;
    if (state_.contact.inferred_contacts > 0) ++inferred_contact_ticks_;
    if (std::isfinite(felt)) {
      felt_sum_ += felt;
      felt_inferred_sum_ += felt * vps::inferred_share(state_.contact);
    }
  }
}

void Tool6Explorer::write(double gain, device::EndEffectorCommand& c) const noexcept {
  // The coupling's reaction acts at the goal's centre of mass; moved to the E point (the tip).
  const vps::Wrench& w = state_.device;
  const Eigen::Vector3d r = goal_W_.linear() * tool_.shell.reference_point;
  const Eigen::Vector3d F_D = R_W_D_.transpose() * (gain * w.force);
  const Eigen::Vector3d tau_D = R_W_D_.transpose() * (gain * (w.torque + r.cross(w.force)));
  c.force_H = F_D.allFinite() ? F_D : Eigen::Vector3d::Zero();
  c.torque_H = tau_D.allFinite() ? tau_D : Eigen::Vector3d::Zero();
}

void Tool6Explorer::fill(double gain, StationLogRecord& r) const noexcept {
  const Eigen::Quaterniond q(goal_W_.linear());
  const Eigen::Vector3d tool = vps::tool_pose_W(tool_, state_).translation();
  for (int i = 0; i < 3; ++i) {
    r.goal_W[i] = goal_W_.translation()[i];
    r.tool_W[i] = tool[i];
    r.torque_W[i] = gain * state_.device.torque[i];
  }
  r.goal_q[0] = q.w();
  r.goal_q[1] = q.x();
  r.goal_q[2] = q.y();
  r.goal_q[3] = q.z();
  r.force_W[0] = gain * state_.device.force.x();
  r.force_W[1] = gain * state_.device.force.y();
  r.force_W_z = gain * state_.device.force.z();
  r.contacts = state_.contact.contacts;
  r.tool_work = state_.contact.nodes_visited + state_.contact.points_tested;
  r.tool_levels = state_.contact.levels_completed;
  r.tool_model = state_.voxmap != nullptr ? 1 : 0;
}

bool write_tool6_params(const Tool6Explorer& t, const std::string& path, std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    *error = "cannot open " + path + " for writing";
    return false;
  }
  const vps::ProbeToolGeometry& g = t.params().geometry;
  const vps::ToolParams& p = t.tool_params();
  const vps::CouplingParams& c = p.coupling;
  std::fprintf(f, "tip_radius %.17g\nrod_radius %.17g\nrod_length %.17g\ntip_mass %.17g\nrod_mass %.17g\n",
               g.tip_radius, g.rod_radius, g.rod_length, g.tip_mass, g.rod_mass);
  // The work-unit budget (the time budget's cap: the truth replays at it).
  std::fprintf(f, "spacing %.17g\nlevels %d\nstiffness %.17g\nbudget %lld\n", g.spacing, g.levels,
               p.contact.stiffness, static_cast<long long>(t.params().budget));
  std::fprintf(f, "dt %.17g\nmass %.17g\nixx %.17g\niyy %.17g\nizz %.17g\n", c.dt, c.mass, c.inertia_body(0, 0),
               c.inertia_body(1, 1), c.inertia_body(2, 2));
  std::fprintf(f, "k_lin %.17g\nb_lin %.17g\nk_rot %.17g\nb_rot %.17g\nlinear_damping %.17g\nangular_damping %.17g\n",
               c.k_lin, c.b_lin, c.k_rot, c.b_rot, c.linear_damping, c.angular_damping);
  const bool ok = std::fclose(f) == 0;
  if (!ok) *error = "write failed: " + path;
  return ok;
}

bool write_voxmap_csv(const vps::Voxmap& vm, const std::string& path, std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    *error = "cannot open " + path + " for writing";
    return false;
  }
  std::fprintf(f, "x,y,z,sdf\n");
  vps::for_each_surface_voxel(vm, [&](const Eigen::Vector3i& v, const vps::Voxel& x) {
    const Eigen::Vector3d c = vps::voxel_centre(vm, v);
    std::fprintf(f, "%.4f,%.4f,%.4f,%.4f\n", c.x(), c.y(), c.z(), x.sdf);
  });
  const bool ok = std::fclose(f) == 0;
  if (!ok) *error = "write failed: " + path;
  return ok;
}

bool write_voxmap_vps(const vps::Voxmap& vm, const vps::PointShell& shell, const std::string& path,
                      std::string* error) {
  const std::vector<std::uint8_t> bytes = vps::serialize_vps(vm, shell);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    *error = "cannot open " + path + " for writing";
    return false;
  }
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size() && std::fclose(f) == 0;
  if (!ok) *error = "write failed: " + path;
  return ok;
}

device::Trajectory make_hand6_trajectory(const ExploreRoute& route, const Eigen::Vector3d& origin_R) {
  device::Trajectory tr;
  tr.end_effectors = 1;
  tr.has_orientation = true;
  for (const RouteKey& k : route.keys) {
    device::TrajectorySample s;
    s.t_s = k.t_s;
    s.end_effectors = 1;
    s.ee[0].position_H = k.tip_R - origin_R;
    s.ee[0].orientation_H = Eigen::Quaterniond(Eigen::AngleAxisd(k.tilt_x_rad, Eigen::Vector3d::UnitX()));
    tr.samples.push_back(s);
  }
  return tr;
}

device::Trajectory load_hand6_route(const std::string& scene_path, const std::string& name,
                                    const Eigen::Vector3d& origin_R, const device::EndEffectorLimits& limits) {
  SceneExploration x;
  if (auto e = load_scene_exploration(scene_path, &x)) throw std::invalid_argument("probe_3d.tool_hand_route: " + *e);
  const ExploreRoute* r = x.find(name);
  if (r == nullptr)
    throw std::invalid_argument("probe_3d.tool_hand_script: no route '" + name + "' in " + scene_path +
                                " (its explore6 routes: " + x.route_names() + ")");
  if (auto e = check_route_reach(*r, origin_R, limits, scene_path))
    throw std::invalid_argument("probe_3d.tool_hand_script: " + *e);
  return make_hand6_trajectory(*r, origin_R);
}

}  // namespace hemm::op
