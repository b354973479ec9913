#include "operator/telemanip/arm_mapping.h"

#include <algorithm>
#include <cmath>

namespace hemm::op::telemanip {

namespace {

bool mapping_in_range(double v, double lo, double hi) { return std::isfinite(v) && v > lo && v <= hi; }

// R^k about R's own axis (angle in [0, pi] from Eigen's AngleAxis): the
// scaled turn of the mapping and, with 1/k, its inverse.
Eigen::Matrix3d scaled_turn(const Eigen::Matrix3d& R, double k) {
  if (k == 1.0) return R;
  const Eigen::AngleAxisd aa(R);
  return Eigen::AngleAxisd(k * aa.angle(), aa.axis()).toRotationMatrix();
}

}  // namespace

std::string validate(const ArmMappingParams& p) {
  if (!p.R_A_D.allFinite() || !p.R_A_D.isUnitary(1e-9) || p.R_A_D.determinant() < 0.0)
    return "R_A_D must be a rotation (orthonormal, det +1)";
  if (std::string e = check_scales(p.translation_scale, p.rotation_scale); !e.empty()) return e;
  if (!mapping_in_range(p.max_step_m, 0.0, 0.1)) return "max_step_m must be in (0, 0.1] m";
  if (!mapping_in_range(p.max_step_rad, 0.0, 1.0)) return "max_step_rad must be in (0, 1] rad";
  if (p.deadman_ee < 0 || p.deadman_ee > 1) return "deadman_ee must be 0 or 1";
  if (p.clutch_button < 0 || p.clutch_button > 8) return "clutch_button must be 0 (none) or a button 1-8";
  if (!mapping_in_range(p.grip_travel_m, 0.0, 0.2)) return "grip travel must be in (0, 0.2] m";
  for (double v : {p.opening_open_m, p.opening_closed_m, p.force_open_n, p.force_closed_n})
    if (!std::isfinite(v) || v < 0.0) return "gripper openings and forces must be finite and >= 0";
  return {};
}

std::string check_scales(double translation_scale, double rotation_scale) {
  if (!mapping_in_range(translation_scale, 0.0, 10.0)) return "translation_scale: must be in (0, 10]";
  if (!(std::isfinite(rotation_scale) && rotation_scale >= 0.25 && rotation_scale <= 4.0))
    return "rotation_scale: must be in [0.25, 4]";
  return {};
}

void reset_arm_mapping(ArmMappingState* s, const Eigen::Isometry3d& T_A_G) noexcept {
  *s = ArmMappingState{};
  s->initialized = true;
  s->T_A_G_cmd = T_A_G;
}

Eigen::Isometry3d mapped_pose_A(const ArmMappingParams& p, const ArmMappingState& s,
                                const Eigen::Isometry3d& T_D_E) noexcept {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = s.T_A_anchor.translation() +
                    p.translation_scale * (p.R_A_D * (T_D_E.translation() - s.T_D_anchor.translation()));
  const Eigen::Matrix3d dR_D = T_D_E.linear() * s.T_D_anchor.linear().transpose();  // the hand's turn, in D
  T.linear() = scaled_turn(p.R_A_D * dR_D * p.R_A_D.transpose(), p.rotation_scale) * s.T_A_anchor.linear();
  return T;
}

Eigen::Isometry3d hand_pose_D(const ArmMappingParams& p, const ArmMappingState& s,
                              const Eigen::Isometry3d& T_A_G) noexcept {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = s.T_D_anchor.translation() +
                    p.R_A_D.transpose() * (T_A_G.translation() - s.T_A_anchor.translation()) / p.translation_scale;
  const Eigen::Matrix3d dR_A = T_A_G.linear() * s.T_A_anchor.linear().transpose();
  T.linear() = p.R_A_D.transpose() * scaled_turn(dR_A, 1.0 / p.rotation_scale) * p.R_A_D * s.T_D_anchor.linear();
  return T;
}

void grip_to_gripper(const ArmMappingParams& p, double grip_position_m, double* opening_m, double* force_n) noexcept {
  const double g = std::isfinite(grip_position_m) ? std::clamp(grip_position_m / p.grip_travel_m, 0.0, 1.0) : 0.0;
  *opening_m = p.opening_open_m + g * (p.opening_closed_m - p.opening_open_m);
  *force_n = p.force_open_n + g * (p.force_closed_n - p.force_open_n);
}

void map_arm_step(const ArmMappingParams& p, const HandReading& hand, ArmMappingState* s, ArmCommandOut* out) noexcept {
  out->clamped = false;
  out->has_gripper = false;
  if (!s->initialized) {
    out->T_A_G = Eigen::Isometry3d::Identity();
    out->pressed = false;
    out->clutched = false;
    return;
  }
  const bool deadman = hand.valid && hand.deadman;
  const bool clutched = deadman && p.clutch_button > 0 && hand.clutch;
  const bool press = deadman && !clutched;
  if (press && !s->engaged) {  // re-anchor: the arm continues from what it was told
    s->T_A_anchor = s->T_A_G_cmd;
    s->T_D_anchor = hand.T_D_E;
    ++s->presses;
  }
  s->engaged = press;
  if (clutched) ++s->clutch_steps;
  if (press) {
    const Eigen::Isometry3d want = mapped_pose_A(p, *s, hand.T_D_E);
    // Translation: at most max_step_m along the way to the mapped position.
    Eigen::Vector3d dp = want.translation() - s->T_A_G_cmd.translation();
    const double d = dp.norm();
    if (d > p.max_step_m) {
      dp *= p.max_step_m / d;
      out->clamped = true;
    }
    // Rotation: at most max_step_rad along the geodesic (slerp).
    const Eigen::Quaterniond q0(s->T_A_G_cmd.linear());
    const Eigen::Quaterniond q1(want.linear());
    const double a = q0.angularDistance(q1);
    Eigen::Quaterniond q = q1;
    if (a > p.max_step_rad) {
      q = q0.slerp(p.max_step_rad / a, q1);
      out->clamped = true;
    }
    s->T_A_G_cmd.translation() += dp;
    s->T_A_G_cmd.linear() = q.normalized().toRotationMatrix();
    if (out->clamped) ++s->clamped_steps;
  }
  out->T_A_G = s->T_A_G_cmd;
  out->pressed = deadman;
  out->clutched = clutched;
  if (hand.has_grip && hand.valid) {
    out->has_gripper = true;
    grip_to_gripper(p, hand.grip_position_m, &out->opening_m, &out->force_n);
  }
}

}  // namespace hemm::op::telemanip
