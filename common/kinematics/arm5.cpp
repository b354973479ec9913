#include "common/kinematics/arm5.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>

namespace hemm::kinematics {
namespace {

bool finite(const Eigen::Ref<const Eigen::MatrixXd>& m) { return m.allFinite(); }

Eigen::Isometry3d dh_transform(double theta, double d, double a, double alpha) {
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(alpha), sa = std::sin(alpha);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << ct, -st * ca, st * sa,  //
      st, ct * ca, -ct * sa,            //
      0, sa, ca;
  T.translation() << a * ct, a * st, d;
  return T;
}

// Weighted 5-vector task error and its Jacobian (position, pitch in sine
// space so it is smooth up to +-90 deg, roll as a joint target).
struct Task {
  Eigen::Matrix<double, 5, 1> e;
  Eigen::Matrix<double, 5, 5> J;
};

Task task(const Arm5Model& model, const Arm5Target& t, const Arm5Vector& q, const IkOptions& o) {
  const Eigen::Isometry3d T = forward_kinematics(model, q);
  const Arm5Jacobian Jg = jacobian(model, q);
  const Eigen::Vector3d xE = T.linear().col(0);
  Task out;
  out.e.head<3>() = t.p_A_E - T.translation();
  out.e(3) = o.pitch_weight_m * (std::sin(t.tool_pitch) - xE.z());
  out.e(4) = o.roll_weight_m * (t.wrist_roll - q(3));
  out.J.topRows<3>() = Jg.topRows<3>();
  for (int i = 0; i < kArm5Dof; ++i) {
    const Eigen::Vector3d w = Jg.block<3, 1>(3, i);
    out.J(3, i) = o.pitch_weight_m * w.cross(xE).z();
    out.J(4, i) = i == 3 ? o.roll_weight_m : 0.0;
  }
  return out;
}

IkResult finish(const Arm5Model& model, const Arm5Target& t, const Arm5Vector& q, int iterations,
                const IkOptions& o) {
  IkResult r;
  r.q = q;
  r.iterations = iterations;
  const Eigen::Isometry3d T = forward_kinematics(model, q);
  r.position_error_m = (t.p_A_E - T.translation()).norm();
  r.pitch_error_rad = std::abs(t.tool_pitch - tool_pitch(T));
  r.roll_error_rad = std::abs(t.wrist_roll - q(3));
  const bool ok = r.position_error_m <= 10 * o.position_tolerance_m &&
                  r.pitch_error_rad <= 10 * o.pitch_tolerance_rad && r.roll_error_rad <= 10 * o.pitch_tolerance_rad;
  r.status = ok ? IkStatus::kConverged : IkStatus::kUnreachable;
  return r;
}

double cost(const Task& t) { return t.e.squaredNorm(); }

IkResult solve_from(const Arm5Model& model, const Arm5Target& t, Arm5Vector q, const IkOptions& o) {
  q = clamp_to_limits(model, q);
  Task cur = task(model, t, q, o);
  double lambda = o.damping;
  int it = 0;
  for (; it < o.max_iterations; ++it) {
    if (cur.e.head<3>().norm() < o.position_tolerance_m &&
        std::abs(cur.e(3)) < o.pitch_weight_m * o.pitch_tolerance_rad * 0.5 &&
        std::abs(cur.e(4)) < o.roll_weight_m * o.pitch_tolerance_rad)
      break;
    // Levenberg-Marquardt: accept steps that lower the cost, else damp more.
    bool accepted = false;
    for (int tries = 0; tries < 12 && !accepted; ++tries) {
      const Eigen::Matrix<double, 5, 5> A =
          cur.J * cur.J.transpose() + lambda * lambda * Eigen::Matrix<double, 5, 5>::Identity();
      Arm5Vector dq = cur.J.transpose() * A.ldlt().solve(cur.e);
      const double m = dq.cwiseAbs().maxCoeff();
      if (!(m < 1e9)) dq.setZero();  // guards NaN too
      if (m > o.max_step_rad) dq *= o.max_step_rad / m;
      const Arm5Vector qn = clamp_to_limits(model, q + dq);
      const Task next = task(model, t, qn, o);
      if (cost(next) < cost(cur)) {
        accepted = true;
        q = qn;
        cur = next;
        lambda = std::max(lambda * 0.5, 1e-6);
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) break;  // a local minimum (out of reach or at limits)
  }
  return finish(model, t, q, it, o);
}

// Exact solution when q4 = 0 (the arm stays in the vertical plane of q1):
// a planar 2-link problem for the wrist point, elbow up.
Arm5Vector analytic_seed(const Arm5Model& m, const Arm5Target& t, bool elbow_up) {
  Arm5Vector q = Arm5Vector::Zero();
  const Eigen::Vector3d& p = t.p_A_E;
  q(0) = std::hypot(p.x(), p.y()) > 1e-9 ? std::atan2(p.y(), p.x()) : 0.0;
  const double c1 = std::cos(q(0)), s1 = std::sin(q(0));
  const double cp = std::cos(t.tool_pitch), sp = std::sin(t.tool_pitch);
  const Eigen::Vector3d w = p - m.A5 * Eigen::Vector3d(cp * c1, cp * s1, sp);
  const double r = w.x() * c1 + w.y() * s1 - m.A1;
  const double z = w.z();
  const double D = std::clamp((r * r + z * z - m.A2 * m.A2 - m.A4 * m.A4) / (2 * m.A2 * m.A4), -1.0, 1.0);
  q(2) = elbow_up ? -std::acos(D) : std::acos(D);
  q(1) = std::atan2(z, r) - std::atan2(m.A4 * std::sin(q(2)), m.A2 + m.A4 * std::cos(q(2)));
  q(3) = t.wrist_roll;
  q(4) = q(1) + q(2) - t.tool_pitch;
  for (int i = 0; i < kArm5Dof; ++i) {
    if (!std::isfinite(q(i))) q(i) = 0.0;
  }
  return q;
}

}  // namespace

std::optional<std::string> validate(const Arm5Model& m) {
  for (double l : {m.A1, m.A2, m.A4, m.A5}) {
    if (!(std::isfinite(l) && l >= 0 && l < 10)) return "link lengths must be finite, in [0, 10) m";
  }
  if (!(m.A2 > 0 && m.A4 > 0)) return "A2 and A4 must be positive";
  if (!finite(m.q_min) || !finite(m.q_max)) return "joint limits must be finite";
  if (!(m.q_min.array() < m.q_max.array()).all()) return "q_min must be below q_max";
  return std::nullopt;
}

bool within_limits(const Arm5Model& m, const Arm5Vector& q, double tol) {
  return ((q.array() >= m.q_min.array() - tol) && (q.array() <= m.q_max.array() + tol)).all();
}

Arm5Vector clamp_to_limits(const Arm5Model& m, const Arm5Vector& q) {
  Arm5Vector out;
  for (int i = 0; i < kArm5Dof; ++i) {
    out(i) = std::isfinite(q(i)) ? std::clamp(q(i), m.q_min(i), m.q_max(i)) : std::clamp(0.0, m.q_min(i), m.q_max(i));
  }
  return out;
}

Eigen::Isometry3d forward_kinematics(const Arm5Model& m, const Arm5Vector& q) {
  const double c1 = std::cos(q(0)), s1 = std::sin(q(0));
  const double c2 = std::cos(q(1)), s2 = std::sin(q(1));
  const double c23 = std::cos(q(1) + q(2)), s23 = std::sin(q(1) + q(2));
  const double c4 = std::cos(q(3)), s4 = std::sin(q(3));
  const double c5 = std::cos(q(4)), s5 = std::sin(q(4));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  auto R = T.linear();
  // Eq. 3 with the second column's sign fixed (see the header).
  const double a11 = c1 * s23 * c4 * s5 + c1 * c23 * c5 + s1 * s4 * s5;
  const double a21 = s1 * s23 * c4 * s5 + s1 * c23 * c5 - c1 * s4 * s5;
  const double a31 = -c23 * c4 * s5 + s23 * c5;
  R(0, 0) = a11;
  R(1, 0) = a21;
  R(2, 0) = a31;
  R(0, 1) = c1 * s23 * s4 - s1 * c4;
  R(1, 1) = s1 * s23 * s4 + c1 * c4;
  R(2, 1) = -c23 * s4;
  R(0, 2) = -c1 * s23 * c4 * c5 + c1 * c23 * s5 - s1 * s4 * c5;
  R(1, 2) = -s1 * s23 * c4 * c5 + s1 * c23 * s5 + c1 * s4 * c5;
  R(2, 2) = c23 * c4 * c5 + s23 * s5;
  T.linear() = R;
  T.translation() << m.A5 * a11 + m.A4 * c1 * c23 + m.A2 * c1 * c2 + m.A1 * c1,
      m.A5 * a21 + m.A4 * s1 * c23 + m.A2 * s1 * c2 + m.A1 * s1,  //
      m.A5 * a31 + m.A4 * s23 + m.A2 * s2;
  return T;
}

std::array<DhRow, kArm5Dof> dh_table(const Arm5Model& m) {
  const double h = std::numbers::pi / 2;
  return {{{0.0, 0.0, m.A1, h}, {0.0, 0.0, m.A2, 0.0}, {-h, 0.0, 0.0, h}, {std::numbers::pi, -m.A4, 0.0, -h}, {h, 0.0, m.A5, h}}};
}

Eigen::Isometry3d dh_forward_kinematics(const Arm5Model& m, const Arm5Vector& q) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const auto rows = dh_table(m);
  for (int i = 0; i < kArm5Dof; ++i) {
    const DhRow& r = rows[static_cast<size_t>(i)];
    T = T * dh_transform(q(i) + r.theta_offset, r.d, r.a, r.alpha);
  }
  return T;
}

namespace {
struct Axes {
  std::array<Eigen::Vector3d, kArm5Dof> axis;
  std::array<Eigen::Vector3d, kArm5Dof> origin;
};

Axes joint_axes(const Arm5Model& m, const Arm5Vector& q) {
  const double c1 = std::cos(q(0)), s1 = std::sin(q(0));
  const double c2 = std::cos(q(1)), s2 = std::sin(q(1));
  const double c23 = std::cos(q(1) + q(2)), s23 = std::sin(q(1) + q(2));
  const double c4 = std::cos(q(3)), s4 = std::sin(q(3));
  const Eigen::Vector3d xF(c1 * c23, s1 * c23, s23);   // forearm axis
  const Eigen::Vector3d yF(-s1, c1, 0.0);
  const Eigen::Vector3d zF(-c1 * s23, -s1 * s23, c23);
  Axes a;
  a.axis[0] = Eigen::Vector3d::UnitZ();
  a.axis[1] = -yF;
  a.axis[2] = -yF;
  a.axis[3] = -xF;
  a.axis[4] = c4 * yF - s4 * zF;  // y after the forearm roll
  a.origin[0] = Eigen::Vector3d::Zero();
  a.origin[1] = m.A1 * Eigen::Vector3d(c1, s1, 0.0);
  a.origin[2] = a.origin[1] + m.A2 * Eigen::Vector3d(c1 * c2, s1 * c2, s2);
  a.origin[3] = a.origin[2] + m.A4 * xF;
  a.origin[4] = a.origin[3];
  return a;
}
}  // namespace

std::array<Eigen::Vector3d, 4> arm_points(const Arm5Model& m, const Arm5Vector& q) {
  const Axes a = joint_axes(m, q);
  return {a.origin[1], a.origin[2], a.origin[3], forward_kinematics(m, q).translation()};
}

Arm5Jacobian jacobian(const Arm5Model& m, const Arm5Vector& q) {
  const Axes a = joint_axes(m, q);
  const Eigen::Vector3d p = forward_kinematics(m, q).translation();
  Arm5Jacobian J;
  for (int i = 0; i < kArm5Dof; ++i) {
    const auto k = static_cast<size_t>(i);
    J.block<3, 1>(0, i) = a.axis[k].cross(p - a.origin[k]);
    J.block<3, 1>(3, i) = a.axis[k];
  }
  return J;
}

double tool_pitch(const Eigen::Isometry3d& T_A_E) {
  return std::asin(std::clamp(T_A_E.linear()(2, 0), -1.0, 1.0));
}

const char* to_string(IkStatus s) {
  switch (s) {
    case IkStatus::kConverged:
      return "converged";
    case IkStatus::kUnreachable:
      return "unreachable (nearest pose returned)";
    case IkStatus::kInvalidInput:
      return "invalid input";
  }
  return "?";
}

IkResult inverse_kinematics(const Arm5Model& model, const Arm5Target& target, const Arm5Vector& q_seed,
                            const IkOptions& options) {
  if (!target.p_A_E.allFinite() || !std::isfinite(target.tool_pitch) || !std::isfinite(target.wrist_roll) ||
      !q_seed.allFinite() || validate(model)) {
    IkResult r;
    r.q = clamp_to_limits(model, q_seed);
    r.status = IkStatus::kInvalidInput;
    return r;
  }
  Arm5Target t = target;
  t.tool_pitch = std::clamp(t.tool_pitch, -std::numbers::pi / 2, std::numbers::pi / 2);
  const auto score = [&](const IkResult& r) {
    return r.position_error_m * r.position_error_m + std::pow(options.pitch_weight_m * r.pitch_error_rad, 2) +
           std::pow(options.roll_weight_m * r.roll_error_rad, 2);
  };
  // Seeds in order of likelihood; the first that converges wins, else the
  // best local minimum (the nearest pose found).
  const Arm5Vector mid = 0.5 * (model.q_min + model.q_max);
  Arm5Vector seeds[5] = {analytic_seed(model, t, true), analytic_seed(model, t, false), q_seed, mid, mid};
  seeds[4](1) = model.q_max(1);
  seeds[4](2) = model.q_max(2);
  IkResult best;
  bool have = false;
  for (const Arm5Vector& s : seeds) {
    IkResult r = solve_from(model, t, s, options);
    if (!have || r.status == IkStatus::kConverged || score(r) < score(best)) {
      best = r;
      have = true;
    }
    if (best.status == IkStatus::kConverged) break;
  }
  // Still stuck (a limit between the seeds and the solution): a coarse grid
  // of postures facing the target.
  const double yaw = std::atan2(t.p_A_E.y(), t.p_A_E.x());
  for (int k = 0; k < 16 && best.status != IkStatus::kConverged; ++k) {
    Arm5Vector g;
    g << yaw, (k & 1) ? 1.2 : 0.2, (k & 2) ? -1.9 : -0.6, t.wrist_roll, (k & 4) ? 1.0 : -1.0;
    if (k & 8) g(4) = 0.0;
    IkResult r = solve_from(model, t, g, options);
    if (r.status == IkStatus::kConverged || score(r) < score(best)) best = r;
  }
  // A clamped target pitch is not the commanded one.
  if (t.tool_pitch != target.tool_pitch) best.status = IkStatus::kUnreachable;
  return best;
}

Arm5Vector damped_rates(const Arm5Model& model, const Arm5Vector& q, const Eigen::Vector3d& v_A, double lambda) {
  if (!q.allFinite() || !v_A.allFinite() || !(lambda > 0)) return Arm5Vector::Zero();
  const Eigen::Matrix<double, 3, 5> Jv = jacobian(model, q).topRows<3>();
  const Eigen::Matrix3d A = Jv * Jv.transpose() + lambda * lambda * Eigen::Matrix3d::Identity();
  return Jv.transpose() * A.ldlt().solve(v_A);
}

}  // namespace hemm::kinematics
