#pragma once
// Small 2D geometry helpers shared by the map and the proxy.
#include <algorithm>

#include <Eigen/Core>

namespace hemm::math {

inline double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}
// Counter-clockwise perpendicular.
inline Eigen::Vector2d perp(const Eigen::Vector2d& v) { return {-v.y(), v.x()}; }

// Closest point to p on segment [a, b]; *t_out gets its parameter in [0, 1].
inline Eigen::Vector2d closest_point_on_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                                const Eigen::Vector2d& p, double* t_out = nullptr) {
  const Eigen::Vector2d d = b - a;
  const double len2 = d.squaredNorm();
  double t = len2 > 0.0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  if (t_out != nullptr) *t_out = t;
  return a + t * d;
}

inline double distance_to_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  return (p - closest_point_on_segment(a, b, p)).norm();
}

}  // namespace hemm::math
