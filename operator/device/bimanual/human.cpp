#include "operator/device/bimanual/human.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hemm::device::bimanual {

Eigen::Isometry3d pose_D(const HumanTarget& g) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = g.orientation_D.normalized().toRotationMatrix();
  T.translation() = g.position_D;
  return T;
}

std::optional<std::string> validate(const HumanModel& h) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!pos(h.hand_mass) || !h.hand_inertia.allFinite() || !(h.hand_inertia.array() > 0.0).all())
    return "hand mass and inertia must be finite and > 0";
  for (double v : {h.arm_stiffness, h.arm_damping, h.arm_rot_stiffness, h.arm_rot_damping, h.grasp_damping,
                   h.grasp_rot_damping, h.finger_stiffness, h.finger_damping, h.voluntary_gain}) {
    if (!nonneg(v)) return "human stiffness and damping must be finite and >= 0";
  }
  if (!pos(h.grasp_stiffness) || !pos(h.grasp_rot_stiffness)) return "grasp stiffness must be > 0";
  if (!(nonneg(h.max_voluntary_force) && h.max_voluntary_force <= 100.0))
    return "max_voluntary_force must be in [0, 100] N";
  return std::nullopt;
}

HumanModel co_contracting_human(double max_voluntary_force) {
  HumanModel h;
  h.arm_stiffness = 1000.0;
  h.arm_damping = 40.0;
  h.arm_rot_stiffness = 10.0;
  h.arm_rot_damping = 0.4;
  h.max_voluntary_force = max_voluntary_force;
  h.voluntary_gain = 4000.0;
  return h;
}

namespace {
bool finite(const HumanTarget& t) {
  return t.position_D.allFinite() && t.orientation_D.coeffs().allFinite() && t.orientation_D.norm() > 0.5 &&
         t.push_force_D.allFinite() && t.push_torque_D.allFinite() && std::isfinite(t.finger_position) &&
         t.joystick.allFinite();
}
}  // namespace

HumanKeyScript::HumanKeyScript(std::vector<HumanKey> keys) : keys_(std::move(keys)) {
  if (keys_.empty()) throw std::invalid_argument("HumanKeyScript: no keys");
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    if (!std::isfinite(keys_[i].t_s) || !finite(keys_[i].target))
      throw std::invalid_argument("HumanKeyScript: key " + std::to_string(i) + " is not finite");
    if (i > 0 && !(keys_[i].t_s > keys_[i - 1].t_s))
      throw std::invalid_argument("HumanKeyScript: key times must increase strictly");
    keys_[i].target.orientation_D.normalize();
  }
}

HumanTarget HumanKeyScript::at(double t) const noexcept {
  if (!(t > keys_.front().t_s)) return keys_.front().target;
  if (t >= keys_.back().t_s) return keys_.back().target;
  const auto it = std::upper_bound(keys_.begin(), keys_.end(), t, [](double v, const HumanKey& k) { return v < k.t_s; });
  const HumanKey& b = *it;
  const HumanKey& a = *(it - 1);
  const double s = (t - a.t_s) / (b.t_s - a.t_s);
  HumanTarget out = a.target;
  out.position_D = a.target.position_D + s * (b.target.position_D - a.target.position_D);
  out.orientation_D = a.target.orientation_D.slerp(s, b.target.orientation_D);
  out.push_force_D = a.target.push_force_D + s * (b.target.push_force_D - a.target.push_force_D);
  out.push_torque_D = a.target.push_torque_D + s * (b.target.push_torque_D - a.target.push_torque_D);
  out.finger_position = a.target.finger_position + s * (b.target.finger_position - a.target.finger_position);
  out.joystick = a.target.joystick + s * (b.target.joystick - a.target.joystick);
  return out;
}

}  // namespace hemm::device::bimanual
