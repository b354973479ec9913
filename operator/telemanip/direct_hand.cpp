#include "operator/telemanip/direct_hand.h"

#include <algorithm>
#include <cmath>

#include "operator/telemanip/arm_mapping.h"

namespace hemm::op::telemanip {

namespace {

// v scaled down to at most `limit` in magnitude (non-finite: zero).
Eigen::Vector3d directhand_clamp(const Eigen::Vector3d& v, double limit) noexcept {
  if (!v.allFinite()) return Eigen::Vector3d::Zero();
  const double n = v.norm();
  return limit > 0.0 && n > limit ? Eigen::Vector3d(v * (limit / n)) : v;
}

}  // namespace

const char* to_string(FeedbackMode m) noexcept { return m == FeedbackMode::kDirect ? "direct" : "model"; }

std::string validate(const DirectHandParams& p) {
  if (!p.R_A_D.allFinite() || !(std::abs(p.R_A_D.determinant() - 1.0) < 1e-6)) return "R_A_D must be a rotation";
  if (std::string e = check_scales(p.translation_scale, p.rotation_scale); !e.empty()) return e;
  if (!(p.max_speed_mps > 0.0 && p.max_rate_radps > 0.0)) return "speed and rate limits must be > 0";
  if (!(p.fade_s > 0.0 && p.fade_s <= 2.0)) return "fade must be in (0, 2] s";
  if (!(p.peak_force_n >= 0.0 && p.peak_torque_nm >= 0.0 && std::isfinite(p.peak_force_n) &&
        std::isfinite(p.peak_torque_nm)))
    return "peak force and torque must be finite and >= 0";
  if (!(p.contact_force_n > 0.0 && std::isfinite(p.contact_force_n))) return "contact force must be finite and > 0";
  return {};
}

void direct_hand_tick(const DirectHandParams& p, const device::EndEffectorSample& e, bool pressed,
                      const DirectPeer* fresh, const DirectPeer* latest, double dt_s, DirectHandState* s,
                      device::EndEffectorCommand* cmd) noexcept {
  DirectHandStats& st = s->stats;
  ++st.ticks;
  if (pressed) ++st.pressed_ticks;
  // The robot's budget: its cumulative E_in, newest by sequence (old and bad ones only count).
  if (fresh != nullptr && fresh->has_port &&
      tdpa::receive_peer<6>(s->side, fresh->seq, fresh->energy_in_J) == tdpa::Receive::kAccepted)
    ++st.peer_accepted;
  // The hand's twist in A: x_A = s R_A_D x_D, turns k times as fast as in D.
  s->hand_A.v = directhand_clamp(p.translation_scale * (p.R_A_D * e.velocity_H), p.max_speed_mps);
  s->hand_A.omega = directhand_clamp(p.rotation_scale * (p.R_A_D * e.angular_velocity_H), p.max_rate_radps);
  if (pressed) {
    s->sent_A = s->hand_A;
  } else {
    s->sent_A = tdpa::ArmTwist{};
  }
  const double step = dt_s / p.fade_s;
  s->gain = pressed ? std::min(1.0, s->gain + step) : std::max(0.0, s->gain - step);
  // The remote wrench as the hand should feel it, in A. The hand's force is
  // s F_A (its work equals the arm's: F_D . v_D = F_A . v_A), so the device's
  // peak force bounds F_A at peak / s: the observer books what is displayed.
  tdpa::ArmWrench received;
  if (latest != nullptr && latest->has_wrench && latest->wrench_A.allFinite()) {
    const double fmax = p.peak_force_n > 0.0 ? p.peak_force_n / p.translation_scale : 0.0;
    received.force = s->gain * directhand_clamp(latest->wrench_A.head<3>(), fmax);
    if (p.renders_torque)
      received.torque =
          s->gain * directhand_clamp(latest->wrench_A.tail<3>(), p.peak_torque_nm / p.rotation_scale);
  }
  s->shown_A = tdpa::operator_arm_tick(s->side, received, s->hand_A, dt_s, p.pc_mode);
  const Eigen::Matrix3d R_D_A = p.R_A_D.transpose();
  const Eigen::Vector3d F = R_D_A * (p.translation_scale * s->shown_A.force);
  const Eigen::Vector3d T = R_D_A * (p.rotation_scale * s->shown_A.torque);
  cmd->force_H = F.allFinite() ? F : Eigen::Vector3d::Zero();
  cmd->torque_H = T.allFinite() ? T : Eigen::Vector3d::Zero();
  const double shown = s->shown_A.force.norm();
  st.peak_shown_n = std::max(st.peak_shown_n, shown);
  // Rendered against remote: the shown force against the wrist force of the
  // state it was computed from (the same stamp), over the remote's contact ticks.
  if (latest != nullptr) {
    const double wrist = latest->wrist_force_A.norm();
    if (wrist > p.contact_force_n) {
      ++st.contact_ticks;
      const double err = (s->shown_A.force - latest->wrist_force_A).norm();
      st.error_sum_sq += err * err;
      st.error_max_n = std::max(st.error_max_n, err);
      st.shown_sum_n += shown;
      st.wrist_sum_n += wrist;
    }
  }
}

}  // namespace hemm::op::telemanip
