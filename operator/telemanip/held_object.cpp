#include "operator/telemanip/held_object.h"

#include <algorithm>
#include <cmath>

namespace hemm::op::telemanip {

namespace {

bool held_finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

// v scaled down to at most `limit` long.
Eigen::Vector3d held_clamp(const Eigen::Vector3d& v, double limit) {
  const double n = v.norm();
  return n > limit ? Eigen::Vector3d(v * (limit / n)) : v;
}

}  // namespace

std::string validate(const HeldObjectParams& p) {
  for (double v : {p.stiffness_n_per_m, p.damping_ns_per_m, p.rot_stiffness_nm_per_rad, p.max_force_n, p.max_torque_nm,
                   p.max_weight_n})
    if (!(std::isfinite(v) && v >= 0.0)) return "held object: stiffness, damping and limits must be finite and >= 0";
  if (!(std::isfinite(p.weight_filter_s) && p.weight_filter_s > 0.0 && p.weight_filter_s <= 10.0))
    return "held object: the weight filter must be in (0, 10] s";
  if (!(std::isfinite(p.coupling_fade_s) && p.coupling_fade_s > 0.0 && p.coupling_fade_s <= 10.0))
    return "held object: the coupling's fade must be in (0, 10] s";
  if (!(std::isfinite(p.weight_rate_n_per_s) && p.weight_rate_n_per_s > 0.0))
    return "held object: the weight rate must be finite and > 0";
  return {};
}

void held_object_step(const HeldObjectParams& p, const HeldObjectInputs& in, double dt, HeldObjectState* s,
                      HeldObjectWrench* out) noexcept {
  *out = HeldObjectWrench{};
  if (!(std::isfinite(dt) && dt > 0.0)) return;
  for (int k = 0; k < 2; ++k)
    if (!held_finite(in.T_A_G[static_cast<std::size_t>(k)]) || !in.remote_force_A[static_cast<std::size_t>(k)].allFinite())
      return;

  // The weight, per hand: the measured load follows through a low-pass, the
  // felt weight follows that at a bounded rate (no steps from a late state).
  const double alpha = 1.0 - std::exp(-dt / p.weight_filter_s);
  const double step = p.weight_rate_n_per_s * dt;
  for (std::size_t k = 0; k < 2; ++k) {
    const bool holds = in.remote_valid && in.holding[k] && in.pressed[k] && p.weight;
    const double load = holds ? std::clamp(-in.remote_force_A[k].z(), 0.0, p.max_weight_n) : 0.0;
    s->load_filtered_n[k] += alpha * (load - s->load_filtered_n[k]);
    const double target = holds ? s->load_filtered_n[k] : 0.0;
    s->weight_n[k] += std::clamp(target - s->weight_n[k], -step, step);
    out->force_A[k].z() -= s->weight_n[k];
  }

  // The coupling.
  const bool engaged = p.coupling && in.remote_valid && in.pressed[0] && in.pressed[1];
  const bool both = engaged && in.holding[0] && in.holding[1];
  const Eigen::Matrix3d& R0 = in.T_A_G[0].linear();
  const Eigen::Matrix3d& R1 = in.T_A_G[1].linear();
  const Eigen::Vector3d p01 = in.T_A_G[1].translation() - in.T_A_G[0].translation();
  if (!engaged) {
    s->both_held = false;
    s->fade = 0.0;
    s->e_prev_valid = false;
    return;
  }
  if (both && !s->both_held) {
    s->both_held = true;
    s->r_G0 = R0.transpose() * p01;
    s->R_G0_G1 = R0.transpose() * R1;
    s->e_prev_valid = false;
    ++s->holds;
  }
  if (!s->both_held) return;
  s->fade = both ? 1.0 : s->fade - dt / p.coupling_fade_s;
  if (s->fade <= 0.0) {
    s->both_held = false;
    s->fade = 0.0;
    s->e_prev_valid = false;
    return;
  }
  ++s->held_ticks;
  const Eigen::Vector3d e = p01 - R0 * s->r_G0;
  const Eigen::Vector3d de = s->e_prev_valid ? Eigen::Vector3d((e - s->e_prev) / dt) : Eigen::Vector3d::Zero();
  s->e_prev = e;
  s->e_prev_valid = true;
  const Eigen::Vector3d F1 =
      s->fade * held_clamp(-(p.stiffness_n_per_m * e + p.damping_ns_per_m * de), p.max_force_n);
  const Eigen::AngleAxisd turn(R1 * (R0 * s->R_G0_G1).transpose());
  const Eigen::Vector3d tau1 =
      s->fade * held_clamp(-p.rot_stiffness_nm_per_rad * turn.angle() * turn.axis(), p.max_torque_nm);
  out->force_A[1] += F1;
  out->force_A[0] -= F1;
  out->torque_A[1] += tau1;
  out->torque_A[0] -= tau1;
  const double d = p01.norm();
  out->squeeze_n = d > 1e-9 ? F1.dot(p01 / d) : 0.0;
  s->peak_squeeze_n = std::max(s->peak_squeeze_n, std::abs(out->squeeze_n));
}

}  // namespace hemm::op::telemanip
