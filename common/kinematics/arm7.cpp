#include "common/kinematics/arm7.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

namespace hemm::kinematics {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Matrix3d skew_outer(const Eigen::Vector3d& d) {
  // Parallel-axis term m (|d|^2 I - d d^T) without the mass.
  return d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose();
}

}  // namespace

Eigen::Matrix3d cylinder_inertia(double mass, double radius, double length) {
  const double ixx = mass * (3.0 * radius * radius + length * length) / 12.0;
  return Eigen::Vector3d(ixx, ixx, 0.5 * mass * radius * radius).asDiagonal();
}

Arm7Model lwr_arm_model() {
  Arm7Model m;
  const double z[kArm7Dof] = {0.102, 0.2085, 0.1915, 0.2085, 0.1915, 0.1985, 0.078};
  const Eigen::Vector3d ax[kArm7Dof] = {Eigen::Vector3d::UnitZ(),  -Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                                        Eigen::Vector3d::UnitY(),  Eigen::Vector3d::UnitZ(),  -Eigen::Vector3d::UnitY(),
                                        Eigen::Vector3d::UnitZ()};
  const double mass[kArm7Dof] = {2.30, 2.30, 2.30, 2.30, 1.60, 1.49, 0.11};
  const Eigen::Vector3d com[kArm7Dof] = {{0.0, 0.023, 0.118},  {0.0, -0.033, 0.074}, {0.0, -0.023, 0.118},
                                         {0.0, 0.033, 0.074},  {0.0, 0.021, 0.086},  {0.0, -0.0045, -0.003},
                                         {0.0, 0.0, -0.016}};
  // Assumed shapes for the inertias (see the header): radius, length.
  const double radius[kArm7Dof] = {0.06, 0.06, 0.06, 0.06, 0.05, 0.05, 0.04};
  const double length[kArm7Dof] = {0.2085, 0.1915, 0.2085, 0.1915, 0.1985, 0.10, 0.02};
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    m.offset[k] = Eigen::Vector3d(0.0, 0.0, z[i]);
    m.axis[k] = ax[i];
    m.link[k].mass = mass[i];
    m.link[k].com = com[i];
    m.link[k].inertia = cylinder_inertia(mass[i], radius[i], length[i]);
  }
  for (int i = 0; i < kArm7Dof; ++i) {
    const double lim = (i % 2 == 0 ? 170.0 : 120.0) * kDeg;
    m.q_min(i) = -lim;
    m.q_max(i) = lim;
  }
  m.armature << 0.10, 0.10, 0.05, 0.05, 0.02, 0.01, 0.01;
  m.qd_max << 110, 110, 128, 128, 204, 184, 184;
  m.qd_max *= kDeg;
  m.tau_max << 176, 176, 100, 100, 100, 38, 38;
  return m;
}

std::optional<std::string> validate(const Arm7Model& m) {
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const std::string j = "joint " + std::to_string(i + 1) + ": ";
    if (!m.offset[k].allFinite() || m.offset[k].norm() > 10.0) return j + "offset must be finite, below 10 m";
    if (!m.axis[k].allFinite() || std::abs(m.axis[k].norm() - 1.0) > 1e-9) return j + "axis must be a unit vector";
    const RigidBodyInertia& l = m.link[k];
    if (!(std::isfinite(l.mass) && l.mass >= 0.0)) return j + "link mass must be finite and >= 0";
    if (!l.com.allFinite() || !l.inertia.allFinite()) return j + "link centre of mass and inertia must be finite";
    if ((l.inertia - l.inertia.transpose()).cwiseAbs().maxCoeff() > 1e-12)
      return j + "link inertia must be symmetric";
    const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(l.inertia).eigenvalues();
    if (ev.minCoeff() < -1e-12) return j + "link inertia must be positive semi-definite";
    // Triangle inequality of principal moments (a physical body).
    if (ev(0) + ev(1) < ev(2) - 1e-9) return j + "link inertia violates the triangle inequality";
  }
  if (!m.armature.allFinite() || (m.armature.array() < 0.0).any()) return "armature must be finite and >= 0";
  if (!m.q_min.allFinite() || !m.q_max.allFinite() || !(m.q_min.array() < m.q_max.array()).all())
    return "joint limits must be finite with q_min < q_max";
  if (!m.qd_max.allFinite() || !(m.qd_max.array() > 0.0).all()) return "speed limits must be finite and > 0";
  if (!m.tau_max.allFinite() || !(m.tau_max.array() > 0.0).all()) return "torque limits must be finite and > 0";
  return std::nullopt;
}

bool within_limits(const Arm7Model& m, const Arm7Vector& q, double tol) {
  return ((q.array() >= m.q_min.array() - tol) && (q.array() <= m.q_max.array() + tol)).all();
}

Arm7Vector clamp_to_limits(const Arm7Model& m, const Arm7Vector& q) {
  Arm7Vector out;
  for (int i = 0; i < kArm7Dof; ++i) {
    out(i) = std::clamp(std::isfinite(q(i)) ? q(i) : 0.0, m.q_min(i), m.q_max(i));
  }
  return out;
}

RigidBodyInertia combine(const RigidBodyInertia& a, const RigidBodyInertia& b) {
  RigidBodyInertia c;
  c.mass = a.mass + b.mass;
  if (c.mass <= 0.0) {
    c.inertia = a.inertia + b.inertia;
    return c;
  }
  c.com = (a.mass * a.com + b.mass * b.com) / c.mass;
  c.inertia = a.inertia + a.mass * skew_outer(a.com - c.com) + b.inertia + b.mass * skew_outer(b.com - c.com);
  return c;
}

Arm7Model with_payload(const Arm7Model& model, const RigidBodyInertia& payload_J7) {
  Arm7Model m = model;
  m.link[kArm7Dof - 1] = combine(m.link[kArm7Dof - 1], payload_J7);
  return m;
}

void forward_kinematics(const Arm7Model& m, const Arm7Vector& q, Arm7Frames& f) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    T.translation() += T.linear() * m.offset[k];
    T.linear() = T.linear() * Eigen::AngleAxisd(q(i), m.axis[k]).toRotationMatrix();
    f.T_A_J[k] = T;
  }
}

Eigen::Isometry3d flange_pose(const Arm7Model& m, const Arm7Vector& q) {
  Arm7Frames f;
  forward_kinematics(m, q, f);
  return f.joint(kArm7Flange);
}

Arm7Jacobian partial_jacobian(const Arm7Model& m, const Arm7Frames& f, int k, const Eigen::Vector3d& p_A) {
  Arm7Jacobian J = Arm7Jacobian::Zero();
  k = std::clamp(k, 0, kArm7Dof);
  for (int i = 1; i <= k; ++i) {
    const Eigen::Vector3d a = f.axis_A(m, i);
    J.block<3, 1>(0, i - 1) = a.cross(p_A - f.origin(i));
    J.block<3, 1>(3, i - 1) = a;
  }
  return J;
}

Arm7Jacobian elbow_jacobian(const Arm7Model& m, const Arm7Frames& f) {
  return partial_jacobian(m, f, kArm7Elbow, f.origin(kArm7Elbow));
}

Arm7Jacobian flange_jacobian(const Arm7Model& m, const Arm7Frames& f) {
  return partial_jacobian(m, f, kArm7Flange, f.origin(kArm7Flange));
}

Wrench6 drift_acceleration(const Arm7Model& m, const Arm7Frames& f, const Arm7Vector& qd, int k,
                           const Eigen::Vector3d& p_A) {
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), dw = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();
  Eigen::Vector3d o_prev = Eigen::Vector3d::Zero();
  k = std::clamp(k, 1, kArm7Dof);
  for (int i = 1; i <= k; ++i) {
    const Eigen::Vector3d o = f.origin(i), r = o - o_prev;
    a += dw.cross(r) + w.cross(w.cross(r));
    const Eigen::Vector3d z = f.axis_A(m, i);
    dw += w.cross(z * qd(i - 1));
    w += z * qd(i - 1);
    o_prev = o;
  }
  const Eigen::Vector3d r = p_A - o_prev;
  Wrench6 out;
  out << a + dw.cross(r) + w.cross(w.cross(r)), dw;
  return out;
}

Arm7Vector inverse_dynamics(const Arm7Model& m, const Arm7Frames& f, const Arm7Vector& qd, const Arm7Vector& qdd,
                            const Eigen::Vector3d& g_A) {
  // Forward pass in A: angular velocity/acceleration of each link, linear
  // acceleration of each joint origin (gravity as a base acceleration -g).
  std::array<Eigen::Vector3d, kArm7Dof> F, N, c_rel;
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), dw = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = -g_A;  // acceleration of the previous origin
  Eigen::Vector3d o_prev = Eigen::Vector3d::Zero();
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Vector3d o = f.T_A_J[k].translation();
    const Eigen::Vector3d r = o - o_prev;
    // The origin of J_i is fixed in link i-1: it moves with the previous link.
    a += dw.cross(r) + w.cross(w.cross(r));
    const Eigen::Vector3d z = f.T_A_J[k].linear() * m.axis[k];
    dw += z * qdd(i) + w.cross(z * qd(i));
    w += z * qd(i);
    const RigidBodyInertia& l = m.link[k];
    const Eigen::Matrix3d& R = f.T_A_J[k].linear();
    c_rel[k] = R * l.com;
    const Eigen::Vector3d ac = a + dw.cross(c_rel[k]) + w.cross(w.cross(c_rel[k]));
    const Eigen::Matrix3d I = R * l.inertia * R.transpose();
    F[k] = l.mass * ac;
    N[k] = I * dw + w.cross(I * w);
    o_prev = o;
  }
  // Backward pass: force and moment (about the joint origin) each link
  // receives from its parent.
  Arm7Vector tau;
  Eigen::Vector3d f_next = Eigen::Vector3d::Zero(), n_next = Eigen::Vector3d::Zero();
  for (int i = kArm7Dof - 1; i >= 0; --i) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Vector3d o = f.T_A_J[k].translation();
    Eigen::Vector3d n = N[k] + c_rel[k].cross(F[k]) + n_next;
    if (i + 1 < kArm7Dof) n += (f.T_A_J[k + 1].translation() - o).cross(f_next);
    const Eigen::Vector3d fi = F[k] + f_next;
    tau(i) = (f.T_A_J[k].linear() * m.axis[k]).dot(n) + m.armature(i) * qdd(i);
    f_next = fi;
    n_next = n;
  }
  return tau;
}

Arm7Vector gravity_torque(const Arm7Model& m, const Arm7Frames& f, const Eigen::Vector3d& g_A) {
  return inverse_dynamics(m, f, Arm7Vector::Zero(), Arm7Vector::Zero(), g_A);
}

Arm7Vector bias_torque(const Arm7Model& m, const Arm7Frames& f, const Arm7Vector& qd, const Eigen::Vector3d& g_A) {
  return inverse_dynamics(m, f, qd, Arm7Vector::Zero(), g_A);
}

Arm7Matrix mass_matrix(const Arm7Model& m, const Arm7Frames& f) {
  // CRBA in A: the composite body C_j of links j..7 (mass, centre, inertia
  // about that centre) receives a unit acceleration of joint j; column j of M
  // holds the moments about each joint axis i <= j this takes.
  Arm7Matrix M = Arm7Matrix::Zero();
  RigidBodyInertia C;  // in A
  for (int j = kArm7Dof - 1; j >= 0; --j) {
    const auto k = static_cast<std::size_t>(j);
    const Eigen::Matrix3d& R = f.T_A_J[k].linear();
    RigidBodyInertia l;
    l.mass = m.link[k].mass;
    l.com = f.T_A_J[k] * m.link[k].com;
    l.inertia = R * m.link[k].inertia * R.transpose();
    C = combine(C, l);
    const Eigen::Vector3d zj = R * m.axis[k];
    const Eigen::Vector3d oj = f.T_A_J[k].translation();
    const Eigen::Vector3d Fj = C.mass * zj.cross(C.com - oj);
    const Eigen::Vector3d Nj = C.inertia * zj;  // about C's centre
    for (int i = 0; i <= j; ++i) {
      const auto ki = static_cast<std::size_t>(i);
      const Eigen::Vector3d zi = f.T_A_J[ki].linear() * m.axis[ki];
      const Eigen::Vector3d oi = f.T_A_J[ki].translation();
      M(i, j) = zi.dot(Nj + (C.com - oi).cross(Fj));
      M(j, i) = M(i, j);
    }
  }
  M.diagonal() += m.armature;
  return M;
}

}  // namespace hemm::kinematics

namespace hemm::kinematics {

Arm7Elbow arm7_elbow(const Arm7Model& m) {
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const bool along = i % 2 == 0 ? std::abs(std::abs(m.axis[k].z()) - 1.0) < 1e-12 : std::abs(m.axis[k].z()) < 1e-12;
    if (!along || m.offset[k].head<2>().norm() > 1e-12)
      throw std::invalid_argument("arm7_elbow: joint " + std::to_string(i + 1) + " does not fit the S-R-S layout");
  }
  Arm7Frames f;
  forward_kinematics(m, Arm7Vector::Zero(), f);
  Arm7Elbow e;
  e.shoulder_A = f.origin(2);
  e.wrist_J7 = f.joint(7).inverse() * f.origin(6);
  e.upper_arm_m = (f.origin(4) - f.origin(2)).norm();
  e.forearm_m = (f.origin(6) - f.origin(4)).norm();
  return e;
}

double elbow_bend(const Arm7Elbow& e, const Eigen::Vector3d& wrist_A) {
  const double a = e.upper_arm_m, b = e.forearm_m, d = (wrist_A - e.shoulder_A).norm();
  if (d > a + b) return -(d - a - b);
  return std::acos(std::clamp((d * d - a * a - b * b) / (2.0 * a * b), -1.0, 1.0));
}

}  // namespace hemm::kinematics
