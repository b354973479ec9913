#include "robot_side/control/arm_keep_out.h"

#include <algorithm>
#include <cmath>

#include "common/math/geometry2.h"
#include "common/math/geometry3.h"

namespace hemm::robot {

const char* to_string(ArmRefusal r) {
  switch (r) {
    case ArmRefusal::kNone: return "allowed";
    case ArmRefusal::kFloor: return "arm target would reach into the floor";
    case ArmRefusal::kBase: return "arm target would reach into the robot's base";
    case ArmRefusal::kScene: return "arm target would reach into something the robot's sensors have seen";
  }
  return "?";
}

const char* short_name(ArmRefusal r) {
  switch (r) {
    case ArmRefusal::kNone: return "none";
    case ArmRefusal::kFloor: return "floor";
    case ArmRefusal::kBase: return "base";
    case ArmRefusal::kScene: return "scene";
  }
  return "?";
}

namespace {
// Whether segment [a, b] meets the box (slab clipping).
bool segment_meets_box(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::AlignedBox3d& box) {
  double t0 = 0.0, t1 = 1.0;
  const Eigen::Vector3d d = b - a;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (a[k] < box.min()[k] || a[k] > box.max()[k]) return false;
      continue;
    }
    double u0 = (box.min()[k] - a[k]) / d[k], u1 = (box.max()[k] - a[k]) / d[k];
    if (u0 > u1) std::swap(u0, u1);
    t0 = std::max(t0, u0);
    t1 = std::min(t1, u1);
    if (t0 > t1) return false;
  }
  return true;
}

Eigen::AlignedBox3d grown(const Eigen::AlignedBox3d& b, double r) {
  return {b.min() - Eigen::Vector3d::Constant(r), b.max() + Eigen::Vector3d::Constant(r)};
}

// Squared distance of p to segment [a, a + d] (len2 = |d|^2), float for the
// seen points' hot loop.
float point_segment_distance2(const Eigen::Vector3f& a, const Eigen::Vector3f& d, float len2, const Eigen::Vector3f& p) {
  const float t = len2 > 0.0f ? std::clamp((p - a).dot(d) / len2, 0.0f, 1.0f) : 0.0f;
  return (p - (a + t * d)).squaredNorm();
}
}  // namespace

ArmRefusal check_arm_chain(const ArmKeepOut& k, std::span<const Eigen::Vector3d> chain, const SeenScene& seen) {
  const double r = k.link_radius + k.clearance;
  for (const Eigen::Vector3d& p : chain)
    if (!p.allFinite() || p.z() < k.floor_z + r) return ArmRefusal::kFloor;  // links are straight: ends suffice
  const Eigen::AlignedBox3d body = grown(k.body, r), head = grown(k.laser_head, r);
  for (std::size_t i = 0; i + 1 < chain.size(); ++i)
    if (segment_meets_box(chain[i], chain[i + 1], body) || segment_meets_box(chain[i], chain[i + 1], head))
      return ArmRefusal::kBase;
  const bool caps = seen.column_capped.size() == seen.columns_R.size();
  for (std::size_t j = 0; j < seen.columns_R.size(); ++j) {
    const Eigen::Vector2d& q = seen.columns_R[j];
    if (caps && seen.column_capped[j]) {
      const Eigen::Vector3d c0(q.x(), q.y(), k.floor_z), c1(q.x(), q.y(), seen.column_top_z);
      for (std::size_t i = 0; i + 1 < chain.size(); ++i)
        if (math::segment_segment(chain[i], chain[i + 1], c0, c1).distance < r) return ArmRefusal::kScene;
    } else {
      for (std::size_t i = 0; i + 1 < chain.size(); ++i)
        if (math::distance_to_segment(chain[i].head<2>(), chain[i + 1].head<2>(), q) < r) return ArmRefusal::kScene;
    }
  }
  if (!seen.points_P.empty() && chain.size() >= 2) {
    // The chain in P; points outside its bounding box grown by the reach
    // are skipped with six comparisons.
    const float reach = static_cast<float>(r + k.seen_pad), reach2 = reach * reach;
    Eigen::AlignedBox3f box;
    std::array<Eigen::Vector3f, 8> c{};
    const std::size_t n = std::min(chain.size(), c.size());
    for (std::size_t i = 0; i < n; ++i) {
      c[i] = (seen.T_P_R * chain[i]).cast<float>();
      box.extend(c[i]);
    }
    box.min().array() -= reach;
    box.max().array() += reach;
    for (const Eigen::Vector3f& p : seen.points_P) {
      if (!box.contains(p)) continue;
      for (std::size_t i = 0; i + 1 < n; ++i) {
        const Eigen::Vector3f d = c[i + 1] - c[i];
        if (point_segment_distance2(c[i], d, d.squaredNorm(), p) < reach2) return ArmRefusal::kScene;
      }
    }
  }
  return ArmRefusal::kNone;
}

bool in_camera_view(const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_S_R, const Eigen::Vector3d& p_R) {
  const Eigen::Vector3d p = T_S_R * p_R;
  if (!(p.z() > 0.0)) return false;
  const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
  const double range = p.norm();
  return u >= 0.0 && u <= K.width && v >= 0.0 && v <= K.height && range >= K.range_min && range <= K.range_max;
}

bool column_seen_from_above(const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_S_R,
                            const Eigen::Vector2d& q, double z0, double z1) {
  return in_camera_view(K, T_S_R, Eigen::Vector3d(q.x(), q.y(), z0)) &&
         in_camera_view(K, T_S_R, Eigen::Vector3d(q.x(), q.y(), z1));
}

}  // namespace hemm::robot
