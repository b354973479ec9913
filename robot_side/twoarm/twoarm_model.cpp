#include "robot_side/twoarm/twoarm_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/kinematics/arm7_ik.h"

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

const char* to_string(Side s) { return s == Side::kRight ? "right" : "left"; }
const char* prefix(Side s) { return s == Side::kRight ? "r_" : "l_"; }

namespace {

bool rigid(const Eigen::Isometry3d& T) {
  return T.matrix().allFinite() && std::abs(T.linear().determinant() - 1.0) < 1e-9 &&
         (T.linear().transpose() * T.linear()).isIdentity(1e-9);
}

}  // namespace

std::optional<std::string> validate(const TwoArmModel& m) {
  for (Side s : {Side::kRight, Side::kLeft}) {
    const ArmMount& a = m.arm(s);
    const std::string who = std::string(to_string(s)) + " arm: ";
    if (auto e = hk::validate(a.arm)) return who + *e;
    if (!rigid(a.T_A_Ar)) return who + "mount must be a finite rigid transform";
    if (!rigid(a.T_J7_G)) return who + "grasp frame must be a finite rigid transform";
    if (!(a.gripper.finger_stroke_m > 0.0 && a.gripper.finger_stroke_m < 0.5))
      return who + "finger stroke must be in (0, 0.5) m";
    if (!(a.gripper.max_force_N > 0.0 && std::isfinite(a.gripper.max_force_N)))
      return who + "gripper force limit must be finite and > 0";
    if (!a.link_radius.allFinite() || !(a.link_radius.array() > 0.0).all() || (a.link_radius.array() > 0.3).any())
      return who + "link radii must be in (0, 0.3] m";
    if (!a.palm_a_J7.allFinite() || !a.palm_b_J7.allFinite() || !(a.palm_radius_m > 0.0 && a.palm_radius_m < 0.3))
      return who + "palm capsule must be finite with a radius in (0, 0.3) m";
    if (!hk::within_limits(a.arm, a.rest_q)) return who + "rest posture outside the joint limits";
  }
  if (!std::isfinite(m.bench.top_z) || !m.bench.min_xy.allFinite() || !m.bench.max_xy.allFinite() ||
      !(m.bench.min_xy.array() < m.bench.max_xy.array()).all())
    return "bench must be finite with min < max";
  if (!m.gravity_A.allFinite()) return "gravity must be finite";
  return std::nullopt;
}

Eigen::Isometry3d grasp_pose_A(const ArmMount& mount, const hk::Arm7Frames& f) {
  return mount.T_A_Ar * f.joint(hk::kArm7Flange) * mount.T_J7_G;
}

Eigen::Isometry3d grasp_pose_A(const ArmMount& mount, const hk::Arm7Vector& q) {
  hk::Arm7Frames f;
  hk::forward_kinematics(mount.arm, q, f);
  return grasp_pose_A(mount, f);
}

hk::Arm7Jacobian grasp_jacobian_A(const ArmMount& mount, const hk::Arm7Frames& f) {
  const Eigen::Vector3d p_Ar = (f.joint(hk::kArm7Flange) * mount.T_J7_G).translation();
  const hk::Arm7Jacobian J_Ar = hk::partial_jacobian(mount.arm, f, hk::kArm7Flange, p_Ar);
  hk::Arm7Jacobian J;
  const Eigen::Matrix3d& R = mount.T_A_Ar.linear();
  J.topRows<3>() = R * J_Ar.topRows<3>();
  J.bottomRows<3>() = R * J_Ar.bottomRows<3>();
  return J;
}

double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

GraspReach grasp_closest_reach(const ArmMount& mount, const Eigen::Isometry3d& T_A_G, const hk::Arm7Vector& q_seed) {
  GraspReach best;
  best.position_error_m = best.orientation_error_rad = std::numeric_limits<double>::infinity();
  if (!rigid(T_A_G) || !q_seed.allFinite()) return best;
  // The flange pose that puts G there, in Ar.
  const Eigen::Isometry3d T_Ar_J7 = mount.T_A_Ar.inverse() * T_A_G * mount.T_J7_G.inverse();
  hk::Arm7IkOptions o;
  o.max_iterations = 100;
  o.position_tolerance_m = 1e-3;
  o.orientation_tolerance_rad = 1e-2;
  double best_cost = std::numeric_limits<double>::infinity();
  // The errors at G, not at the flange the solver works on (an orientation
  // error moves G by the flange-to-G lever as well).
  const auto consider = [&](const hk::Arm7IkResult& r) {
    const Eigen::Isometry3d G = grasp_pose_A(mount, r.q);
    const double dp = (G.translation() - T_A_G.translation()).norm();
    const double dr = rotation_angle(G.linear(), T_A_G.linear());
    const double cost = dp + o.rotation_weight_m * dr;
    if (r.converged || cost < best_cost) {
      best_cost = cost;
      best = GraspReach{r.q, r.converged, dp, dr};
    }
    return r.converged;
  };
  if (consider(hk::inverse_kinematics(mount.arm, T_Ar_J7, q_seed, o))) return best;
  for (const hk::Arm7Vector& seed : hk::ik_seed_postures(mount.arm)) {
    if (consider(hk::inverse_kinematics(mount.arm, T_Ar_J7, seed, o))) return best;
  }
  return best;
}

std::optional<hk::Arm7Vector> grasp_inverse_kinematics(const ArmMount& mount, const Eigen::Isometry3d& T_A_G,
                                                       const hk::Arm7Vector& q_seed) {
  const GraspReach r = grasp_closest_reach(mount, T_A_G, q_seed);
  if (!r.reached) return std::nullopt;
  return r.q;
}

Eigen::Isometry3d downward_grasp(const Eigen::Vector3d& p_A) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = Eigen::Vector3d::UnitY();
  T.linear().col(1) = Eigen::Vector3d::UnitX();
  T.linear().col(2) = -Eigen::Vector3d::UnitZ();
  T.translation() = p_A;
  return T;
}

}  // namespace hemm::twoarm
