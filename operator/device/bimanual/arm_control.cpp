#include "operator/device/bimanual/arm_control.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

namespace hemm::device::bimanual {

namespace hk = hemm::kinematics;
using hk::Arm7Jacobian;
using hk::Arm7Matrix;
using hk::Arm7Vector;
using hk::Wrench6;

namespace {

// Projector onto range(J^T) = J^T (J^T)^+ from the SVD of J^T (7 x 6).
Arm7Matrix range_projector(const Arm7Jacobian& J, double rel_tol) {
  const Eigen::JacobiSVD<Eigen::Matrix<double, 7, 6>> svd(J.transpose(), Eigen::ComputeFullU);
  const auto& s = svd.singularValues();
  const double tol = rel_tol * std::max(s(0), 1e-300);
  Arm7Matrix P = Arm7Matrix::Zero();
  for (int i = 0; i < 6; ++i) {
    if (s(i) > tol) P += svd.matrixU().col(i) * svd.matrixU().col(i).transpose();
  }
  return P;
}

}  // namespace

NullSpaceTorques null_space_eq1_4(const Arm7Jacobian& J4, const Arm7Jacobian& J7, const Wrench6& F_d, double rel_tol) {
  NullSpaceTorques out;
  out.T_d = J4.transpose() * F_d;  // J4's columns 5-7 are zero: [T_d; 0]
  // (J7^T)^+ by the SVD J7^T = U S V^T: (J7^T)^+ = V S^+ U^T.
  const Eigen::JacobiSVD<Eigen::Matrix<double, 7, 6>> svd(J7.transpose(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  const auto& s = svd.singularValues();
  const double tol = rel_tol * std::max(s(0), 1e-300);
  Eigen::Matrix<double, 6, 1> uTt = svd.matrixU().leftCols<6>().transpose() * out.T_d;
  for (int i = 0; i < 6; ++i) uTt(i) = s(i) > tol ? uTt(i) / s(i) : 0.0;
  out.F_E = svd.matrixV() * uTt;
  out.T_comp = -J7.transpose() * out.F_E;
  out.T = out.T_d + out.T_comp;
  return out;
}

Arm7Matrix kinematic_null_projector(const Arm7Jacobian& J7, double rel_tol) {
  return Arm7Matrix::Identity() - range_projector(J7, rel_tol);
}

Eigen::Matrix<double, 6, 6> operational_space_inertia(const Arm7Jacobian& J, const Arm7Matrix& M, double rel_tol) {
  const Arm7Matrix Minv = M.ldlt().solve(Arm7Matrix::Identity());
  const Eigen::Matrix<double, 6, 6> A = J * Minv * J.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(A);
  const double tol = rel_tol * std::max(es.eigenvalues().maxCoeff(), 1e-300);
  Eigen::Matrix<double, 6, 6> Lambda = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 6; ++i) {
    const double ev = es.eigenvalues()(i);
    if (ev > tol) Lambda += es.eigenvectors().col(i) * es.eigenvectors().col(i).transpose() / ev;
  }
  return Lambda;
}

Arm7Matrix dynamic_null_projector(const Arm7Jacobian& J7, const Arm7Matrix& M, double rel_tol) {
  const Arm7Matrix Minv = M.ldlt().solve(Arm7Matrix::Identity());
  return Arm7Matrix::Identity() - J7.transpose() * operational_space_inertia(J7, M, rel_tol) * J7 * Minv;
}

const char* to_string(NullSpaceProjector p) { return p == NullSpaceProjector::kKinematic ? "kinematic" : "dynamic"; }

Wrench6 shift_wrench(const Wrench6& w, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  Wrench6 out = w;
  out.tail<3>() += (from - to).cross(w.head<3>());
  return out;
}

Wrench6 hand_wrench_at_E(const Wrench6& ft_J7, const Eigen::Isometry3d& T_D_J7, const HandleSpec& h,
                         const Eigen::Vector3d& g_D, const Eigen::Vector3d& a_E, const Eigen::Vector3d& alpha,
                         const Eigen::Vector3d& omega) {
  const Eigen::Matrix3d& R = T_D_J7.linear();
  const Eigen::Vector3d p_fl = T_D_J7.translation();
  const Eigen::Vector3d p_E = T_D_J7 * h.T_J7_E.translation();
  const Eigen::Vector3d c = T_D_J7 * h.inertia_J7.com;
  const Eigen::Matrix3d I = R * h.inertia_J7.inertia * R.transpose();
  const Eigen::Vector3d r = c - p_E;
  const Eigen::Vector3d a_c = a_E + alpha.cross(r) + omega.cross(omega.cross(r));
  // The sensor reads the hand's wrench minus what the handle's own weight
  // and motion take: add those back (about the flange).
  const Eigen::Vector3d f_load = h.inertia_J7.mass * (a_c - g_D);
  const Eigen::Vector3d t_load = I * alpha + omega.cross(I * omega) + (c - p_fl).cross(f_load);
  Wrench6 w;
  w.head<3>() = R * ft_J7.head<3>() + f_load;
  w.tail<3>() = R * ft_J7.tail<3>() + t_load;
  return shift_wrench(w, p_fl, p_E);
}

Box default_workspace() {
  Box b;
  b.min_D << -1.0, -0.75, 0.10;
  b.max_D << -0.20, 0.75, 0.85;
  return b;
}

ArmControlParams default_arm_control() {
  ArmControlParams p;
  p.workspace_D = default_workspace();
  return p;
}

std::optional<std::string> validate(const ArmControlParams& p) {
  auto fin = [](double v) { return std::isfinite(v); };
  auto nonneg = [&](double v) { return fin(v) && v >= 0.0; };
  if (!(fin(p.inertia_ratio_translation) && p.inertia_ratio_translation >= 0.1 && p.inertia_ratio_translation <= 1.0) ||
      !(fin(p.inertia_ratio_rotation) && p.inertia_ratio_rotation >= 0.1 && p.inertia_ratio_rotation <= 1.0))
    return "inertia ratios must be in [0.1, 1]";
  if (!(nonneg(p.elbow_force) && p.elbow_force <= 100.0)) return "elbow_force must be in [0, 100] N";
  for (double v : {p.null_space_damping, p.cartesian_damping, p.cartesian_rot_damping,
                   p.workspace_stiffness, p.workspace_damping, p.speed_limit_damping, p.joint_speed_damping,
                   p.joint_limit_stiffness, p.collision.stiffness, p.collision.damping}) {
    if (!nonneg(v)) return "stiffness and damping gains must be finite and >= 0";
  }
  if (!(p.peak_force > 0.0 && p.peak_force <= 300.0)) return "peak_force must be in (0, 300] N";
  if (!(p.peak_torque > 0.0 && p.peak_torque <= 50.0)) return "peak_torque must be in (0, 50] N m";
  if (!(p.max_linear_speed > 0.0 && p.max_linear_speed <= 3.0)) return "max_linear_speed must be in (0, 3] m/s";
  if (!(p.joint_speed_fraction > 0.0 && p.joint_speed_fraction <= 1.0)) return "joint_speed_fraction must be in (0, 1]";
  if (!(p.joint_limit_margin >= 0.0 && p.joint_limit_margin < 0.5)) return "joint_limit_margin must be in [0, 0.5) rad";
  if (!(p.collision.activation_m > 0.0 && p.collision.activation_m <= 0.5)) return "collision activation must be in (0, 0.5] m";
  if (!(p.collision.max_force > 0.0 && fin(p.collision.max_force))) return "collision max_force must be > 0";
  const Box& b = p.workspace_D;
  if (!b.min_D.allFinite() || !b.max_D.allFinite() || !(b.min_D.array() < b.max_D.array()).all())
    return "workspace box must be finite with min < max";
  return std::nullopt;
}

BimanualController::BimanualController(const RigGeometry& rig, const std::array<HandleKind, kArms>& handles,
                                       const std::array<ArmControlParams, kArms>& params, double period_s)
    : rig_(rig), params_(params), dt_(period_s) {
  if (auto e = validate(rig)) throw std::invalid_argument("BimanualController: rig: " + *e);
  if (!(period_s > 0.0 && period_s <= 0.01)) throw std::invalid_argument("BimanualController: period must be in (0, 10] ms");
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    if (auto e = validate(params[k]))
      throw std::invalid_argument(std::string("BimanualController: ") + to_string(static_cast<ArmSide>(a)) + " arm: " + *e);
    handles_[k] = handle_spec(handles[k]);
    nominal_[k] = hk::with_payload(rig.arm, handles_[k].inertia_J7);
  }
}

void BimanualController::reset() noexcept { have_prev_ = {false, false}; }

void BimanualController::update(const std::array<ArmInput, kArms>& in, std::array<ArmOutput, kArms>& out) noexcept {
  std::array<Arm7Vector, kArms> qd;
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    hk::forward_kinematics(nominal_[k], in[k].q, frames_[k]);
    capsules_[k] = arm_capsules(rig_, static_cast<ArmSide>(a), handles_[k], frames_[k]);
    qd[k] = in[k].enabled ? in[k].qd : Arm7Vector::Zero();
  }
  collision_avoidance(rig_, params_[0].collision, capsules_, frames_, qd, collision_);

  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmControlParams& P = params_[k];
    const hk::Arm7Model& m = nominal_[k];
    const HandleSpec& h = handles_[k];
    const hk::Arm7Frames& f = frames_[k];
    const ArmInput& I = in[k];
    ArmOutput& O = out[k];
    const Eigen::Isometry3d& T_D_A = rig_.T_D_A[k];
    const Eigen::Matrix3d& R = T_D_A.linear();

    const Eigen::Isometry3d T_D_J7 = T_D_A * f.joint(7);
    O.T_D_E = T_D_J7 * h.T_J7_E;
    O.elbow_D = T_D_A * f.origin(hk::kArm7Elbow);
    const Eigen::Vector3d p_E_A = T_D_A.inverse() * O.T_D_E.translation();
    const Arm7Jacobian J_E_A = hk::partial_jacobian(m, f, 7, p_E_A);
    Arm7Jacobian J_E;  // in D
    J_E.topRows<3>() = R * J_E_A.topRows<3>();
    J_E.bottomRows<3>() = R * J_E_A.bottomRows<3>();
    O.twist_E_D = J_E * I.qd;
    O.nonfinite_wrench = !I.w_env_D.allFinite();
    if (!I.enabled) {
      O.tau.setZero();
      O.tau_bias.setZero();
      O.tau_task.setZero();
      O.tau_null.setZero();
      O.tau_collision.setZero();
      O.tau_limits.setZero();
      O.w_env_applied_D.setZero();
      O.w_hand_D.setZero();
      O.w_limits_D.setZero();
      O.torque_limited = O.wrench_limited = false;
      have_prev_[k] = false;
      continue;
    }
    // End-effector acceleration by differences of the measured twist.
    Wrench6 acc = Wrench6::Zero();
    if (have_prev_[k]) acc = (O.twist_E_D - prev_twist_[k]) / dt_;
    prev_twist_[k] = O.twist_E_D;
    have_prev_[k] = true;

    const Eigen::Vector3d g_A = R.transpose() * rig_.gravity_D;
    O.tau_bias = P.compensate_coriolis ? hk::bias_torque(m, f, I.qd, g_A) : hk::gravity_torque(m, f, g_A);

    // The renderer's wrench, within the device's peak force and torque.
    Wrench6 w_env = O.nonfinite_wrench ? Wrench6::Zero() : I.w_env_D;
    O.wrench_limited = false;
    if (w_env.head<3>().norm() > P.peak_force) {
      w_env.head<3>() *= P.peak_force / w_env.head<3>().norm();
      O.wrench_limited = true;
    }
    if (w_env.tail<3>().norm() > P.peak_torque) {
      w_env.tail<3>() *= P.peak_torque / w_env.tail<3>().norm();
      O.wrench_limited = true;
    }
    O.w_env_applied_D = w_env;

    // The device's own walls: workspace box and speed limit at E, plus the
    // damping the hand feels.
    const Eigen::Vector3d p_E = O.T_D_E.translation();
    const Eigen::Vector3d v_E = O.twist_E_D.head<3>(), w_E = O.twist_E_D.tail<3>();
    Wrench6 w_lim = Wrench6::Zero();
    for (int i = 0; i < 3; ++i) {
      if (p_E(i) > P.workspace_D.max_D(i)) {
        w_lim(i) += -P.workspace_stiffness * (p_E(i) - P.workspace_D.max_D(i)) - P.workspace_damping * v_E(i);
      } else if (p_E(i) < P.workspace_D.min_D(i)) {
        w_lim(i) += P.workspace_stiffness * (P.workspace_D.min_D(i) - p_E(i)) - P.workspace_damping * v_E(i);
      }
    }
    const double speed = v_E.norm();
    if (speed > P.max_linear_speed) w_lim.head<3>() -= P.speed_limit_damping * (speed - P.max_linear_speed) * v_E / speed;
    O.w_limits_D = w_lim;
    Wrench6 w_felt = w_env + w_lim;
    w_felt.head<3>() -= P.cartesian_damping * v_E;
    w_felt.tail<3>() -= P.cartesian_rot_damping * w_E;

    // Feed-forward inertia reduction: inertia shaping at E from the hand's
    // wrench (wrist sensor minus the handle's load).
    O.w_hand_D = hand_wrench_at_E(I.ft_J7, T_D_J7, h, rig_.gravity_D, acc.head<3>(), acc.tail<3>(), w_E);
    const double st = P.feedforward ? 1.0 / P.inertia_ratio_translation : 1.0;
    const double sr = P.feedforward ? 1.0 / P.inertia_ratio_rotation : 1.0;
    Wrench6 w_cmd;
    w_cmd.head<3>() = (st - 1.0) * O.w_hand_D.head<3>() + st * w_felt.head<3>();
    w_cmd.tail<3>() = (sr - 1.0) * O.w_hand_D.tail<3>() + sr * w_felt.tail<3>();
    O.tau_task = J_E.transpose() * w_cmd;

    // Null space: the elbow pushed outwards (Eq. 1-4 or dynamically consistent).
    const Arm7Matrix M = hk::mass_matrix(m, f);
    const Arm7Jacobian J4 = hk::elbow_jacobian(m, f);
    Wrench6 F_d = Wrench6::Zero();
    const double out_dir = static_cast<ArmSide>(a) == ArmSide::kRight ? -1.0 : 1.0;
    F_d.head<3>() = R.transpose() * Eigen::Vector3d(0.0, out_dir * P.elbow_force, 0.0);
    const Arm7Vector tau0 = J4.transpose() * F_d - P.null_space_damping * (M * I.qd);
    if (P.projector == NullSpaceProjector::kKinematic) {
      O.tau_null = kinematic_null_projector(J_E_A) * tau0;
    } else {
      const Arm7Matrix Minv = M.ldlt().solve(Arm7Matrix::Identity());
      const Eigen::Matrix<double, 6, 6> Lambda = operational_space_inertia(J_E_A, M);
      const Wrench6 drift = hk::drift_acceleration(m, f, I.qd, 7, p_E_A);
      O.tau_null = tau0 - J_E_A.transpose() * (Lambda * (J_E_A * (Minv * tau0) + drift));
    }

    O.tau_collision = collision_.tau[k];

    // Joint range springs and joint speed damping.
    O.tau_limits.setZero();
    for (int i = 0; i < hk::kArm7Dof; ++i) {
      const double hi = m.q_max(i) - P.joint_limit_margin, lo = m.q_min(i) + P.joint_limit_margin;
      if (I.q(i) > hi) O.tau_limits(i) -= P.joint_limit_stiffness * (I.q(i) - hi);
      if (I.q(i) < lo) O.tau_limits(i) += P.joint_limit_stiffness * (lo - I.q(i));
      const double vmax = P.joint_speed_fraction * m.qd_max(i);
      if (std::abs(I.qd(i)) > vmax)
        O.tau_limits(i) -= P.joint_speed_damping * M(i, i) * (std::abs(I.qd(i)) - vmax) * (I.qd(i) > 0 ? 1.0 : -1.0);
    }

    // Torque limits: scale everything but the bias uniformly to fit, then clip.
    const Arm7Vector rest = O.tau_task + O.tau_null + O.tau_collision + O.tau_limits;
    double s = 1.0;
    for (int i = 0; i < hk::kArm7Dof; ++i) {
      const double lim = m.tau_max(i), b = O.tau_bias(i), r = rest(i);
      if (std::abs(b + r) > lim && std::abs(r) > 1e-12) {
        const double room = (r > 0 ? lim - b : -lim - b) / r;
        s = std::min(s, std::max(room, 0.0));
      }
    }
    O.tau = (O.tau_bias + s * rest).cwiseMax(-m.tau_max).cwiseMin(m.tau_max);
    O.torque_limited = s < 1.0 || (O.tau_bias + s * rest - O.tau).cwiseAbs().maxCoeff() > 0.0;
    if (!O.tau.allFinite()) O.tau.setZero();
  }
}

}  // namespace hemm::device::bimanual
