#include "operator/device/bimanual/collision.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hemm::device::bimanual {

namespace hk = hemm::kinematics;

ArmCapsules arm_capsules(const RigGeometry& rig, ArmSide side, const HandleSpec& handle, const hk::Arm7Frames& f) {
  const Eigen::Isometry3d& T_D_A = rig.T_D_A[static_cast<std::size_t>(index(side))];
  ArmCapsules c;
  for (int i = 1; i <= 6; ++i) {
    Capsule& k = c[static_cast<std::size_t>(i - 1)];
    k.a = T_D_A * f.origin(i);
    k.b = T_D_A * f.origin(i + 1);
    k.radius = rig.link_radius(i - 1);
    k.link = i;
  }
  const Eigen::Isometry3d T_D_J7 = T_D_A * f.joint(7);
  c[6].a = T_D_J7 * Eigen::Vector3d(0.0, 0.0, -0.03);
  c[6].b = T_D_J7 * Eigen::Vector3d(0.0, 0.0, -0.01);
  c[6].radius = rig.link_radius(6);
  c[6].link = 7;
  c[7].a = T_D_J7 * Eigen::Vector3d(0.0, 0.0, handle.capsule_radius);
  c[7].b = T_D_J7 * Eigen::Vector3d(0.0, 0.0, handle.capsule_length);
  c[7].radius = handle.capsule_radius;
  c[7].link = 7;
  return c;
}

ClosestPoints segment_box(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Box& box) {
  // The distance from a point moving along the segment to a convex box is
  // convex in the segment parameter: golden-section search.
  const auto at = [&](double t) { return Eigen::Vector3d(a0 + t * (a1 - a0)); };
  const auto dist = [&](double t) {
    const Eigen::Vector3d p = at(t);
    return (p - p.cwiseMax(box.min_D).cwiseMin(box.max_D)).squaredNorm();
  };
  constexpr double g = 0.6180339887498949;
  double lo = 0.0, hi = 1.0;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = dist(x1), f2 = dist(x2);
  for (int it = 0; it < 48; ++it) {
    if (f1 <= f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = dist(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = dist(x2);
    }
  }
  // The ends may beat the bracketed interior (the minimum at t = 0 or 1).
  double best = 0.5 * (lo + hi);
  for (double t : {0.0, 1.0}) {
    if (dist(t) < dist(best)) best = t;
  }
  ClosestPoints out;
  out.p = at(best);
  out.q = out.p.cwiseMax(box.min_D).cwiseMin(box.max_D);
  out.distance = (out.p - out.q).norm();
  return out;
}

namespace {

Eigen::Vector3d point_velocity_D(const RigGeometry& rig, int arm, const hk::Arm7Frames& f, int link,
                                 const Eigen::Vector3d& p_D, const hk::Arm7Vector& qd) {
  const Eigen::Isometry3d& T_D_A = rig.T_D_A[static_cast<std::size_t>(arm)];
  const hk::Arm7Jacobian J = hk::partial_jacobian(rig.arm, f, link, T_D_A.inverse() * p_D);
  return T_D_A.linear() * (J.topRows<3>() * qd);
}

void add_force(const RigGeometry& rig, int arm, const hk::Arm7Frames& f, int link, const Eigen::Vector3d& p_D,
               const Eigen::Vector3d& F_D, hk::Arm7Vector& tau) {
  const Eigen::Isometry3d& T_D_A = rig.T_D_A[static_cast<std::size_t>(arm)];
  const hk::Arm7Jacobian J = hk::partial_jacobian(rig.arm, f, link, T_D_A.inverse() * p_D);
  tau += J.topRows<3>().transpose() * (T_D_A.linear().transpose() * F_D);
}

}  // namespace

void collision_avoidance(const RigGeometry& rig, const CollisionParams& P, const std::array<ArmCapsules, kArms>& caps,
                         const std::array<hk::Arm7Frames, kArms>& frames, const std::array<hk::Arm7Vector, kArms>& qd,
                         CollisionResult& out) {
  out.count = 0;
  out.min_arm_arm_m = std::numeric_limits<double>::infinity();
  out.min_arm_table_m = std::numeric_limits<double>::infinity();
  for (auto& t : out.tau) t.setZero();
  const auto spring = [&](double gap, double gap_rate) {
    return std::clamp(P.stiffness * (P.activation_m - gap) - P.damping * gap_rate, 0.0, P.max_force);
  };
  // Arm against arm: every capsule pair.
  for (int i = 0; i < kArmCapsules; ++i) {
    const Capsule& c0 = caps[0][static_cast<std::size_t>(i)];
    for (int j = 0; j < kArmCapsules; ++j) {
      const Capsule& c1 = caps[1][static_cast<std::size_t>(j)];
      const ClosestPoints cp = segment_segment(c0.a, c0.b, c1.a, c1.b);
      const double gap = cp.distance - c0.radius - c1.radius;
      out.min_arm_arm_m = std::min(out.min_arm_arm_m, gap);
      if (gap >= P.activation_m) continue;
      // Direction from arm 1 to arm 0 (axes crossing: between the centres).
      Eigen::Vector3d n = cp.p - cp.q;
      if (n.norm() < 1e-9) n = 0.5 * (c0.a + c0.b - c1.a - c1.b);
      if (n.norm() < 1e-9) n = Eigen::Vector3d::UnitY();
      n.normalize();
      const Eigen::Vector3d v0 = point_velocity_D(rig, 0, frames[0], c0.link, cp.p, qd[0]);
      const Eigen::Vector3d v1 = point_velocity_D(rig, 1, frames[1], c1.link, cp.q, qd[1]);
      const double F = spring(gap, (v0 - v1).dot(n));
      Repulsion& r = out.pairs[static_cast<std::size_t>(out.count++)];
      r = Repulsion{0, i, 1, j, cp.p, cp.q, F * n, gap};
      add_force(rig, 0, frames[0], c0.link, cp.p, F * n, out.tau[0]);
      add_force(rig, 1, frames[1], c1.link, cp.q, -F * n, out.tau[1]);
    }
  }
  // Each arm against the table and the column.
  for (int a = 0; a < kArms; ++a) {
    for (int i = 0; i < kArmCapsules; ++i) {
      const Capsule& c = caps[static_cast<std::size_t>(a)][static_cast<std::size_t>(i)];
      for (int b = 0; b < 2; ++b) {
        if (b == 1 && (!P.column || c.link <= 2)) continue;  // links 1-2 sit at the column by design
        const Box& box = b == 0 ? rig.table : rig.column;
        const ClosestPoints cp = segment_box(c.a, c.b, box);
        const double gap = cp.distance - c.radius;
        out.min_arm_table_m = std::min(out.min_arm_table_m, gap);
        if (gap >= P.activation_m || out.count >= kMaxRepulsions) continue;
        Eigen::Vector3d n = cp.p - cp.q;
        if (n.norm() < 1e-9) n = b == 0 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d(-1.0, 0.0, 0.0);
        n.normalize();
        const Eigen::Vector3d v = point_velocity_D(rig, a, frames[static_cast<std::size_t>(a)], c.link, cp.p,
                                                   qd[static_cast<std::size_t>(a)]);
        const double F = spring(gap, v.dot(n));
        Repulsion& r = out.pairs[static_cast<std::size_t>(out.count++)];
        r = Repulsion{a, i, -1, -1, cp.p, cp.q, F * n, gap};
        add_force(rig, a, frames[static_cast<std::size_t>(a)], c.link, cp.p, F * n, out.tau[static_cast<std::size_t>(a)]);
      }
    }
  }
}

}  // namespace hemm::device::bimanual
