#include "robot_side/twoarm/arm_impedance.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

std::optional<std::string> validate(const ImpedanceParams& p, const hk::Arm7Model& arm) {
  const double v[] = {p.stiffness_N_per_m,        p.damping_Ns_per_m,          p.rot_stiffness_Nm_per_rad,
                      p.rot_damping_Nms_per_rad,  p.null_stiffness_Nm_per_rad, p.null_damping_Nms_per_rad,
                      p.null_lambda,              p.joint_limit_stiffness_Nm_per_rad,
                      p.joint_limit_damping_Nms_per_rad};
  for (double x : v) {
    if (!(std::isfinite(x) && x >= 0.0)) return "gains must be finite and >= 0";
  }
  if (!(p.force_limit_N > 0.0 && std::isfinite(p.force_limit_N))) return "force_limit_N must be finite and > 0";
  if (!(p.torque_limit_Nm > 0.0 && std::isfinite(p.torque_limit_Nm))) return "torque_limit_Nm must be finite and > 0";
  const double half_range = 0.5 * (arm.q_max - arm.q_min).minCoeff();
  if (!(p.joint_limit_margin_rad >= 0.0 && p.joint_limit_margin_rad < half_range))
    return "joint_limit_margin_rad must be in [0, half the smallest joint range)";
  return std::nullopt;
}

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

void arm_impedance(const ArmMount& mount, const Eigen::Vector3d& gravity_Ar, const ImpedanceParams& p,
                   const ImpedanceInput& in, const hk::Arm7Frames& frames, ImpedanceOutput& out) noexcept {
  const hk::Arm7Model& arm = mount.arm;
  out.T_A_G = grasp_pose_A(mount, frames);
  const hk::Arm7Jacobian J = grasp_jacobian_A(mount, frames);
  out.twist_A = J * in.qd;

  out.tau_bias = p.compensate_coriolis ? hk::bias_torque(arm, frames, in.qd, gravity_Ar)
                                       : hk::gravity_torque(arm, frames, gravity_Ar);

  // Null-space posture through N = I - J^T (J J^T + lambda^2 I)^-1 J.
  Eigen::Matrix<double, 6, 6> JJt = J * J.transpose();
  JJt.diagonal().array() += p.null_lambda * p.null_lambda;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> JJt_ldlt(JJt);
  const hk::Arm7Vector tau0 = p.null_stiffness_Nm_per_rad * (mount.rest_q - in.q) - p.null_damping_Nms_per_rad * in.qd;
  out.tau_null = tau0 - J.transpose() * JJt_ldlt.solve(J * tau0);

  // Joint-limit springs (and damping towards the limit) inside the margin.
  for (int i = 0; i < hk::kArm7Dof; ++i) {
    const double lo = arm.q_min(i) + p.joint_limit_margin_rad, hi = arm.q_max(i) - p.joint_limit_margin_rad;
    double tl = 0.0;
    if (in.q(i) < lo) {
      tl = p.joint_limit_stiffness_Nm_per_rad * (lo - in.q(i));
      if (in.qd(i) < 0.0) tl -= p.joint_limit_damping_Nms_per_rad * in.qd(i);
    } else if (in.q(i) > hi) {
      tl = p.joint_limit_stiffness_Nm_per_rad * (hi - in.q(i));
      if (in.qd(i) > 0.0) tl -= p.joint_limit_damping_Nms_per_rad * in.qd(i);
    }
    out.tau_limits(i) = tl;
  }

  // The spring, and the static wrench at G of everything else the arm does
  // (joint-limit springs, the avoidance, the projector's leakage): what G
  // would push on a wall with. The spring yields so that the sum stays
  // within the wrist limits.
  const hk::Wrench6 w_other = JJt_ldlt.solve(J * (out.tau_null + out.tau_limits + in.tau_extra));
  Eigen::Vector3d f = p.stiffness_N_per_m * (in.T_A_G_d.translation() - out.T_A_G.translation());
  Eigen::Vector3d t = p.rot_stiffness_Nm_per_rad * rotation_vector(in.T_A_G_d.linear() * out.T_A_G.linear().transpose());
  out.force_limited = false;
  auto cap = [&](Eigen::Vector3d& spring, const Eigen::Vector3d& other, double limit) {
    if (spring.norm() > limit) {
      spring *= limit / spring.norm();
      out.force_limited = true;
    }
    const Eigen::Vector3d total = spring + other;
    if (total.norm() > limit) {
      spring -= total * (1.0 - limit / total.norm());
      out.force_limited = true;
    }
  };
  cap(f, w_other.head<3>(), p.force_limit_N);
  cap(t, w_other.tail<3>(), p.torque_limit_Nm);
  out.T_A_G_yielded = out.T_A_G;
  if (p.stiffness_N_per_m > 0.0) out.T_A_G_yielded.translation() += f / p.stiffness_N_per_m;
  if (p.rot_stiffness_Nm_per_rad > 0.0) {
    const Eigen::Vector3d r = t / p.rot_stiffness_Nm_per_rad;
    if (r.norm() > 0.0) out.T_A_G_yielded.linear() = Eigen::AngleAxisd(r.norm(), r.normalized()) * out.T_A_G.linear();
  }
  out.wrench_A.head<3>() = f - p.damping_Ns_per_m * out.twist_A.head<3>();
  out.wrench_A.tail<3>() = t - p.rot_damping_Nms_per_rad * out.twist_A.tail<3>();
  out.tau_task = J.transpose() * out.wrench_A;

  out.torque_limited = false;
  for (int i = 0; i < hk::kArm7Dof; ++i) {
    const double raw = out.tau_bias(i) + out.tau_task(i) + out.tau_null(i) + out.tau_limits(i) + in.tau_extra(i);
    const double lim = arm.tau_max(i);
    const double c = std::isfinite(raw) ? std::clamp(raw, -lim, lim) : 0.0;
    if (c != raw) out.torque_limited = true;
    out.tau(i) = c;
  }
}

}  // namespace hemm::twoarm
