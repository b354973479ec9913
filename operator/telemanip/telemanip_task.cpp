#include "operator/telemanip/telemanip_task.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::op::telemanip {

namespace {

Eigen::Isometry3d teletask_pose(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = p;
  return T;
}

HandReading teletask_hand(const device::DeviceSample& in, int k, const ArmMappingParams& mp) {
  HandReading h;
  const device::EndEffectorSample& e = in.ee[static_cast<std::size_t>(k)];
  const bool finite = e.position_H.allFinite() && e.orientation_H.coeffs().allFinite() && e.orientation_H.norm() > 0.5;
  h.valid = finite && e.enabled && k < in.end_effectors;
  if (finite) h.T_D_E = teletask_pose(e.position_H, e.orientation_H);
  const int g = mp.deadman_ee;
  const device::HandleInputs& gate = in.ee[static_cast<std::size_t>(g)].handle;
  h.deadman = g < in.end_effectors && gate.has_deadman && gate.deadman;
  h.clutch = g < in.end_effectors && (gate.buttons & clutch_bit(mp)) != 0;
  h.has_grip = e.handle.has_grip;
  h.grip_position_m = e.handle.grip_position;
  if (!h.has_grip && e.handle.has_joystick) {
    // The joystick handle has no lever: its mini-joystick's forward axis
    // (0..1, back is open) stands in for one, so that arm's gripper is commanded too.
    h.has_grip = true;
    h.grip_position_m = std::clamp(e.handle.joystick.y(), 0.0, 1.0) * mp.grip_travel_m;
  }
  return h;
}

}  // namespace

std::string validate(const TelemanipTaskParams& p) {
  for (const ArmMappingParams& m : p.mapping)
    if (std::string e = validate(m); !e.empty()) return "mapping: " + e;
  if (p.mode == FeedbackMode::kDirect) {
    if (p.render) return "the direct mode renders no model (render must be off)";
    for (const DirectHandParams& d : p.direct)
      if (std::string e = validate(d); !e.empty()) return "direct: " + e;
  }
  if (std::string e = validate(p.gripper); !e.empty()) return e;
  if (std::string e = validate(p.held); !e.empty()) return e;
  if (!(std::isfinite(p.contact_stiffness) && p.contact_stiffness > 0 && p.contact_stiffness <= 1e10))
    return "contact stiffness must be in (0, 1e10] N/m^3";
  if (p.budget < 1) return "work budget must be >= 1";
  if (p.tick_budget_ns < 0 || p.tick_budget_ns > 100'000'000 || p.tick_margin_ns < 0 || p.tick_margin_ns > 100'000'000)
    return "tick budget and margin must be in [0, 100 ms]";
  if (!(p.calibration_voxel >= 1e-3 && p.calibration_voxel <= 0.1) || p.calibration_layers < 1 || p.calibration_layers > 20)
    return "calibration voxel must be in [1, 100] mm, layers in [1, 20]";
  if (!(p.period_s > 0 && p.period_s <= 0.01)) return "period must be in (0, 10 ms]";
  if (p.render)
    for (const device::EndEffectorLimits& l : p.limits)
      if (!(l.peak_force > 0 && l.max_stiffness > 0)) return "each end-effector must report a peak force and a stiffness";
  return {};
}

TelemanipTask::TelemanipTask(const TelemanipTaskParams& p) : p_(p) {
  if (std::string e = validate(p); !e.empty()) throw std::invalid_argument("telemanip: " + e);
  if (!p.render) return;
  if (std::string e = make_gripper_tool_set(p.gripper, &tools_); !e.empty())
    throw std::invalid_argument("telemanip: " + e);
  for (int k = 0; k < kTeleArms; ++k) {
    const device::EndEffectorLimits& l = p.limits[static_cast<std::size_t>(k)];
    const double s = p.mapping[static_cast<std::size_t>(k)].translation_scale;
    // The hand feels s^2 the coupling's stiffness (F_D = s F_A, x_A = s x_D):
    // designed for what the device renders.
    vps::CouplingDeviceLimits d;
    d.dt = p.period_s;
    d.peak_force = l.peak_force / s;
    d.max_stiffness = l.max_stiffness / (s * s);
    if (l.max_linear_speed > 0) d.max_speed = std::min(d.max_speed, s * l.max_linear_speed);
    // Likewise k^2 in rotation (tau_D = k tau_A, turn_A = k turn_D).
    const double k_rot = p.mapping[static_cast<std::size_t>(k)].rotation_scale;
    d.renders_torque = l.renders_torque;
    d.peak_torque = l.peak_torque / k_rot;
    d.max_rot_stiffness = l.max_rotational_stiffness / (k_rot * k_rot);
    const vps::ProbeTool& mid = tools_.tools[tools_.tools.size() / 2];
    vps::ToolParams& tp = tool_params_[static_cast<std::size_t>(k)];
    tp.coupling = vps::design_coupling(mid.mass, mid.inertia_com, d).params;
    tp.contact.stiffness = p.contact_stiffness;
    tp.budget = p.budget;
    Hand& h = hands_[static_cast<std::size_t>(k)];
    h.states.resize(static_cast<std::size_t>(palm_shell()) + 1);  // and the palm's, last
    for (std::size_t i = 0; i < h.states.size(); ++i)
      vps::init_tool_state(shell_tool(static_cast<int>(i)), &h.states[i]);
    h.shell = tools_.nearest(p.mapping[static_cast<std::size_t>(k)].opening_open_m);
  }
  vps::TimeBudgetParams tb;
  tb.tick_ns = p.tick_budget_ns;
  tb.margin_ns = p.tick_margin_ns;
  tb.max_work = p.budget;
  if (tb.tick_ns > 0) {
    // Before the live voxmap: a bench-sized box of its resolution stands in
    // (the ticks then track the live one's cost).
    calibration_ = vps::calibrate_work_rate_on_box({0.35, 0.5, 0.05}, p.calibration_voxel, p.calibration_layers,
                                                   tools_.tools.back().shell, tool_params_[0].contact, tb.rate, 16,
                                                   &steady_now_ns);
  }
  for (auto& b : budget_) b = vps::TickWorkBudget(tb, calibration_.rate);
}

const vps::ProbeTool& TelemanipTask::shell_tool(int i) const noexcept {
  return i >= palm_shell() ? tools_.palm : tools_.tools[static_cast<std::size_t>(i)];
}

bool TelemanipTask::grasp_phase(int k, const RemoteArmsState* remote) noexcept {
  const std::size_t ki = static_cast<std::size_t>(k);
  Hand& h = hands_[ki];
  const ArmCommandOut& c = cmd_[ki];
  if (c.has_gripper) h.open_ref_m = std::max(h.open_ref_m, c.opening_m);
  const bool seen = remote != nullptr && remote->valid;
  const bool holding = seen && remote->gripper[ki].holding;
  const bool closing = seen && c.has_gripper &&
                       (c.opening_m < remote->gripper[ki].opening_m - kClosingTol_m ||
                        c.opening_m < h.open_ref_m - kLeverClosing_m);
  if (holding || closing) {
    if (!h.grasp) h.grasp_held = false;
    h.grasp = true;
    h.grasp_held = h.grasp_held || holding;
    h.grasp_p_A = c.T_A_G.translation();
  } else if (h.grasp && (!h.grasp_held || (c.T_A_G.translation() - h.grasp_p_A).norm() >= kGraspClear_m)) {
    // Closed on nothing and open again, or gone from what it let go of.
    h.grasp = false;
    h.open_ref_m = c.has_gripper ? c.opening_m : 0.0;
  }
  return h.grasp;
}

void TelemanipTask::render_hand(int k, const vps::Voxmap* vm, std::uint64_t build, double opening, bool grasping,
                                std::int64_t deadline_ns, device::EndEffectorCommand& c) noexcept {
  const std::size_t ki = static_cast<std::size_t>(k);
  Hand& h = hands_[ki];
  const ArmCommandOut& cmd = cmd_[ki];
  HandRenderStats& st = stats_[ki];
  // The shell of the gripper's opening (the palm's while it grasps
  // something); the coupled body carries over.
  const int want = grasping ? palm_shell() : tools_.nearest(opening);
  if (want != h.shell) {
    vps::ToolState& from = h.states[static_cast<std::size_t>(h.shell)];
    vps::ToolState& to = h.states[static_cast<std::size_t>(want)];
    to.body = from.body;
    to.started = from.started;
    to.goal_prev = from.goal_prev;
    to.voxmap = nullptr;  // its pair cache is of another shell
    h.shell = want;
  }
  const vps::ProbeTool& tool = shell_tool(h.shell);
  vps::ToolState& s = h.states[static_cast<std::size_t>(h.shell)];
  vps::ToolParams& tp = tool_params_[ki];
  // Released or clutched: the tool follows the command, nothing displayed;
  // so too in a grasp phase, unless the palm is rendered (step 3).
  const bool engaged = cmd.pressed && !cmd.clutched;
  const bool grasp_free = grasping && !p_.grasp_palm_contact;
  if (!engaged || grasp_free) vm = nullptr;
  if (vm != nullptr && build != h.voxmap_build) s.voxmap = nullptr;  // a new build, maybe at the old address
  if (vm != nullptr) h.voxmap_build = build;
  if (vm == nullptr) {
    vps::probe_tool_tick(tp, tool, nullptr, cmd.T_A_G, &s);
    if (engaged) ++(grasp_free ? st.grasp_ticks : st.no_model_ticks);
    st.last_force_D.setZero();
    st.last_torque_D.setZero();
    st.last_work = 0;
    return;
  }
  vps::TickWorkBudget& b = budget_[ki];
  tp.budget = b.begin(steady_now_ns(), deadline_ns);
  vps::probe_tool_tick(tp, tool, vm, cmd.T_A_G, &s);
  const std::int64_t work = s.contact.nodes_visited + s.contact.points_tested;
  const int levels = s.contact.levels_completed;
  b.end(steady_now_ns(), work, levels, levels >= tool.shell.levels);
  // The reaction at the goal's centre of mass, moved to G (= the E point), into D.
  const ArmMappingParams& mp = p_.mapping[ki];
  const Eigen::Matrix3d R_D_A = mp.R_A_D.transpose();
  const Eigen::Vector3d r = cmd.T_A_G.linear() * tool.shell.reference_point;
  const Eigen::Vector3d F = R_D_A * (mp.translation_scale * s.device.force);
  const Eigen::Vector3d T = R_D_A * (mp.rotation_scale * (s.device.torque + r.cross(s.device.force)));
  c.force_H = F.allFinite() ? F : Eigen::Vector3d::Zero();
  c.torque_H = T.allFinite() ? T : Eigen::Vector3d::Zero();
  st.last_force_D = c.force_H;
  st.last_torque_D = c.torque_H;
  st.last_work = work;
  const double f = c.force_H.norm();
  if (f > st.peak_force_n) st.peak_force_n = f;
  if (s.contact.contacts > 0) {
    ++st.contact_ticks;
    st.sum_force_n += f;
  }
}

void TelemanipTask::render_held(const RemoteArmsState& remote, device::DeviceCommand& command) noexcept {
  HeldObjectInputs in;
  in.remote_valid = remote.valid;
  for (std::size_t k = 0; k < kTeleArms; ++k) {
    in.pressed[k] = cmd_[k].pressed && !cmd_[k].clutched;
    in.holding[k] = remote.gripper[k].holding;
    in.T_A_G[k] = cmd_[k].T_A_G;
    in.remote_force_A[k] = remote.arm[k].force_A;
  }
  HeldObjectWrench& w = held_w_;
  held_object_step(p_.held, in, p_.period_s, &held_, &w);
  for (std::size_t k = 0; k < kTeleArms; ++k) {
    // At G (= the E point), into D as the contact's wrench is (F_D = s F_A, tau_D = k tau_A).
    const ArmMappingParams& mp = p_.mapping[k];
    const Eigen::Matrix3d R_D_A = mp.R_A_D.transpose();
    device::EndEffectorCommand& c = command.ee[k];
    c.force_H += R_D_A * (mp.translation_scale * w.force_A[k]);
    c.torque_H += R_D_A * (mp.rotation_scale * w.torque_A[k]);
  }
}

void TelemanipTask::publish_trace(const device::DeviceSample& in, const RemoteArmsState* remote,
                                  const device::DeviceCommand& command) noexcept {
  HandTraceSample& t = trace_.back();
  t.t_ns = in.t_ns;
  const bool seen = remote != nullptr && remote->valid;
  t.remote_ns = seen ? remote->stamp_ns : 0;
  t.direct = p_.mode == FeedbackMode::kDirect;
  t.squeeze_n = held_w_.squeeze_n;
  for (std::size_t k = 0; k < kTeleArms; ++k) {
    HandTraceArm& a = t.arm[k];
    const ArmCommandOut& c = cmd_[k];
    const ArmMappingParams& mp = p_.mapping[k];
    a.pressed = c.pressed;
    a.clutched = c.clutched;
    a.holding = seen && remote->gripper[k].holding;
    a.commanded_A = c.T_A_G.translation();
    a.remote_A = seen ? remote->arm[k].p_A : Eigen::Vector3d::Zero();
    a.felt_A = mp.R_A_D * command.ee[k].force_H / mp.translation_scale;
    a.held_A = held_w_.force_A[k];
    a.remote_force_A = seen ? remote->arm[k].force_A : Eigen::Vector3d::Zero();
    a.commanded_opening_m = c.opening_m;
    a.remote_opening_m = seen ? remote->gripper[k].opening_m : 0.0;
  }
  trace_.publish();
}

void TelemanipTask::tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
                         servo::TickOutput& out) noexcept {
  ++ticks_;
  const RemoteArmsState* fresh = remote_.take();  // new this tick (null: none)
  const RemoteArmsState* remote = fresh != nullptr ? fresh : remote_.latest();
  const vps::Voxmap* vm = override_vm_;
  std::uint64_t build = override_build_;
  if (vm == nullptr && p_.render && model.version != 0) {
    if (const auto* snap = dynamic_cast<const OperatorModelSnapshot*>(&model)) {
      vm = snap->voxmap.get();
      build = snap->voxmap_builds;
    }
  }
  TelemanipSetpoint& sp = setpoints_.back();
  sp.t_ns = in.t_ns;
  sp.tick = ticks_;
  std::int64_t work = 0;
  const bool direct = p_.mode == FeedbackMode::kDirect;
  // A robot that restarted (another frame epoch) counts its energies from
  // zero again: so do both ends (docs/telemanipulation_passivity.md).
  if (direct && remote != nullptr && remote->valid && (!direct_epoch_seen_ || remote->frame_epoch != direct_epoch_)) {
    if (direct_epoch_seen_) {
      for (DirectHandState& d : direct_) tdpa::reset<6>(d.side);
      ++direct_resets_;
    }
    direct_epoch_seen_ = true;
    direct_epoch_ = remote->frame_epoch;
  }
  for (int k = 0; k < kTeleArms; ++k) {
    const std::size_t ki = static_cast<std::size_t>(k);
    ArmMappingState& ms = map_[ki];
    if (!ms.initialized && remote != nullptr && remote->valid)
      reset_arm_mapping(&ms, teletask_pose(remote->arm[ki].p_A, remote->arm[ki].q_A));
    map_arm_step(p_.mapping[ki], teletask_hand(in, k, p_.mapping[ki]), &ms, &cmd_[ki]);
    const ArmCommandOut& c = cmd_[ki];
    if (c.pressed) ++stats_[ki].engaged_ticks;
    ArmSetpoint& a = sp.arm[ki];
    a.direct = direct && ms.initialized;
    if (a.direct) {
      DirectHandState& d = direct_[ki];
      direct_hand_tick(p_.direct[ki], in.ee[ki], c.pressed && !c.clutched, fresh != nullptr && fresh->valid ? &fresh->arm[ki].direct : nullptr,
                       remote != nullptr && remote->valid ? &remote->arm[ki].direct : nullptr, p_.period_s, &d,
                       &out.command.ee[ki]);
      a.twist_A = d.sent_A;
      a.side = d.side;
      if (remote != nullptr && remote->valid) {
        DirectHandStats& st = d.stats;
        const Eigen::Vector3d pc = c.T_A_G.translation(), pr = remote->arm[ki].p_A;
        if (!st.started) {
          st.started = true;
          st.commanded_start_A = pc;
          st.remote_start_A = pr;
        }
        st.max_commanded_travel_m = std::max(st.max_commanded_travel_m, (pc - st.commanded_start_A).norm());
        st.max_remote_travel_m = std::max(st.max_remote_travel_m, (pr - st.remote_start_A).norm());
      }
    }
    if (p_.render && ms.initialized) {
      // The shell at the opening the remote gripper has (measured), else the commanded one.
      const double opening = remote != nullptr && remote->valid ? remote->gripper[ki].opening_m
                             : c.has_gripper                    ? c.opening_m
                                                                : p_.mapping[ki].opening_open_m;
      render_hand(k, vm, build, opening, grasp_phase(k, remote), out.deadline_ns, out.command.ee[ki]);
      work += stats_[ki].last_work;
    }
    a.active = ms.initialized;
    a.pressed = c.pressed;
    a.p_A = c.T_A_G.translation();
    a.q_A = Eigen::Quaterniond(c.T_A_G.linear());
    a.has_gripper = c.has_gripper;
    a.opening_m = c.opening_m;
    a.force_n = c.force_n;
    MappingAnchor& an = anchors_[ki].back();
    an.engaged = ms.engaged;
    an.state = ms;
    anchors_[ki].publish();
  }
  held_w_ = HeldObjectWrench{};
  if (p_.render && remote != nullptr && remote->valid && map_[0].initialized && map_[1].initialized)
    render_held(*remote, out.command);
  if (trace_on_) publish_trace(in, remote, out.command);
  if (tick_tap_ != nullptr) {
    tap_record_.tick = out.setpoint.tick;
    tap_record_.in = in;
    tap_record_.model_version = vm != nullptr ? build : 0;
    tap_record_.command = out.command;
    tap_record_.view_presses = 0;
    tap_record_.mode = p_.mode == FeedbackMode::kDirect ? 1u : 0u;
    tap_record_.remote_seq = remote != nullptr ? remote->seq : 0;
    tick_tap_->push(tap_record_);
  }
  setpoints_.publish();
  if (roi_out_ != nullptr && map_[0].initialized && map_[1].initialized) {
    ProbePosition& pp = roi_out_->back();
    pp.p_W = 0.5 * (map_[0].T_A_G_cmd.translation() + map_[1].T_A_G_cmd.translation());
    pp.active = true;
    roi_out_->publish();
  }
  out.publish_setpoint = false;  // the loop's one-end-effector setpoint is not ours
  out.renderer = "telemanip";
  out.work = work;
}

}  // namespace hemm::op::telemanip
