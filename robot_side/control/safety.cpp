#include "robot_side/control/safety.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hemm::robot {

double stoppable_speed(double d, double a, double t_r) {
  if (!(d > 0) || !(a > 0)) return 0.0;
  if (std::isinf(d)) return std::numeric_limits<double>::infinity();
  t_r = std::max(0.0, t_r);
  // v t_r + v^2 / (2a) = d  =>  v = -a t_r + sqrt(a^2 t_r^2 + 2 a d)
  return -a * t_r + std::sqrt(a * a * t_r * t_r + 2 * a * d);
}

GuardLimit collision_guard(const CollisionGuardParams& p, std::span<const Eigen::Vector2d> points) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  GuardLimit g;
  g.free_ahead = kInf;
  g.free_behind = kInf;
  for (const Eigen::Vector2d& pt : points) {
    if (!pt.allFinite() || std::abs(pt.y()) > p.half_width) continue;
    if (pt.x() >= p.front_x) g.free_ahead = std::min(g.free_ahead, pt.x() - p.front_x);
    if (pt.x() <= p.rear_x) g.free_behind = std::min(g.free_behind, p.rear_x - pt.x());
  }
  g.max_forward = stoppable_speed(g.free_ahead - p.margin, p.max_decel, p.reaction_time);
  g.max_backward = stoppable_speed(g.free_behind - p.margin, p.max_decel, p.reaction_time);
  return g;
}

}  // namespace hemm::robot
