#include "robot_side/twoarm/twoarm_robot.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "common/haptics/passivity/tdpa_wire.h"

namespace hemm::twoarm {

TwoArmRobot::TwoArmRobot(const std::string& scene_path, const TwoArmRobotOptions& options)
    : o_(options), sim_(scene_path) {
  for (std::size_t a = 0; a < kArms; ++a) {
    if (auto e = validate(o_.control.arm[a], sim_.model().arms[a].arm))
      throw std::runtime_error("two-arm control params: " + *e);
  }
  if (!(o_.watchdog_ns > 0)) throw std::runtime_error("two-arm watchdog must be > 0");
  if (!(o_.direct_twist_hold_ns > 0)) throw std::runtime_error("twoarm.direct_twist_hold_ms must be > 0");
  watchdog_.timeout_ns = o_.watchdog_ns;
  reset({sim_.model().arms[0].rest_q, sim_.model().arms[1].rest_q}, {0.0, 0.0});
}

void TwoArmRobot::reset(const std::array<kinematics::Arm7Vector, kArms>& q, const std::array<double, kArms>& finger_m) {
  sim_.reset(q, finger_m);
  commanded_ = hold_targets(sim_.model(), readings(), {o_.initial_grip_force_N, o_.initial_grip_force_N});
  active_ = commanded_;
  following_ = false;
  deadman_ = false;
  gate_disarm(gate_);
  watchdog_ = robot::Watchdog{o_.watchdog_ns};
  direct_ = {};
  tracked_ = {};
  reset_passivity();
}

void TwoArmRobot::reset_passivity() noexcept {
  for (haptics::tdpa::ArmSide& p : port_) haptics::tdpa::reset<6>(p);
  energy_record_ = PeerEnergyRecord{};
}

int64_t TwoArmRobot::time_ns() const noexcept { return origin_ns_ + std::llround(sim_.time_s() * 1e9); }

void TwoArmRobot::set_time_origin_ns(int64_t now_ns) noexcept {
  origin_ns_ = now_ns - std::llround(sim_.time_s() * 1e9);
}

int64_t TwoArmRobot::timestep_ns() const noexcept { return std::llround(sim_.timestep_s() * 1e9); }

std::array<ArmReading, kArms> TwoArmRobot::readings() const noexcept {
  return {sim_.reading(Side::kRight), sim_.reading(Side::kLeft)};
}

bool TwoArmRobot::command(const wire::ArmsCommand& cmd, uint64_t seq, int64_t sent_ns) {
  ValidatedArmsCommand v;
  std::optional<ArmsRefusal> r = validate_arms_command(sim_.model(), o_.limits, cmd, readings(), &v);
  if (!r) r = check_energy_not_decreasing(v, energy_record_);
  if (r) {
    ++counters_.commands;
    ++counters_.refusals;
    counters_.last_refusal = r->reason;
    counters_.last_refused_seq = seq;
    counters_.last_refused_index = r->index;
    counters_.last_refusal_detail = std::move(r->detail);
    return false;
  }
  note_energy(v, &energy_record_);
  apply(v, seq, sent_ns);
  return true;
}

void TwoArmRobot::apply(const ValidatedArmsCommand& v, uint64_t seq, int64_t sent_ns) noexcept {
  ++counters_.commands;
  const int64_t now = time_ns();
  watchdog_feed(watchdog_, sent_ns, now);
  // Towards the re-arm, with the stops as they are now (the watchdog was
  // just fed: an expired one is not a stop in force for this command).
  gate_offer(gate_, !operator_in_control_ || !link_up_ || estop_, !v.deadman, v.deadman);
  deadman_ = v.deadman;
  // The operator's energy is a budget, taken whether or not the arms follow
  // (old ones are ignored, bad ones counted: receive_peer).
  for (std::size_t i = 0; i < kArms; ++i) {
    if (v.has_energy[i]) haptics::tdpa::receive_peer<6>(port_[i], seq, v.peer_energy_in_J[i]);
  }
  if (gate_.armed && deadman_) {
    commanded_ = merge_arms_command(commanded_, v);
    bool any_twist = false;
    for (std::size_t i = 0; i < kArms; ++i) {
      if (v.has_twist[i]) {
        direct_[i] = true;
        twist_[i] = v.twist[i];
        twist_sent_ns_[i] = std::min(sent_ns, now);
        any_twist = true;
      } else if (v.has_arm[i]) {
        direct_[i] = false;
      }
    }
    if (any_twist) ++counters_.direct_commands;
    counters_.last_command_seq = seq;
    ++counters_.applied;
  }
}

void TwoArmRobot::stop_commanded_motion() noexcept { deadman_ = false; }

void TwoArmRobot::set_link(bool operator_in_control, bool link_up) noexcept {
  operator_in_control_ = operator_in_control;
  link_up_ = link_up;
}

void TwoArmRobot::set_estop(bool engaged) noexcept { estop_ = engaged; }

void TwoArmRobot::step() noexcept {
  const int64_t now = time_ns();
  const bool expired = watchdog_expired(watchdog_, now);
  uint32_t flags = 0;
  if (!operator_in_control_) flags |= wire::SAFETY_NO_OPERATOR;
  if (expired && operator_in_control_) flags |= wire::SAFETY_WATCHDOG;
  if (estop_) flags |= wire::SAFETY_ESTOP;
  if (!link_up_) flags |= wire::SAFETY_LINK_LOST;
  if (!operator_in_control_ || !link_up_ || expired || estop_) gate_disarm(gate_);
  if (!gate_.armed) flags |= wire::SAFETY_REARM;
  safety_ = flags;
  const std::array<ArmReading, kArms> in = readings();
  const bool follow = gate_.armed && deadman_;
  if (follow) {
    const double dt_s = sim_.timestep_s();
    for (std::size_t a = 0; a < kArms; ++a) {
      if (!direct_[a]) continue;
      // Resuming after a hold: the twist moves the arm from the hold, not
      // from a target the stop left behind.
      if (!following_) commanded_.T_A_G[a] = active_.T_A_G[a];
      haptics::tdpa::ArmTwist received;  // zero: a stale twist stops the arm
      if (now - twist_sent_ns_[a] <= o_.direct_twist_hold_ns) {
        received = twist_[a];
      } else {
        ++counters_.direct_stale_ticks;
      }
      const kinematics::Wrench6& f = feedback_A_[a];
      tracked_[a] = haptics::tdpa::robot_arm_tick(port_[a], received, haptics::tdpa::ArmWrench{f.head<3>(), f.tail<3>()},
                                                  dt_s, o_.pc_mode);
      commanded_.T_A_G[a] = haptics::tdpa::advance_target(commanded_.T_A_G[a], tracked_[a], dt_s);
    }
    active_ = commanded_;
  } else if (following_) {
    // The stop begins: hold where the grasp frames are, under the load they
    // carry (the set point offset by the wrist sensor's external wrench over
    // the stiffness, within the force limits, so a held box does not make
    // the arm sag), and keep the grips.
    const TwoArmTargets here = hold_targets(sim_.model(), in, {0.0, 0.0});
    for (std::size_t a = 0; a < kArms; ++a) {
      const ImpedanceParams& p = o_.control.arm[a];
      Eigen::Vector3d f = -out_.wrench_ext_A[a].head<3>(), t = -out_.wrench_ext_A[a].tail<3>();
      if (f.norm() > p.force_limit_N) f *= p.force_limit_N / f.norm();
      if (t.norm() > p.torque_limit_Nm) t *= p.torque_limit_Nm / t.norm();
      Eigen::Isometry3d T = here.T_A_G[a];
      if (p.stiffness_N_per_m > 0.0) T.translation() += f / p.stiffness_N_per_m;
      if (p.rot_stiffness_Nm_per_rad > 0.0 && t.norm() > 0.0) {
        const Eigen::Vector3d r = t / p.rot_stiffness_Nm_per_rad;
        T.linear() = Eigen::AngleAxisd(r.norm(), r.normalized()).toRotationMatrix() * T.linear();
      }
      active_.T_A_G[a] = T;
    }
  }
  if (!follow) tracked_ = {};
  following_ = follow;
  const auto t0 = std::chrono::steady_clock::now();
  twoarm_control(sim_.model(), o_.control, in, active_, out_);
  const auto t1 = std::chrono::steady_clock::now();
  compute_.record(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
  for (std::size_t a = 0; a < kArms; ++a) {
    const ImpedanceOutput& io = out_.arm[a];
    if (o_.direct_feedback_measured) {
      feedback_A_[a] = out_.wrench_ext_A[a];
    } else {
      // The environment's wrench on the gripper that the (capped) spring
      // balances: minus what the spring pushes with.
      const ImpedanceParams& p = o_.control.arm[a];
      feedback_A_[a].head<3>() = -p.stiffness_N_per_m * (io.T_A_G_yielded.translation() - io.T_A_G.translation());
      feedback_A_[a].tail<3>() =
          -p.rot_stiffness_Nm_per_rad * rotation_vector(io.T_A_G_yielded.linear() * io.T_A_G.linear().transpose());
    }
    // Past the wrist limit the target moves back to the yielded set point,
    // so a twist into a wall does not wind the target up behind it.
    if (follow && direct_[a] && io.force_limited) commanded_.T_A_G[a] = io.T_A_G_yielded;
  }
  sim_.set_command(Side::kRight, out_.command[0]);
  sim_.set_command(Side::kLeft, out_.command[1]);
  sim_.step();
}

void TwoArmRobot::snapshot(TwoArmSnapshot* out) const noexcept {
  out->stamp_ns = time_ns();
  out->readings = readings();
  out->targets = active_;
  out->control = out_;
  out->safety = safety_;
  out->armed = gate_.armed;
  out->following = following_;
  out->last_command_seq = counters_.last_command_seq;
  out->commands = counters_.commands;
  out->applied = counters_.applied;
  out->refusals = counters_.refusals;
  out->last_refusal = counters_.last_refusal;
  out->last_refused_seq = counters_.last_refused_seq;
  out->last_refused_index = counters_.last_refused_index;
  out->port = port_;
  out->feedback_A = feedback_A_;
  out->direct = direct_;
  out->pc_mode = o_.pc_mode;
  out->feedback_measured = o_.direct_feedback_measured;
  out->direct_commands = counters_.direct_commands;
  out->direct_stale_ticks = counters_.direct_stale_ticks;
}

void to_wire(const TwoArmModel& model, const TwoArmSnapshot& s, wire::ArmsState* out) {
  out->Clear();
  to_wire(model, s.readings, s.targets, s.control, s.stamp_ns, out);
  out->set_safety(s.safety);
  out->set_last_command_seq(s.last_command_seq);
  out->set_refusals(s.refusals);
  out->set_last_refusal(s.last_refusal);
  out->set_last_refused_seq(s.last_refused_seq);
  out->set_last_refused_index(s.last_refused_index);
  // The direct mode's ports and fed-back wrenches, for the arms in it only
  // (an ArmsState must fit one datagram: about 1100 of 1156 bytes with both arms
  // direct); only E_in and pc_on go out, the operator needs no more (the
  // station's report has E_out, the dissipation and the controller's ticks).
  for (uint32_t i = 0; i < kArms; ++i) {
    if (!s.direct[i]) continue;
    wire::PassivityPort* p = out->add_passivity();
    haptics::tdpa::fill(p, i, s.port[i], s.pc_mode);
    p->clear_energy_out_j();
    p->clear_dissipated_j();
    p->clear_pc_active_ticks();
    wire::DirectWrench* w = out->add_direct_wrench();
    w->set_index(i);
    for (int j = 0; j < 6; ++j) w->add_wrench_a(static_cast<float>(s.feedback_A[i](j)));
    w->set_measured(s.feedback_measured);
  }
}

void TwoArmRobot::state(wire::ArmsState* out) const {
  TwoArmSnapshot s;
  snapshot(&s);
  to_wire(sim_.model(), s, out);
}

}  // namespace hemm::twoarm
