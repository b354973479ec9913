#include "common/kinematics/arm7_ik.h"

#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>

namespace hemm::kinematics {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// Rotation vector taking R to R_target, in A.
Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_target, const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R_target * R.transpose());
  return aa.angle() * aa.axis();
}

struct Residual {
  Vector6 e;  // weighted
  double position_error = 0.0;
  double orientation_error = 0.0;
  double cost() const { return e.squaredNorm(); }
};

Residual residual(const Arm7Model& m, const Eigen::Isometry3d& T_t, const Arm7Vector& q, const Arm7IkOptions& o,
                  Arm7Frames& f) {
  forward_kinematics(m, q, f);
  const Eigen::Isometry3d& T = f.joint(kArm7Flange);
  Residual r;
  const Eigen::Vector3d ep = T_t.translation() - T.translation();
  const Eigen::Vector3d er = rotation_error(T_t.linear(), T.linear());
  r.e << ep, o.rotation_weight_m * er;
  r.position_error = ep.norm();
  r.orientation_error = er.norm();
  return r;
}

}  // namespace

Arm7IkResult inverse_kinematics(const Arm7Model& m, const Eigen::Isometry3d& T_t, const Arm7Vector& q_seed,
                                const Arm7IkOptions& o) {
  Arm7IkResult out;
  out.q = clamp_to_limits(m, q_seed);
  if (!T_t.matrix().allFinite() || !q_seed.allFinite()) return out;
  Arm7Frames f;
  Arm7Vector q = out.q;
  Residual cur = residual(m, T_t, q, o, f);
  double lambda = o.damping;
  int it = 0;
  const auto done = [&](const Residual& r) {
    return r.position_error < o.position_tolerance_m && r.orientation_error < o.orientation_tolerance_rad;
  };
  for (; it < o.max_iterations && !done(cur); ++it) {
    forward_kinematics(m, q, f);
    Arm7Jacobian J = flange_jacobian(m, f);
    J.bottomRows<3>() *= o.rotation_weight_m;
    const Matrix6 JJt = J * J.transpose();
    bool accepted = false;
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      const Matrix6 A = JJt + lambda * lambda * Matrix6::Identity();
      Arm7Vector dq = J.transpose() * A.ldlt().solve(cur.e);
      const double mx = dq.cwiseAbs().maxCoeff();
      if (!(mx < 1e9)) dq.setZero();  // guards NaN too
      if (mx > o.max_step_rad) dq *= o.max_step_rad / mx;
      const Arm7Vector qn = clamp_to_limits(m, q + dq);
      const Residual next = residual(m, T_t, qn, o, f);
      if (next.cost() < cur.cost()) {
        accepted = true;
        q = qn;
        cur = next;
        lambda = std::max(lambda * 0.3, 1e-6);
      } else {
        lambda *= 5.0;
      }
    }
    if (!accepted) break;  // a local minimum (out of reach, or a limit in the way)
  }
  out.q = q;
  out.iterations = it;
  out.position_error_m = cur.position_error;
  out.orientation_error_rad = cur.orientation_error;
  out.converged = done(cur);
  return out;
}

std::vector<Eigen::Quaterniond> sample_orientations(int n) {
  std::vector<Eigen::Quaterniond> out;
  if (n <= 0) return out;
  out.reserve(static_cast<std::size_t>(n));
  const double phi = std::sqrt(2.0);
  const double psi = 1.533751168755204288118041;  // root of psi^4 = psi + 4
  for (int i = 0; i < n; ++i) {
    const double s = i + 0.5;
    const double r = std::sqrt(s / n), R = std::sqrt(1.0 - s / n);
    const double alpha = 2.0 * std::numbers::pi * s / phi, beta = 2.0 * std::numbers::pi * s / psi;
    out.emplace_back(R * std::cos(beta), r * std::sin(alpha), r * std::cos(alpha), R * std::sin(beta));
    out.back().normalize();
  }
  return out;
}

std::vector<Arm7Vector> ik_seed_postures(const Arm7Model& m) {
  std::vector<Arm7Vector> out;
  for (int k = 0; k < 8; ++k) {
    Arm7Vector q = Arm7Vector::Zero();
    q(1) = (k & 1) ? 0.8 : -0.8;
    q(3) = (k & 2) ? 1.4 : -1.4;
    q(5) = (k & 4) ? 0.8 : -0.8;
    out.push_back(clamp_to_limits(m, q));
  }
  return out;
}

ReachabilityResult reachability(const Arm7Model& m, const Eigen::Vector3d& p_A,
                                std::span<const Eigen::Quaterniond> orientations, std::span<const Arm7Vector> seeds,
                                const Arm7IkOptions& o) {
  ReachabilityResult r;
  Arm7Vector warm = Arm7Vector::Zero();
  bool have_warm = false;
  for (const Eigen::Quaterniond& R : orientations) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R.normalized().toRotationMatrix();
    T.translation() = p_A;
    ++r.sampled;
    bool ok = false;
    if (have_warm) {
      const Arm7IkResult s = inverse_kinematics(m, T, warm, o);
      if (s.converged) {
        ok = true;
        warm = s.q;
      }
    }
    for (std::size_t k = 0; k < seeds.size() && !ok; ++k) {
      const Arm7IkResult s = inverse_kinematics(m, T, seeds[k], o);
      if (s.converged) {
        ok = true;
        warm = s.q;
        have_warm = true;
      }
    }
    if (ok) ++r.reached;
  }
  return r;
}

}  // namespace hemm::kinematics
