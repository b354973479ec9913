#pragma once
// Small 3D geometry helpers shared by the arms' keep-out checks (the robot's
// arm, the bimanual device's collision avoidance).
#include <algorithm>

#include <Eigen/Core>

namespace hemm::math {

struct ClosestPoints {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();  // on the first shape
  Eigen::Vector3d q = Eigen::Vector3d::Zero();  // on the second
  double distance = 0.0;                        // |p - q|
};

// Closest points of segments [p1, q1] and [p2, q2] (either may be a point).
inline ClosestPoints segment_segment(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1, const Eigen::Vector3d& p2,
                                     const Eigen::Vector3d& q2) {
  // Closest points of two segments: minimise |p1 + s d1 - p2 - t d2| over
  // s, t in [0, 1] (the unconstrained optimum, then clamped edge by edge).
  const Eigen::Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  constexpr double eps = 1e-18;
  double s = 0.0, t = 0.0;
  if (a <= eps && e <= eps) {
    s = t = 0.0;
  } else if (a <= eps) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= eps) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > eps * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  ClosestPoints out;
  out.p = p1 + s * d1;
  out.q = p2 + t * d2;
  out.distance = (out.p - out.q).norm();
  return out;
}

}  // namespace hemm::math
