#include "operator/telemanip/telemanip_link.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <stdexcept>

#include "common/haptics/passivity/tdpa_wire.h"
#include "common/mapping/depth_stream.h"
#include "common/net/stream_link.h"
#include "robot_side/twoarm/arms_wire.h"

namespace hemm::op::telemanip {

namespace {

Eigen::Vector3d telelink_vec(const proto::Vec3& v) { return {v.x(), v.y(), v.z()}; }
void telelink_vec_out(const Eigen::Vector3d& v, proto::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

// Both arms and both grippers, each index once (the robot's side says 0
// right, 1 left; a state naming others is not the two-arm robot's).
std::optional<std::string> telelink_check_indices(const wire::ArmsState& s) {
  if (s.arm_size() != kTeleArms || s.gripper_size() != kTeleArms)
    return "arms state: expected 2 arms and 2 grippers, got " + std::to_string(s.arm_size()) + " and " +
           std::to_string(s.gripper_size());
  std::array<bool, kTeleArms> arm{}, grip{};
  for (const wire::ArmState& a : s.arm()) {
    if (a.index() >= kTeleArms || arm[a.index()]) return "arms state: arm index " + std::to_string(a.index());
    arm[a.index()] = true;
  }
  for (const wire::GripperState& g : s.gripper()) {
    if (g.index() >= kTeleArms || grip[g.index()]) return "arms state: gripper index " + std::to_string(g.index());
    grip[g.index()] = true;
  }
  return std::nullopt;
}

}  // namespace

const char* short_name(wire::ArmsRefusalReason r) {
  switch (r) {
    case wire::ARMS_REFUSAL_UNSPECIFIED: return "none";
    case wire::ARMS_REFUSAL_NONFINITE: return "nonfinite";
    case wire::ARMS_REFUSAL_UNKNOWN_ARM: return "unknown_arm";
    case wire::ARMS_REFUSAL_UNKNOWN_GRIPPER: return "unknown_gripper";
    case wire::ARMS_REFUSAL_BAD_POSE: return "bad_pose";
    case wire::ARMS_REFUSAL_OUT_OF_REACH: return "out_of_reach";
    case wire::ARMS_REFUSAL_GRIPPER_RANGE: return "gripper_range";
    case wire::ARMS_REFUSAL_PASSIVITY: return "passivity";
    default: break;
  }
  return "?";
}

std::optional<ArmsRefusalEvent> observe_arms_refusals(ArmsRefusalMonitor& m, const wire::ArmsState& s,
                                                      std::string* error) {
  const int reason = static_cast<int>(s.last_refusal());
  const bool known = wire::ArmsRefusalReason_IsValid(reason);
  const bool none = reason == wire::ARMS_REFUSAL_UNSPECIFIED;
  if (!known || none != (s.refusals() == 0)) {
    ++m.summary.errors;
    if (error != nullptr)
      *error = !known ? "unknown arms refusal reason" : none ? "refusal count without a reason" : "refusal reason without a count";
    return std::nullopt;
  }
  if (s.frame_epoch() != m.frame_epoch) {  // a restarted robot counts from 0
    m.frame_epoch = s.frame_epoch();
    m.count = 0;
  }
  if (s.refusals() <= m.count) return std::nullopt;  // seen, or an older state
  ArmsRefusalEvent e;
  e.reason = static_cast<wire::ArmsRefusalReason>(reason);
  e.seq = s.last_refused_seq();
  e.index = s.last_refused_index();
  e.new_refusals = s.refusals() - m.count;
  e.total = s.refusals();
  m.count = s.refusals();
  ArmsRefusalSummary& sum = m.summary;
  sum.refused += e.new_refusals;
  ++sum.events;
  ++sum.by_reason[static_cast<std::size_t>(reason)];
  sum.last_reason = e.reason;
  sum.last_seq = e.seq;
  sum.last_index = e.index;
  return e;
}

void setpoint_to_command(const TelemanipSetpoint& sp, bool deadman, std::int64_t stamp_ns, wire::ArmsCommand* out,
                         tdpa::PcMode pc_mode) {
  out->Clear();
  out->set_stamp_ns(stamp_ns);
  out->set_mode(wire::MODE_MANIPULATION);
  out->set_deadman(deadman);
  for (std::uint32_t i = 0; i < kTeleArms; ++i) {
    const ArmSetpoint& a = sp.arm[i];
    if (!a.active) continue;
    if (a.direct) {
      // Released (or a stale setpoint): zero, the robot holds where it is.
      const tdpa::ArmTwist tw = deadman ? a.twist_A : tdpa::ArmTwist{};
      wire::DirectTwist* t = out->add_twist();
      t->set_index(i);
      telelink_vec_out(tw.v, t->mutable_v_a());
      telelink_vec_out(tw.omega, t->mutable_omega_a());
      tdpa::fill(out->add_passivity(), i, a.side, pc_mode);
    }
    if (a.has_gripper) {
      wire::GripperTarget* g = out->add_gripper();
      g->set_index(i);
      g->set_opening_m(a.opening_m);
      g->set_force_n(a.force_n);
    }
    if (a.direct) continue;
    wire::ArmTarget* t = out->add_arm();
    t->set_index(i);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = a.q_A.normalized().toRotationMatrix();
    T.translation() = a.p_A;
    mapping::pose3_to_wire(T, t->mutable_t_a_g());
  }
}

void direct_from_wire(const wire::ArmsState& s, std::uint64_t seq, RemoteArmsState* out, std::uint64_t* bad_ports,
                      std::uint64_t* bad_wrenches, std::string* error) {
  for (RemoteArm& a : out->arm) a.direct = DirectPeer{};
  for (const wire::PassivityPort& p : s.passivity()) {
    tdpa::Vec6 e;
    std::string why;
    if (p.index() >= kTeleArms || out->arm[p.index()].direct.has_port) {
      why = "passivity port of arm " + std::to_string(p.index()) + " unknown or named twice";
    } else if (tdpa::read_energy_in(p, &e, &why)) {
      DirectPeer& d = out->arm[p.index()].direct;
      d.has_port = true;
      d.seq = seq;
      d.energy_in_J = e;
      continue;
    }
    ++*bad_ports;
    if (error != nullptr) *error = why;
  }
  for (const wire::DirectWrench& w : s.direct_wrench()) {
    bool ok = w.index() < kTeleArms && !out->arm[w.index()].direct.has_wrench && w.wrench_a_size() == 6;
    tdpa::Vec6 v = tdpa::Vec6::Zero();
    for (int j = 0; ok && j < 6; ++j) {
      v[j] = w.wrench_a(j);
      ok = std::isfinite(v[j]);
    }
    if (!ok) {
      ++*bad_wrenches;
      if (error != nullptr) *error = "direct wrench of arm " + std::to_string(w.index()) + ": not 6 finite values, unknown or twice";
      continue;
    }
    out->arm[w.index()].direct.has_wrench = true;
    out->arm[w.index()].direct.wrench_A = v;
  }
  for (RemoteArm& a : out->arm) a.direct.wrist_force_A = a.force_A;
}

void state_from_wire(const wire::ArmsState& s, std::uint64_t seq, std::int64_t recv_ns, RemoteArmsState* out) {
  out->valid = true;
  out->stamp_ns = s.stamp_ns();
  out->recv_ns = recv_ns;
  out->seq = seq;
  out->frame_epoch = s.frame_epoch();
  out->safety = s.safety();
  out->last_command_seq = s.last_command_seq();
  for (const wire::ArmState& a : s.arm()) {
    RemoteArm& r = out->arm[a.index()];
    const proto::Pose3& T = a.t_a_g();
    r.p_A = telelink_vec(T.position());
    r.q_A = Eigen::Quaterniond(T.orientation().w(), T.orientation().x(), T.orientation().y(), T.orientation().z());
    r.v_A = telelink_vec(a.v_a());
    r.force_A = telelink_vec(a.force_a());
    r.torque_A = telelink_vec(a.torque_a());
    r.force_limited = a.force_limited();
  }
  for (const wire::GripperState& g : s.gripper()) {
    RemoteGripper& r = out->gripper[g.index()];
    r.opening_m = g.opening_m();
    r.grip_force_n = g.grip_force_n();
    r.holding = g.holding();
  }
}

TelemanipLink::TelemanipLink(asio::io_context& io, NewestMailbox<TelemanipSetpoint>& setpoints,
                             NewestMailbox<RemoteArmsState>& remote, SendStream send, Clock clock,
                             const TelemanipLinkParams& p, LinkUp link_up)
    : timer_(io),
      setpoints_(setpoints),
      remote_(remote),
      send_(std::move(send)),
      clock_(std::move(clock)),
      p_(p),
      link_up_(std::move(link_up)) {
  if (!(p.rate_hz >= 100.0 && p.rate_hz <= 1000.0))
    throw std::invalid_argument("TelemanipLink: rate_hz must be in [100, 1000]");
  if (p.stale_after_ns <= 0) throw std::invalid_argument("TelemanipLink: stale_after_ns must be > 0");
  if (!send_ || !clock_) throw std::invalid_argument("TelemanipLink: send and clock are required");
}

void TelemanipLink::attach(net::StreamLink& streams, ReceivedTap tap, Accepted accepted) {
  streams.on(wire::StreamMessage::kArmsState, [this, tap = std::move(tap), accepted = std::move(accepted)](
                                                   const net::DatagramHeader& h, std::int64_t recv_ns,
                                                   const wire::StreamMessage& m) {
    if (tap) tap(h.seq, recv_ns, m);
    const std::uint64_t before = stats_.states_in;
    on_arms_state(h.seq, recv_ns, m.arms_state());
    if (accepted && stats_.states_in != before) accepted(m.arms_state());
  });
}

void TelemanipLink::start() {
  running_ = true;
  next_ = std::chrono::steady_clock::now();
  arm_timer();
}

void TelemanipLink::stop() {
  running_ = false;
  timer_.cancel();
}

void TelemanipLink::arm_timer() {
  if (!running_) return;
  next_ += std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / p_.rate_hz));
  const auto now = std::chrono::steady_clock::now();
  if (next_ < now) next_ = now;  // behind: no burst to catch up
  timer_.expires_at(next_);
  timer_.async_wait([this](const asio::error_code& ec) {
    if (ec || !running_) return;
    send_once();
    arm_timer();
  });
}

void TelemanipLink::send_once() {
  if (const TelemanipSetpoint* sp = setpoints_.take()) {
    latest_ = *sp;
    have_ = true;
  }
  if (link_up_ && !link_up_()) {
    if (!was_down_) ++stats_.link_down;
    was_down_ = true;
    newest_seq_ = 0;  // the next session numbers its datagrams from 1
    return;
  }
  was_down_ = false;
  if (!have_) {
    ++stats_.no_setpoint;
    return;
  }
  const std::int64_t now = clock_();
  bool pressed = false;
  for (const ArmSetpoint& a : latest_.arm) pressed = pressed || (a.active && a.pressed);
  const bool stale = now - latest_.t_ns > p_.stale_after_ns;
  if (pressed && stale) ++stats_.stale;
  const bool deadman = pressed && !stale;
  setpoint_to_command(latest_, deadman, now, msg_.mutable_arms_command(), p_.pc_mode);
  if (send_(msg_)) {
    ++stats_.commands_sent;
    if (msg_.arms_command().twist_size() > 0) ++stats_.direct_commands;
    if (deadman) ++stats_.deadman_pressed;
  } else {
    ++stats_.send_failures;
  }
}

void TelemanipLink::on_arms_state(std::uint64_t seq, std::int64_t recv_ns, const wire::ArmsState& s) {
  std::optional<std::string> bad = twoarm::check_arms_state(s);
  if (!bad) bad = telelink_check_indices(s);
  if (bad) {
    ++stats_.states_rejected;
    if (stats_.states_rejected == 1 || stats_.states_rejected % 1000 == 0)
      spdlog::warn("event=arms_state_rejected count={} reason=\"{}\"", stats_.states_rejected, *bad);
    return;
  }
  // Sequence numbers count from 1 per session: a new session or a restarted
  // robot (another frame epoch) starts the order again.
  if (s.frame_epoch() != state_epoch_) {
    state_epoch_ = s.frame_epoch();
    newest_seq_ = 0;
  }
  if (seq != 0 && seq <= newest_seq_) {  // newest wins: an older datagram overtook nothing
    ++stats_.states_reordered;
    return;
  }
  newest_seq_ = seq;
  ++stats_.states_in;
  std::string err;
  if (auto e = observe_arms_refusals(refusals_, s, &err)) {
    spdlog::warn("event=arms_command_refused reason={} seq={} index={} new={} total={}", short_name(e->reason), e->seq,
                 e->index, e->new_refusals, e->total);
  } else if (!err.empty() && (refusals_.summary.errors == 1 || refusals_.summary.errors % 1000 == 0)) {
    spdlog::warn("event=arms_refusal_fields_bad count={} reason=\"{}\"", refusals_.summary.errors, err);
  }
  stats_.refusals = refusals_.summary;
  state_from_wire(s, seq, recv_ns, &remote_.back());
  const std::uint64_t bad_before = stats_.ports_rejected + stats_.wrenches_rejected;
  err.clear();
  direct_from_wire(s, seq, &remote_.back(), &stats_.ports_rejected, &stats_.wrenches_rejected, &err);
  if (const std::uint64_t dropped = stats_.ports_rejected + stats_.wrenches_rejected; dropped > bad_before &&
      (bad_before == 0 || dropped / 1000 != bad_before / 1000))
    spdlog::warn("event=arms_state_passivity_dropped ports={} wrenches={} reason=\"{}\"", stats_.ports_rejected,
                 stats_.wrenches_rejected, err);
  remote_.publish();
  if (safety_out_ != nullptr) safety_out_->store(s.safety(), std::memory_order_relaxed);
}

}  // namespace hemm::op::telemanip
