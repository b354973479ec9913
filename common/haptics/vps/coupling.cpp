#include "common/haptics/vps/coupling.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace hemm::vps {

namespace {
double min_principal_inertia(const Eigen::Matrix3d& I) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(I);
  return std::max(es.eigenvalues().minCoeff(), 1e-12);
}
Eigen::Vector3d rotation_error(const Eigen::Quaterniond& q_target, const Eigen::Quaterniond& q) {
  Eigen::Quaterniond e = q_target * q.conjugate();
  if (e.w() < 0) e.coeffs() = -e.coeffs();  // shortest way round
  const Eigen::AngleAxisd aa(e);
  return aa.angle() * aa.axis();
}
}  // namespace

CouplingDesign design_coupling(double mass, const Eigen::Matrix3d& inertia_body, const CouplingDeviceLimits& d,
                               const CouplingDesignOptions& o) {
  CouplingDesign out;
  CouplingParams& p = out.params;
  p.dt = d.dt;
  p.mass = mass;
  p.inertia_body = inertia_body;
  const double w = o.omega_dt / d.dt;
  // One axis of the rule: returns {K, B, c} for inertia m, device damping b.
  struct Axis {
    double k, b, c;
  };
  auto design_axis = [&](double m, double b_dev, double k_max, double f_peak, double v_max) {
    const double budget = o.passivity_margin * b_dev;
    const double B = std::min(o.damping_share * budget, o.damping_force_share * f_peak / v_max);
    const double K = std::min({k_max, 2.0 * (budget - B) / d.dt, m * w * w});
    const double c_want = std::max(0.0, 2.0 * o.zeta * std::sqrt(K * m) - B);
    const double c = std::min(c_want, std::max(0.0, o.drag_force_share * f_peak / v_max - B));
    return Axis{K, B, c};
  };
  out.device_damping = d.physical_damping > 0 ? d.physical_damping : d.max_stiffness * d.dt / 2;
  const Axis lin = design_axis(mass, out.device_damping, d.max_stiffness, d.peak_force, d.max_speed);
  p.k_lin = lin.k;
  p.b_lin = lin.b;
  p.linear_damping = lin.c;
  out.passivity_lhs = lin.k * d.dt / 2 + lin.b;
  out.passivity_bound = o.passivity_margin * out.device_damping;
  out.damping_force_at_max_speed = lin.b * d.max_speed;
  out.drag_at_max_speed = (lin.b + lin.c) * d.max_speed;
  const double Imin = min_principal_inertia(inertia_body);
  if (d.renders_torque) {
    out.rot_device_damping = d.physical_rot_damping > 0 ? d.physical_rot_damping : d.max_rot_stiffness * d.dt / 2;
    const Axis rot =
        design_axis(Imin, out.rot_device_damping, d.max_rot_stiffness, d.peak_torque, d.max_angular_speed);
    p.k_rot = rot.k;
    p.b_rot = rot.b;
    p.angular_damping = rot.c;
    out.rot_passivity_lhs = rot.k * d.dt / 2 + rot.b;
    out.rot_passivity_bound = o.passivity_margin * out.rot_device_damping;
  } else {
    // Not displayed: only the tool's own stability matters.
    p.k_rot = 0.25 * Imin * w * w;
    p.b_rot = 2.0 * o.zeta * std::sqrt(p.k_rot * Imin);
    p.angular_damping = 0.0;
  }
  return out;
}

double max_contact_stiffness(const CouplingParams& p, double omega_dt) {
  const double w = omega_dt / p.dt;
  return std::max(0.0, p.mass * w * w - p.k_lin);
}

double max_expected_penetration(const CouplingParams& p, double max_lead, double peak_force,
                                double contact_stiffness) {
  if (!(contact_stiffness > 0)) return 0.0;
  return std::min(p.k_lin * max_lead, peak_force) / contact_stiffness;
}

void step_virtual_coupling(const CouplingParams& p, const Eigen::Isometry3d& T_W_D, const Eigen::Vector3d& v_D,
                           const Eigen::Vector3d& w_D, const Wrench& contact, RigidBodyState* s,
                           Wrench* device_wrench, Wrench* coupling_wrench) {
  const double dt = p.dt;
  // Translation: springs explicit, damping implicit.
  const Eigen::Vector3d spring = p.k_lin * (T_W_D.translation() - s->position);
  const Eigen::Vector3d v_new = (p.mass * s->linear_velocity + dt * (spring + p.b_lin * v_D + contact.force)) /
                                (p.mass + dt * (p.b_lin + p.linear_damping));
  const Eigen::Vector3d f_c = spring + p.b_lin * (v_D - v_new);
  // Rotation: world inertia, gyroscopic term explicit, damping implicit.
  const Eigen::Matrix3d R = s->orientation.toRotationMatrix();
  const Eigen::Matrix3d Iw = R * p.inertia_body * R.transpose();
  const Eigen::Quaterniond q_D(T_W_D.linear());
  const Eigen::Vector3d rot_spring = p.k_rot * rotation_error(q_D, s->orientation);
  const Eigen::Vector3d w = s->angular_velocity;
  const Eigen::Vector3d rhs = Iw * w + dt * (rot_spring + p.b_rot * w_D + contact.torque - w.cross(Iw * w));
  const Eigen::Matrix3d A = Iw + dt * (p.b_rot + p.angular_damping) * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d w_new = A.ldlt().solve(rhs);
  const Eigen::Vector3d tau_c = rot_spring + p.b_rot * (w_D - w_new);
  s->linear_velocity = v_new;
  s->position += dt * v_new;
  s->angular_velocity = w_new;
  const double angle = w_new.norm() * dt;
  if (angle > 0.0) {
    s->orientation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, w_new.normalized())) * s->orientation;
  }
  s->orientation.normalize();
  if (device_wrench != nullptr) {
    device_wrench->force = -f_c;
    device_wrench->torque = -tau_c;
  }
  if (coupling_wrench != nullptr) {
    coupling_wrench->force = f_c;
    coupling_wrench->torque = tau_c;
  }
}

double kinetic_energy(const CouplingParams& p, const RigidBodyState& s) {
  const Eigen::Matrix3d R = s.orientation.toRotationMatrix();
  const Eigen::Matrix3d Iw = R * p.inertia_body * R.transpose();
  return 0.5 * p.mass * s.linear_velocity.squaredNorm() + 0.5 * s.angular_velocity.dot(Iw * s.angular_velocity);
}

double coupling_potential(const CouplingParams& p, const RigidBodyState& s, const Eigen::Isometry3d& T_W_D) {
  const Eigen::Vector3d e = T_W_D.translation() - s.position;
  const Eigen::Vector3d r = rotation_error(Eigen::Quaterniond(T_W_D.linear()), s.orientation);
  return 0.5 * p.k_lin * e.squaredNorm() + 0.5 * p.k_rot * r.squaredNorm();
}

}  // namespace hemm::vps
