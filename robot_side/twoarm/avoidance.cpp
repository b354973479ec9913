#include "robot_side/twoarm/avoidance.h"

#include <algorithm>
#include <limits>

#include "common/math/geometry3.h"

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

ArmCapsules arm_capsules_A(const ArmMount& m, const hk::Arm7Frames& f) {
  ArmCapsules c;
  for (int link = 3; link <= 7; ++link) {
    ArmCapsule& k = c[static_cast<std::size_t>(link - 3)];
    k.link = link;
    k.radius = m.link_radius(link - 1);
    if (link < 7) {
      k.a = m.T_A_Ar * f.origin(link);
      k.b = m.T_A_Ar * f.origin(link + 1);
    } else {
      // As the scene's geom: 3 cm to 1 cm behind the flange.
      k.a = m.T_A_Ar * (f.joint(7) * Eigen::Vector3d(0.0, 0.0, -0.03));
      k.b = m.T_A_Ar * (f.joint(7) * Eigen::Vector3d(0.0, 0.0, -0.01));
    }
  }
  ArmCapsule& palm = c[kPalm];
  palm.link = 7;
  palm.radius = m.palm_radius_m;
  palm.a = m.T_A_Ar * (f.joint(7) * m.palm_a_J7);
  palm.b = m.T_A_Ar * (f.joint(7) * m.palm_b_J7);
  return c;
}

namespace {

// Adds the joint torques of force f_A at point p_A on `link` of one arm.
void push(const ArmMount& m, const hk::Arm7Frames& f, int link, const Eigen::Vector3d& p_A, const Eigen::Vector3d& f_A,
          hk::Arm7Vector& tau) {
  const Eigen::Vector3d p_Ar = m.T_A_Ar.inverse() * p_A;
  const hk::Arm7Jacobian J = hk::partial_jacobian(m.arm, f, link, p_Ar);
  tau += J.topRows<3>().transpose() * (m.T_A_Ar.linear().transpose() * f_A);
}

Eigen::Vector3d point_velocity_A(const ArmMount& m, const hk::Arm7Frames& f, int link, const Eigen::Vector3d& p_A,
                                 const hk::Arm7Vector& qd) {
  const Eigen::Vector3d p_Ar = m.T_A_Ar.inverse() * p_A;
  return m.T_A_Ar.linear() * (hk::partial_jacobian(m.arm, f, link, p_Ar).topRows<3>() * qd);
}

double repulsion(const AvoidanceParams& p, double gap, double approach_speed) {
  double mag = p.stiffness_N_per_m * (p.activation_m - gap);
  if (approach_speed > 0.0) mag += p.damping_Ns_per_m * approach_speed;
  return std::clamp(mag, 0.0, p.max_force_N);
}

}  // namespace

void avoidance(const TwoArmModel& model, const AvoidanceParams& p, const std::array<hk::Arm7Frames, kArms>& frames,
               const std::array<hk::Arm7Vector, kArms>& qd, AvoidanceResult& out) noexcept {
  std::array<ArmCapsules, kArms> caps;
  for (std::size_t a = 0; a < kArms; ++a) {
    caps[a] = arm_capsules_A(model.arms[a], frames[a]);
    out.tau[a].setZero();
  }
  out.active_pairs = 0;
  out.min_arm_arm_m = std::numeric_limits<double>::infinity();
  out.min_arm_bench_m = std::numeric_limits<double>::infinity();
  const ArmMount& R = model.arms[0];
  const ArmMount& L = model.arms[1];
  for (int i = 0; i < kCapsulesPerArm; ++i) {
    for (int j = 0; j < kCapsulesPerArm; ++j) {
      if (i == kPalm && j == kPalm) continue;  // hand-overs bring the grippers together
      const ArmCapsule& cr = caps[0][static_cast<std::size_t>(i)];
      const ArmCapsule& cl = caps[1][static_cast<std::size_t>(j)];
      const math::ClosestPoints cp = math::segment_segment(cr.a, cr.b, cl.a, cl.b);
      const double gap = cp.distance - cr.radius - cl.radius;
      out.min_arm_arm_m = std::min(out.min_arm_arm_m, gap);
      if (gap >= p.activation_m || cp.distance < 1e-9) continue;
      const Eigen::Vector3d n = (cp.p - cp.q) / cp.distance;  // from the left capsule to the right one
      const Eigen::Vector3d v_rel = point_velocity_A(R, frames[0], cr.link, cp.p, qd[0]) -
                                    point_velocity_A(L, frames[1], cl.link, cp.q, qd[1]);
      const double mag = repulsion(p, gap, -v_rel.dot(n));
      push(R, frames[0], cr.link, cp.p, mag * n, out.tau[0]);
      push(L, frames[1], cl.link, cp.q, -mag * n, out.tau[1]);
      ++out.active_pairs;
    }
  }
  // Link capsules (not the palms) against the bench top, over its footprint.
  const Bench& b = model.bench;
  for (std::size_t a = 0; a < kArms; ++a) {
    for (int i = 0; i < kPalm; ++i) {
      const ArmCapsule& c = caps[a][static_cast<std::size_t>(i)];
      const Eigen::Vector3d& low = c.a.z() < c.b.z() ? c.a : c.b;  // a segment's lowest point is an end
      if ((low.head<2>().array() < b.min_xy.array()).any() || (low.head<2>().array() > b.max_xy.array()).any()) continue;
      const double gap = low.z() - c.radius - b.top_z;
      out.min_arm_bench_m = std::min(out.min_arm_bench_m, gap);
      if (gap >= p.activation_m) continue;
      const Eigen::Vector3d v = point_velocity_A(model.arms[a], frames[a], c.link, low, qd[a]);
      const double mag = repulsion(p, gap, -v.z());
      push(model.arms[a], frames[a], c.link, low, Eigen::Vector3d(0.0, 0.0, mag), out.tau[a]);
      ++out.active_pairs;
    }
  }
}

}  // namespace hemm::twoarm
