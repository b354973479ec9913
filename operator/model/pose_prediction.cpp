#include "operator/model/pose_prediction.h"

#include <algorithm>
#include <cmath>

namespace hemm::op {

math::Pose2 integrate_unicycle(const math::Pose2& T, double v, double omega, double dt) {
  if (dt <= 0.0) return T;
  const double dth = omega * dt;
  math::Pose2 out;
  if (std::abs(dth) < 1e-9) {
    // Second-order straight-line limit of the arc.
    const double mid = T.theta + 0.5 * dth;
    out.x = T.x + v * dt * std::cos(mid);
    out.y = T.y + v * dt * std::sin(mid);
  } else {
    const double r = v / omega;
    out.x = T.x + r * (std::sin(T.theta + dth) - std::sin(T.theta));
    out.y = T.y - r * (std::cos(T.theta + dth) - std::cos(T.theta));
  }
  out.theta = math::wrap_angle(T.theta + dth);
  return out;
}

CommandHistory::CommandHistory(std::size_t capacity) : buf_(std::max<std::size_t>(capacity, 2)) {}

bool CommandHistory::push(const SentCommand& c) {
  if (!std::isfinite(c.v) || !std::isfinite(c.omega)) return false;
  if (size_ > 0 && c.t_ns < (*this)[size_ - 1].t_ns) return false;
  if (size_ < buf_.size()) {
    buf_[(head_ + size_) % buf_.size()] = c;
    ++size_;
  } else {
    buf_[head_] = c;
    head_ = (head_ + 1) % buf_.size();
  }
  return true;
}

math::Pose2 predict_pose(const PredictionInput& in, const CommandHistory& h, std::int64_t delay_ns,
                         std::int64_t now_ns, double max_horizon_s) {
  math::Pose2 pose = in.T_W_R;
  if (!math::is_finite(pose)) return pose;
  const std::int64_t horizon_ns = static_cast<std::int64_t>(std::max(0.0, max_horizon_s) * 1e9);
  const std::int64_t end = std::min(now_ns, in.stamp_local_ns + horizon_ns);
  if (end <= in.stamp_local_ns) return pose;
  double v = std::isfinite(in.v) ? in.v : 0.0;
  double omega = std::isfinite(in.omega) ? in.omega : 0.0;
  std::int64_t t = in.stamp_local_ns;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const SentCommand& c = h[i];
    const std::int64_t eff = c.t_ns + delay_ns;  // when it acts on the robot
    if (eff <= t) {
      v = c.v;  // already acting at the stamp
      omega = c.omega;
      continue;
    }
    if (eff >= end) break;
    pose = integrate_unicycle(pose, v, omega, static_cast<double>(eff - t) * 1e-9);
    t = eff;
    v = c.v;
    omega = c.omega;
  }
  return integrate_unicycle(pose, v, omega, static_cast<double>(end - t) * 1e-9);
}

}  // namespace hemm::op
