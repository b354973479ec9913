#include "robot_side/control/head_control.h"

#include <algorithm>
#include <cmath>

namespace hemm::robot {

std::optional<std::string> check(const HeadParams& p) {
  if (!p.head_R.allFinite()) return "head: position not finite";
  if (!(p.pan_min < p.pan_max && p.tilt_min < p.tilt_max && std::isfinite(p.pan_min) && std::isfinite(p.pan_max) &&
        std::isfinite(p.tilt_min) && std::isfinite(p.tilt_max)))
    return "head: joint limits need min < max";
  if (!(p.home_pan >= p.pan_min && p.home_pan <= p.pan_max && p.home_tilt >= p.tilt_min && p.home_tilt <= p.tilt_max))
    return "head: home outside the joint limits";
  if (!(p.max_rate > 0.0 && std::isfinite(p.max_rate))) return "head: max_rate must be positive";
  if (!(p.min_range >= 0.0 && p.min_range < p.max_range && std::isfinite(p.max_range)))
    return "head: need 0 <= min_range < max_range";
  if (p.gaze_timeout_ns <= 0) return "head: gaze timeout must be positive";
  return std::nullopt;
}

Eigen::Isometry3d head_T_R_S(const Eigen::Vector3d& head_R, double pan, double tilt) {
  const Eigen::Vector3d fwd(std::cos(tilt), 0.0, -std::sin(tilt));
  Eigen::Matrix3d M;
  M.col(0) = Eigen::Vector3d(0, -1, 0);          // x_S: right
  M.col(2) = fwd;                                 // z_S: optical axis
  M.col(1) = fwd.cross(Eigen::Vector3d(0, -1, 0));  // y_S = z_S x x_S: down
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(pan, Eigen::Vector3d::UnitZ()).toRotationMatrix() * M;
  T.translation() = head_R;
  return T;
}

HeadAim aim_head(const HeadParams& p, const Eigen::Vector3d& point_R) {
  HeadAim a;
  if (!point_R.allFinite()) {
    a.refusal = GazeRefusal::kNotFinite;
    return a;
  }
  const Eigen::Vector3d d = point_R - p.head_R;
  const double r = d.norm();
  if (r < p.min_range || r < 1e-9) {
    a.refusal = GazeRefusal::kTooNear;
    return a;
  }
  a.pan = std::atan2(d.y(), d.x());
  a.tilt = std::atan2(-d.z(), std::hypot(d.x(), d.y()));
  if (r > p.max_range) {
    a.refusal = GazeRefusal::kTooFar;
  } else if (a.pan < p.pan_min || a.pan > p.pan_max) {
    a.refusal = GazeRefusal::kPanLimit;
  } else if (a.tilt < p.tilt_min || a.tilt > p.tilt_max) {
    a.refusal = GazeRefusal::kTiltLimit;
  }
  return a;
}

HeadControlState head_control_init(const HeadParams& p) {
  HeadControlState s;
  s.pan_sp = p.home_pan;
  s.tilt_sp = p.home_tilt;
  s.gaze_watchdog.timeout_ns = p.gaze_timeout_ns;
  return s;
}

GazeRefusal head_gaze_command(const HeadParams& p, HeadControlState& s, const Eigen::Vector3d& point_W, bool active,
                              const Eigen::Isometry3d& T_W_R, std::uint64_t seq, std::int64_t now_ns) {
  if (!active) {
    s.following = false;
    s.holding = false;
    return GazeRefusal::kNone;
  }
  const HeadAim a = aim_head(p, T_W_R.inverse() * point_W);
  if (a.refusal != GazeRefusal::kNone) {
    ++s.refusals;
    s.last_refusal = a.refusal;
    s.last_refused_seq = seq;
    s.holding = true;
    return a.refusal;
  }
  s.following = true;
  s.holding = false;
  s.target_W = point_W;
  watchdog_feed(s.gaze_watchdog, now_ns);
  return GazeRefusal::kNone;
}

void head_control_step(const HeadParams& p, HeadControlState& s, const Eigen::Isometry3d& T_W_R, bool may_follow,
                       bool estop, std::int64_t now_ns, double dt) {
  const bool expired = watchdog_expired(s.gaze_watchdog, now_ns);
  if (!may_follow || expired) {
    s.following = false;
    s.holding = false;  // a refusal holds only while the operator's gaze is in force
  }
  if (estop) return;  // the e-stop holds the setpoints
  double pan_goal = p.home_pan, tilt_goal = p.home_tilt;
  if (s.holding) {
    pan_goal = s.pan_sp;
    tilt_goal = s.tilt_sp;
  } else if (s.following) {
    const HeadAim a = aim_head(p, T_W_R.inverse() * s.target_W);
    if (a.refusal == GazeRefusal::kNotFinite || a.refusal == GazeRefusal::kTooNear) {
      pan_goal = s.pan_sp;  // the base came onto the target: hold
      tilt_goal = s.tilt_sp;
    } else {
      pan_goal = std::clamp(a.pan, p.pan_min, p.pan_max);
      tilt_goal = std::clamp(a.tilt, p.tilt_min, p.tilt_max);
    }
  }
  const double step = p.max_rate * std::max(0.0, dt);
  s.pan_sp += std::clamp(pan_goal - s.pan_sp, -step, step);
  s.tilt_sp += std::clamp(tilt_goal - s.tilt_sp, -step, step);
}

}  // namespace hemm::robot
