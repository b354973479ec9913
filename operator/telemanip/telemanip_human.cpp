#include "operator/telemanip/telemanip_human.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "wire.pb.h"

namespace hemm::op::telemanip {

MappedHumanScript::MappedHumanScript(const device::bimanual::HumanTarget& rest, const ArmMappingParams& mapping,
                                     std::vector<GRouteKey> keys, NewestMailbox<MappingAnchor>* anchors, double lead_s,
                                     const std::atomic<std::uint32_t>* robot_safety)
    : rest_(rest),
      mapping_(mapping),
      keys_(std::move(keys)),
      anchors_(anchors),
      lead_s_(lead_s),
      robot_safety_(robot_safety) {
  if (std::string e = validate(mapping); !e.empty()) throw std::invalid_argument("human: mapping: " + e);
  if (anchors_ == nullptr) throw std::invalid_argument("human: no anchor mailbox");
  if (!(std::isfinite(lead_s) && lead_s >= 0.0)) throw std::invalid_argument("human: lead must be >= 0");
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const GRouteKey& k = keys_[i];
    if (!std::isfinite(k.t_s) || !k.dp_A.allFinite() || !std::isfinite(k.grip_m) || (i == 0 && k.t_s != 0.0) ||
        (i > 0 && !(k.t_s > keys_[i - 1].t_s)))
      throw std::invalid_argument("human: route keys must be finite, from t = 0, strictly increasing");
  }
}

bool DeadmanHabit::step(std::uint32_t safety, double t_s) noexcept {
  if (safety == kNoRobotState) {
    t_seen = -1.0;  // nothing from the robot (yet, or a new session): wait
    return pressed;
  }
  if (t_seen < 0.0) t_seen = t_s;
  if (!pressed) {
    pressed = t_s - t_seen >= kReaction_s && t_s - t_released >= kReaction_s;
    t_rearm = -1.0;
  } else if ((safety & wire::SAFETY_REARM) != 0) {
    if (t_rearm < 0.0) t_rearm = t_s;
    if (t_s - t_rearm >= kReaction_s) {  // the robot waits for a neutral command: let go, press again
      pressed = false;
      t_released = t_s;
    }
  } else {
    t_rearm = -1.0;
  }
  return pressed;
}

double MappedHumanScript::end_s() const noexcept { return keys_.empty() ? 0.0 : lead_s_ + keys_.back().t_s; }

device::bimanual::HumanTarget MappedHumanScript::at(double t_s) const noexcept {
  if (const MappingAnchor* a = anchors_->take()) anchor_ = *a;
  if (!engaged_ && anchor_.engaged) {
    engaged_ = true;
    t_engaged_ = t_s;
  }
  device::bimanual::HumanTarget g = rest_;
  if (robot_safety_ != nullptr) g.deadman = deadman_.step(robot_safety_->load(std::memory_order_relaxed), t_s);
  if (!engaged_ || keys_.empty() || !anchor_.engaged) return g;
  // The route at t (piecewise linear, held after its end).
  const double t = t_s - t_engaged_ - lead_s_;
  Eigen::Vector3d dp = keys_.front().dp_A;
  double grip = keys_.front().grip_m;
  if (t >= keys_.back().t_s) {
    dp = keys_.back().dp_A;
    grip = keys_.back().grip_m;
  } else if (t > 0.0) {
    std::size_t i = 1;
    while (keys_[i].t_s < t) ++i;
    const GRouteKey& a = keys_[i - 1];
    const GRouteKey& b = keys_[i];
    const double f = (t - a.t_s) / (b.t_s - a.t_s);
    dp = a.dp_A + f * (b.dp_A - a.dp_A);
    grip = a.grip_m + f * (b.grip_m - a.grip_m);
  }
  // Where the hand must be for the mapping to ask G there (from the anchor).
  Eigen::Isometry3d want_A = anchor_.state.T_A_anchor;
  want_A.translation() += dp;
  const Eigen::Isometry3d hand_D = hand_pose_D(mapping_, anchor_.state, want_A);
  g.position_D = hand_D.translation();
  g.orientation_D = Eigen::Quaterniond(hand_D.linear());
  g.finger_position = grip;
  return g;
}

std::vector<GRouteKey> demo_right_route(double grip_travel_m) {
  const Eigen::Vector3d fwd(0.10, 0.0, 0.0);
  return {{0.0, Eigen::Vector3d::Zero(), 0.0}, {2.0, fwd, 0.0},  {3.0, fwd, 0.0},
          {5.0, Eigen::Vector3d::Zero(), 0.0}, {6.0, Eigen::Vector3d::Zero(), grip_travel_m},
          {7.0, Eigen::Vector3d::Zero(), grip_travel_m}, {8.0, Eigen::Vector3d::Zero(), 0.0}};
}

}  // namespace hemm::op::telemanip
