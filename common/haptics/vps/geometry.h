// Small exact geometric kernels for voxelization and pointshell generation.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace hemm::vps {

// Triangle against axis-aligned box (centre c, half size h) by the separating
// axis theorem: the 13 axes e_i (box), n (triangle normal) and e_i x f_j
// (box axes crossed with triangle edges). Touching counts as overlapping.
inline bool triangle_box_overlap(const Eigen::Vector3d& c, double h, const Eigen::Vector3d& a0,
                                 const Eigen::Vector3d& b0, const Eigen::Vector3d& c0) {
  const Eigen::Vector3d v0 = a0 - c, v1 = b0 - c, v2 = c0 - c;
  // e_i: triangle bounding box against the box.
  for (int i = 0; i < 3; ++i) {
    const double mn = std::min({v0[i], v1[i], v2[i]}), mx = std::max({v0[i], v1[i], v2[i]});
    if (mn > h || mx < -h) return false;
  }
  const Eigen::Vector3d f[3] = {v1 - v0, v2 - v1, v0 - v2};
  // e_i x f_j.
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d ax = Eigen::Vector3d::Zero();
      // e_i x f = components rotated; computed explicitly to stay exact.
      const int u = (i + 1) % 3, w = (i + 2) % 3;
      ax[u] = -f[j][w];
      ax[w] = f[j][u];
      const double p0 = ax.dot(v0), p1 = ax.dot(v1), p2 = ax.dot(v2);
      const double r = h * (std::abs(ax[0]) + std::abs(ax[1]) + std::abs(ax[2]));
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  }
  // Triangle normal: plane against box.
  const Eigen::Vector3d n = f[0].cross(f[1]);
  const double d = n.dot(v0);
  const double r = h * (std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]));
  return std::abs(d) <= r;
}

// Closest point on triangle (a, b, c) to p, and which feature it lies on:
// 0 face interior, 1/2/3 vertex a/b/c, 4/5/6 edge ab/bc/ca.
struct ClosestPoint {
  Eigen::Vector3d point;
  int feature;
};

inline ClosestPoint closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                              const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi regions of the triangle's features, tested in turn.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {a, 1};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {b, 2};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * ab, 4};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {c, 3};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * ac, 6};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), 5};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {a + ab * v + ac * w, 0};
}

inline double point_triangle_distance_sq(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                         const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return (closest_point_on_triangle(p, a, b, c).point - p).squaredNorm();
}

}  // namespace hemm::vps
