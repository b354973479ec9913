#include "operator/station/operator_task.h"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace hemm::op {

Eigen::Matrix3d R_B_H() {
  Eigen::Matrix3d r;
  r << 0, 0, -1,  //
      -1, 0, 0,   //
      0, 1, 0;
  return r;
}

wire::Mode to_wire_mode(math::Mode m) {
  switch (m) {
    case math::Mode::kExploration: return wire::MODE_EXPLORATION;
    case math::Mode::kNavigation: return wire::MODE_NAVIGATION;
    case math::Mode::kManipulation: return wire::MODE_MANIPULATION;
  }
  return wire::MODE_IDLE;
}

const char* station_log_header() {
  return "t_ns,mode,robot_x,robot_y,robot_theta,goal_x,goal_y,goal_z,proxy_x,proxy_y,fw_x,fw_y,"
         "fh_x,fh_y,fh_z,v,omega,contacts,model_version,model_age_ns,scale,state_stamp_ns,odom_x,odom_y,odom_theta,"
         "truth_x,truth_y,truth_theta,has_truth,force_gain,proxy3_x,proxy3_y,proxy3_z,fw_z,probe3_contact,"
         "goal_qw,goal_qx,goal_qy,goal_qz,tool_x,tool_y,tool_z,tw_x,tw_y,tw_z,tool_work,tool_levels,tool_model";
}

std::size_t format_station_log_record(const StationLogRecord& r, char* buf, std::size_t size) {
  const int n = std::snprintf(
      buf, size,
      "%" PRId64 ",%u,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%d,%" PRIu64
      ",%" PRId64 ",%.6f,%" PRId64 ",%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d,%.4f,%.6f,%.6f,%.6f,%.5f,%d,"
      "%.7f,%.7f,%.7f,%.7f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%" PRId64 ",%d,%d\n",
      r.t_ns, r.mode, r.robot[0], r.robot[1], r.robot[2], r.goal_W[0], r.goal_W[1], r.goal_W[2], r.proxy_W[0],
      r.proxy_W[1], r.force_W[0], r.force_W[1], r.force_H[0], r.force_H[1], r.force_H[2], r.v, r.omega, r.contacts,
      r.model_version, r.model_age_ns, r.scale, r.state_stamp_ns, r.odom[0], r.odom[1], r.odom[2], r.truth[0],
      r.truth[1], r.truth[2], r.has_truth, r.force_gain, r.proxy3_W[0], r.proxy3_W[1], r.proxy3_W[2], r.force_W_z,
      r.probe3_contact, r.goal_q[0], r.goal_q[1], r.goal_q[2], r.goal_q[3], r.tool_W[0], r.tool_W[1], r.tool_W[2],
      r.torque_W[0], r.torque_W[1], r.torque_W[2], r.tool_work, r.tool_levels, r.tool_model);
  if (n < 0 || static_cast<std::size_t>(n) >= size) return 0;
  return static_cast<std::size_t>(n);
}

bool device_deadman(const device::DeviceSample& in) noexcept {
  bool any = false, all = true;
  const int n = std::clamp(in.end_effectors, 0, device::kMaxEndEffectors);
  for (int i = 0; i < n; ++i) {
    const device::HandleInputs& h = in.ee[static_cast<std::size_t>(i)].handle;
    if (!h.has_deadman) continue;
    any = true;
    all = all && h.deadman;
  }
  return any && all;
}

OperatorServoTask::OperatorServoTask(const OperatorTaskParams& p, StationLogger* log, OperatorView* view)
    : p_(p), mode_(p.initial_mode), log_(log), view_(view) {
  if (std::string e = haptics::validate(p.proxy); !e.empty())
    throw std::invalid_argument("OperatorServoTask: proxy: " + e);
  if (!(p.exploration_range > 0) || !(p.navigation_look_ahead > 0) || !(p.arm_reach > 0) ||
      !(p.relax_speed > 0) || !(p.max_extrapolation_s >= 0) || !(p.engage_move > 0) ||
      !std::isfinite(p.engage_move))
    throw std::invalid_argument("OperatorServoTask: ranges, reach, relax speed, engage_move must be positive");
  explore_ = math::make_exploration_map(p.workspace, p.exploration_range);
  navigate_ = math::make_navigation_map(p.workspace, p.navigation_look_ahead);
  if (!p.navigation_point_origin_R.allFinite() || p.navigation_point_origin_R.norm() > 5.0)
    throw std::invalid_argument("OperatorServoTask: navigation_point_origin_R must be finite, within 5 m");
  navigate_.point_map.origin_R = p.navigation_point_origin_R;
  manipulate_ = math::make_manipulation_map(p.workspace, p.arm_base_R, p.arm_workspace_centre_R, p.arm_reach);
  if (std::string e = math::validate(navigate_); !e.empty())
    throw std::invalid_argument("OperatorServoTask: navigation map: " + e);
  proxy_ = haptics::make_proxy_data(p.proxy);
  if (p.probe_3d) {
    p_.probe3d.force.period = p.proxy.period;
    if (std::string e = vps::validate(p_.probe3d); !e.empty())
      throw std::invalid_argument("OperatorServoTask: probe3d: " + e);
    if (!(p.probe3d_range > 0.0 && p.probe3d_range <= 10.0) || !p.probe3d_origin_R.allFinite() ||
        p.probe3d_origin_R.norm() > 5.0)
      throw std::invalid_argument("OperatorServoTask: probe3d_range in (0, 10] m, origin within 5 m");
    tool_probe_params_ = p_.probe3d;
    tool_probe_params_.force.probe_radius = p.tool_probe_radius;
    if (std::string e = vps::validate(tool_probe_params_); !e.empty())
      throw std::invalid_argument("OperatorServoTask: tool probe: " + e);
  }
  probe3d_map_.scale = p.probe3d_range / math::horizontal_half_extent(p.workspace);
  probe3d_map_.centre_B = p.workspace.centre_B;
  probe3d_map_.origin_R = p.probe3d_origin_R;
  if (p.tool6.enabled) {
    Tool6Params t = p.tool6;
    t.period_s = p.proxy.period;
    tool6_ = std::make_unique<Tool6Explorer>(t);  // throws on bad parameters
  }
  empty_map_ = mapping::build_snapshot(mapping::MapParams{}, mapping::LocalMap{});
  last_.mode = mode_;
}

const math::ScaledMap& OperatorServoTask::map_of(math::Mode m) const noexcept {
  switch (m) {
    case math::Mode::kNavigation: return navigate_.point_map;
    case math::Mode::kManipulation: return manipulate_.map;
    case math::Mode::kExploration: break;
  }
  return explore_.map;
}

void OperatorServoTask::switch_to(math::Mode next, const Eigen::Vector3d& p_B) noexcept {
  if (next == mode_) return;
  const Eigen::Vector3d proxy3(proxy_.proxy_W.x(), proxy_.proxy_W.y(), goal_W_.z());
  anchor_ = math::reanchor_at_switch(map_of(next), T_W_R_, p_B, proxy3, goal_W_, map_of(mode_).scale);
  mode_ = next;
  ++switches_;
  hold_motion(p_B);
}

void OperatorServoTask::hold_motion(const Eigen::Vector3d& p_B) noexcept {
  if (!held_) ++holds_;
  held_ = true;
  hold_moved_ = false;
  hold_neutral_ = false;
  hold_ref_B_ = p_B;
}

void OperatorServoTask::tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
                             servo::TickOutput& out) noexcept {
  ++ticks_;
  const auto* snap = model.version != 0 ? dynamic_cast<const OperatorModelSnapshot*>(&model) : nullptr;
  const mapping::MapSnapshot& map = snap != nullptr ? snap->map : empty_map_;
  if (snap != nullptr && snap->have_state) {
    double dt = static_cast<double>(in.t_ns - snap->stamp_ns) * 1e-9;
    dt = std::clamp(dt, 0.0, p_.max_extrapolation_s);
    T_W_R_ = integrate_unicycle(snap->T_W_R, snap->v, snap->omega, dt);
  }
  const Eigen::Matrix3d R = R_B_H();
  const Eigen::Vector3d& p_H = in.ee[0].position_H;  // the Omni's stylus: end-effector 0
  // A pose that is not finite is not the device origin: the point stays
  // where the last finite one was, and all motion is held (below).
  const bool pose_ok = p_H.allFinite() && in.ee[0].orientation_H.coeffs().allFinite();
  if (pose_ok) {
    p_B_last_ = R * p_H;
  } else {
    ++nonfinite_poses_;
  }
  const Eigen::Vector3d p_B = p_B_last_;

  // A model going stale (or a robot restart being taken in): the force fades
  // (never a step: the gain moves at most 1 / fade per second whatever its
  // target does) and the robot is held.
  bool stale = false;
  double gain_target = 1.0, fade_s = 1.0;
  if (snap != nullptr) {
    fade_s = static_cast<double>(snap->fade_ns) * 1e-9;
    if (snap->have_data) {
      const std::int64_t over = in.t_ns - snap->data_stamp_ns - snap->stale_after_ns;
      stale = over > 0;
      gain_target = std::clamp(1.0 - static_cast<double>(over) / static_cast<double>(snap->fade_ns), 0.0, 1.0);
    }
    if (snap->resyncing) {
      stale = true;
      gain_target = 0.0;
    }
  }
  const double gain_step = p_.proxy.period / std::max(fade_s, 1e-3);
  force_gain_ += std::clamp(gain_target - force_gain_, -gain_step, gain_step);
  const bool resynced = snap != nullptr && snap->resyncs != resyncs_seen_;
  if (resynced) resyncs_seen_ = snap->resyncs;

  // Buttons: rising edges switch modes (not on the very first tick: a held
  // button at start-up is not a press). Both down is the e-stop.
  constexpr std::uint32_t kBoth = device::kButton1 | device::kButton2;
  const std::uint32_t buttons = in.ee[0].handle.buttons;
  const std::uint32_t pressed =
      view_presses_ != nullptr ? view_presses_->exchange(0, std::memory_order_relaxed) : 0u;
  const std::uint32_t rising = first_ ? 0u : ((buttons & ~buttons_prev_) | pressed);
  const bool estop_press = !first_ && (buttons & kBoth) == kBoth && (buttons_prev_ & kBoth) != kBoth;
  buttons_prev_ = buttons;
  if (estop_press) {
    ++estop_presses_;
    hold_motion(p_B);
  }
  if (stale) hold_motion(p_B);  // held from where the hand is when the model is fresh again
  if (!pose_ok) hold_motion(p_B);  // held from the last finite point until the hand moves on from there
  if (!estop_press && !first_) {
    if (rising & device::kButton1) {
      switch_to(mode_ == math::Mode::kExploration   ? math::Mode::kNavigation
                : mode_ == math::Mode::kNavigation ? math::Mode::kManipulation
                                                   : math::Mode::kExploration,
                p_B);
    } else if (rising & device::kButton2) {
      switch_to(mode_ == math::Mode::kNavigation ? math::Mode::kExploration : math::Mode::kNavigation, p_B);
    }
  }
  math::relax_anchor(anchor_, p_.relax_speed, p_.proxy.period);

  const math::ScaledMap& sm = map_of(mode_);
  goal_W_ = math::anchored_point_W(sm, anchor_, T_W_R_, p_B);
  if (first_ || resynced) {
    // Start-up, or a restarted robot's map and pose just took over (the force
    // has faded out): the proxy starts again at the goal.
    haptics::proxy_reset(proxy_, goal_W_.head<2>());
    if (first_) ++holds_;  // start-up: held from the first tick
    hold_ref_B_ = p_B;
    first_ = false;
  }
  haptics::proxy_tick(p_.proxy, map, proxy_, goal_W_, sm.scale);

  // The proxy seen from the device: R frame, then B of the active map.
  const Eigen::Vector2d proxy_R2 = math::apply(math::inverse(T_W_R_), proxy_.proxy_W);
  const Eigen::Vector3d proxy_R(proxy_R2.x(), proxy_R2.y(), math::map_point(sm, p_B + anchor_.offset_B).z());
  Eigen::Vector3d proxy_B = math::unmap_point(sm, proxy_R) - anchor_.offset_B;

  // The 3-DoF point probe on the live voxmap (exploration): its force
  // replaces the 2D proxy's; the 2D proxy keeps running for the mode switches.
  const bool probe3 = p_.probe_3d && mode_ == math::Mode::kExploration;
  if (probe3) {
    probe3d_goal_W_ = math::anchored_point_W(probe3d_map_, anchor_, T_W_R_, p_B);
    if (resynced || !probe3d_.initialized) vps::point_probe_reset(probe3d_, probe3d_goal_W_);
    const vps::Voxmap* vm = snap != nullptr && !snap->resyncing ? snap->voxmap.get() : nullptr;
    vps::point_probe_tick(p_.probe3d, vm, probe3d_, probe3d_goal_W_, probe3d_map_.scale);
    const Eigen::Vector3d proxy3_R = math::apply(math::inverse(T_W_R_), probe3d_.proxy_W);
    proxy_B = math::unmap_point(probe3d_map_, proxy3_R) - anchor_.offset_B;
  }
  if (probe_out_ != nullptr) {
    probe_out_->back() = ProbePosition{probe3d_.proxy_W, probe3};
    probe_out_->publish();
  }

  // The 6-DoF tool on the live voxmap (exploration): its wrench replaces the
  // force below (tool6_explorer.h).
  const bool tool6 = tool6_ != nullptr && mode_ == math::Mode::kExploration;
  if (tool6) {
    const bool live = snap != nullptr && snap->have_state && !snap->resyncing;
    tool6_->tick(in.ee[0], T_W_R_, live ? snap->voxmap.get() : nullptr, live ? snap->voxmap_builds : 0,
                 out.deadline_ns);
  }

  // Manipulation through the model (issue 13): the point probe at the tool
  // tip on the live voxmap; the arm target below is taken from its proxy
  // (proxy_B), so the commanded tool stops on the model's surface.
  const bool tool3 = p_.probe_3d && mode_ == math::Mode::kManipulation;
  if (tool3) {
    if (resynced || !tool_probe_active_ || !tool_probe_.initialized) vps::point_probe_reset(tool_probe_, goal_W_);
    const vps::Voxmap* vm = snap != nullptr && !snap->resyncing ? snap->voxmap.get() : nullptr;
    vps::point_probe_tick(tool_probe_params_, vm, tool_probe_, goal_W_, sm.scale);
    const Eigen::Vector3d tool_R = math::apply(math::inverse(T_W_R_), tool_probe_.proxy_W);
    proxy_B = math::unmap_point(sm, tool_R) - anchor_.offset_B;
  }
  tool_probe_active_ = tool3;

  StationSetpoint sp;
  sp.t_ns = in.t_ns;
  sp.tick = ticks_;
  sp.mode = mode_;
  sp.estop_presses = estop_presses_;
  sp.nonfinite_poses = nonfinite_poses_;
  sp.deadman = pose_ok && device_deadman(in);
  math::BaseCommand nav_cmd;
  if (mode_ == math::Mode::kNavigation) nav_cmd = math::navigation_command(navigate_, proxy_B + anchor_.offset_B);
  if (held_) {
    if ((p_B - hold_ref_B_).norm() >= p_.engage_move) hold_moved_ = true;
    if (mode_ != math::Mode::kNavigation || (nav_cmd.v == 0.0 && nav_cmd.omega == 0.0)) hold_neutral_ = true;
    held_ = !(hold_moved_ && hold_neutral_);
  }
  if (held_) {
    // Nothing moves: zero command, no arm target, deadman released.
  } else if (mode_ == math::Mode::kNavigation) {
    sp.v = nav_cmd.v;
    sp.omega = nav_cmd.omega;
    sp.moves_robot = true;
  } else if (mode_ == math::Mode::kManipulation) {
    const math::ManipulationTarget t = math::manipulation_target(manipulate_, proxy_B + anchor_.offset_B);
    sp.arm_target_R = t.p_R;
    sp.arm_valid = true;
    sp.moves_robot = true;
  }
  if (tool6) {
    sp.tool_W = tool6_->goal_W().translation();
    sp.tool_valid = true;
  } else if (probe3) {
    sp.tool_W = probe3d_goal_W_;
    sp.tool_valid = true;
  }
  last_ = sp;
  setpoints_.publish(sp);

  const Eigen::Vector3d F_W =
      force_gain_ * (probe3 ? probe3d_.force_W : tool3 ? tool_probe_.force_W : proxy_.force_W);  // rendered
  const Eigen::Vector3d F_B = math::force_W_to_B(T_W_R_, F_W);
  const Eigen::Vector3d F_H = R.transpose() * F_B;
  out.command.ee[0].force_H = F_H.allFinite() ? F_H : Eigen::Vector3d::Zero();
  if (tool6) tool6_->write(force_gain_, out.command.ee[0]);
  out.publish_setpoint = false;  // the base / arm command travels in StationSetpoint
  out.points[0].proxy_position_H = R.transpose() * proxy_B;
  out.points[0].interaction_point_H = R.transpose() * (p_B + anchor_.offset_B);
  out.mode = static_cast<std::uint32_t>(to_wire_mode(mode_));
  // The renderer whose force is displayed and its work (the 2D proxy runs
  // every tick beside the others, bounded by its caps).
  if (tool6) {
    out.renderer = "tool6";
    out.work = tool6_->work();
  } else if (probe3 || tool3) {
    out.renderer = "point_probe";
    out.work = static_cast<std::int64_t>(probe3 ? probe3d_.work : tool_probe_.work);
  } else {
    out.renderer = "proxy2d";
    out.work = static_cast<std::int64_t>(proxy_.work);
  }

  if (view_ != nullptr) {
    view_->T_W_R = T_W_R_;
    view_->t_ns = in.t_ns;
    view_->mode = mode_;
    view_->valid = snap != nullptr && snap->have_state && !stale;
    view_->resyncs = resyncs_seen_;
    view_->robot_safety = snap != nullptr && snap->have_state ? snap->state.safety : 0u;
  }

  if (log_ != nullptr || view_ticks_ != nullptr) {
    StationLogRecord r;
    r.t_ns = in.t_ns;
    r.mode = out.mode;
    r.robot[0] = T_W_R_.x;
    r.robot[1] = T_W_R_.y;
    r.robot[2] = T_W_R_.theta;
    for (int i = 0; i < 3; ++i) r.goal_W[i] = probe3 ? probe3d_goal_W_[i] : goal_W_[i];
    r.proxy_W[0] = proxy_.proxy_W.x();
    r.proxy_W[1] = proxy_.proxy_W.y();
    r.force_W[0] = F_W.x();
    r.force_W[1] = F_W.y();
    r.force_W_z = F_W.z();
    if (probe3 || tool3) {
      const vps::PointProbeData& pd = probe3 ? probe3d_ : tool_probe_;
      for (int i = 0; i < 3; ++i) r.proxy3_W[i] = pd.proxy_W[i];
      r.probe3_contact = pd.contact ? 1 : 0;
    }
    r.force_gain = force_gain_;
    for (int i = 0; i < 3; ++i) r.force_H[i] = out.command.ee[0].force_H[i];
    r.v = sp.v;
    r.omega = sp.omega;
    r.contacts = probe3 ? (probe3d_.contact ? 1 : 0) : tool3 ? (tool_probe_.contact ? 1 : 0) : proxy_.contact_count;
    r.model_version = model.version;
    r.model_age_ns = model.version != 0 ? in.t_ns - model.stamp_ns : -1;
    r.scale = sm.scale;
    if (snap != nullptr && snap->have_state) {
      const RobotStateSample& st = snap->state;
      r.state_stamp_ns = st.stamp_local_ns;
      r.odom[0] = st.T_W_R_odom.x;
      r.odom[1] = st.T_W_R_odom.y;
      r.odom[2] = st.T_W_R_odom.theta;
      r.truth[0] = st.T_W_R_truth.x;
      r.truth[1] = st.T_W_R_truth.y;
      r.truth[2] = st.T_W_R_truth.theta;
      r.has_truth = st.has_truth ? 1 : 0;
    }
    if (tool6) tool6_->fill(force_gain_, r);
    if (log_ != nullptr) log_->push(r);
    if (view_ticks_ != nullptr) view_ticks_->publish(r);
  }
  if (tick_tap_ != nullptr) {
    tap_record_.tick = out.setpoint.tick;
    tap_record_.in = in;
    tap_record_.model_version = model.version;
    tap_record_.command = out.command;
    tap_record_.view_presses = pressed;
    tap_record_.mode = out.mode;
    tick_tap_->push(tap_record_);
  }
}

}  // namespace hemm::op
