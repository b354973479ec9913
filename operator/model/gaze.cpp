#include "operator/model/gaze.h"

#include <algorithm>
#include <cmath>

namespace hemm::op {

std::optional<std::string> check(const GazeParams& p) {
  if (!(p.lookahead_s >= 0.0 && p.lookahead_s <= 5.0)) return "gaze: lookahead_s not in [0, 5]";
  if (!(p.max_lookahead_m >= 0.0 && p.max_lookahead_m <= 5.0)) return "gaze: max_lookahead_m not in [0, 5]";
  if (!(p.velocity_tau_s > 0.0 && p.velocity_tau_s <= 10.0)) return "gaze: velocity_tau_s not in (0, 10]";
  if (!(p.unseen_radius_m > 0.0 && p.unseen_radius_m <= 5.0)) return "gaze: unseen_radius_m not in (0, 5]";
  if (!(p.unseen_gain >= 0.0 && p.unseen_gain <= 100.0)) return "gaze: unseen_gain not in [0, 100]";
  if (!(p.hysteresis_m >= 0.0 && p.hysteresis_m <= 2.0)) return "gaze: hysteresis_m not in [0, 2]";
  return std::nullopt;
}

GazeChoice choose_gaze(const GazeParams& p, GazeChooserState& s, const std::optional<Eigen::Vector3d>& tool_W,
                       std::int64_t t_ns, std::span<const GazeCandidate> unseen,
                       const std::optional<Eigen::AlignedBox3d>& roi_W) {
  GazeChoice c;
  if (!tool_W || !tool_W->allFinite()) {
    s.have_tool = false;
    s.have_gaze = false;
    s.velocity_W.setZero();
    return c;
  }
  const Eigen::Vector3d x = *tool_W;
  if (s.have_tool && t_ns > s.last_t_ns) {
    const double dt = static_cast<double>(t_ns - s.last_t_ns) * 1e-9;
    const Eigen::Vector3d v = (x - s.last_tool_W) / dt;
    const double a = 1.0 - std::exp(-dt / p.velocity_tau_s);
    s.velocity_W += a * (v - s.velocity_W);
  } else if (!s.have_tool) {
    s.velocity_W.setZero();
  }
  s.have_tool = true;
  s.last_tool_W = x;
  s.last_t_ns = t_ns;

  Eigen::Vector3d step = s.velocity_W * p.lookahead_s;
  if (step.norm() > p.max_lookahead_m) step *= p.max_lookahead_m / step.norm();
  c.predicted_W = x + step;

  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double w = 0.0;
  for (const GazeCandidate& u : unseen) {
    if (!(u.weight > 0.0) || !std::isfinite(u.weight) || !u.point_W.allFinite()) continue;
    if ((u.point_W - c.predicted_W).norm() > p.unseen_radius_m) continue;
    sum += u.weight * u.point_W;
    w += u.weight;
  }
  Eigen::Vector3d want = c.predicted_W;
  if (w > 0.0) {
    const double a = p.unseen_gain * w / (1.0 + p.unseen_gain * w);
    want += a * (sum / w - c.predicted_W);
  }
  if (roi_W && !roi_W->isEmpty()) want = want.cwiseMax(roi_W->min()).cwiseMin(roi_W->max());
  c.wanted_W = want;

  if (!s.have_gaze || (want - s.gaze_W).norm() > p.hysteresis_m) {
    if (s.have_gaze) ++s.moves;
    s.gaze_W = want;
    s.have_gaze = true;
  }
  c.active = true;
  c.point_W = s.gaze_W;
  return c;
}

}  // namespace hemm::op
