#include "common/mapping/grasp_estimate.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "common/haptics/held_object.h"

namespace hemm::mapping {

namespace grasp_detail {

using Phi = Eigen::Matrix<double, 6, 10>;
using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

bool rotation_ok(const Eigen::Matrix3d& R) {
  return R.isUnitary(1e-6) && R.determinant() > 0;
}

GraspSampleResult check(const GraspEstimator& e, const GraspSample& s) {
  if (!s.T_A_G.matrix().allFinite() || !s.v_A.allFinite() || !s.omega_A.allFinite() || !s.force_A.allFinite() ||
      !s.torque_A.allFinite()) {
    return GraspSampleResult::kNonFinite;
  }
  if (!rotation_ok(s.T_A_G.linear())) return GraspSampleResult::kNotRotation;
  if (e.has_previous && s.stamp_ns <= e.previous_stamp_ns) return GraspSampleResult::kNotMonotonic;
  return GraspSampleResult::kUsed;
}

// Static enough for gravity alone? Keeps the sample as the next one's previous.
GraspSampleResult static_check(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s) {
  const bool had = e->has_previous;
  const double gap = 1e-9 * static_cast<double>(s.stamp_ns - e->previous_stamp_ns);
  const Eigen::Vector3d dv = s.v_A - e->previous_v_A, dw = s.omega_A - e->previous_omega_A;
  e->has_previous = true;
  e->previous_stamp_ns = s.stamp_ns;
  e->previous_v_A = s.v_A;
  e->previous_omega_A = s.omega_A;
  if (!had || gap > p.max_sample_gap_s) return GraspSampleResult::kNoAcceleration;
  if (s.v_A.norm() > p.max_speed || s.omega_A.norm() > p.max_angular_speed || dv.norm() > p.max_acceleration * gap ||
      dw.norm() > p.max_angular_acceleration * gap) {
    ++e->moving;
    return GraspSampleResult::kMoving;
  }
  return GraspSampleResult::kUsed;
}

// The Kalman form of RLS with a 6-row measurement (Joseph update, keeps P symmetric).
GraspSampleResult update(const GraspEstimateParams& p, GraspEstimator* e, const Phi& H, const Vector6& y,
                         bool gate) {
  Matrix6 R = Matrix6::Zero();
  R.diagonal() << Eigen::Vector3d::Constant(p.force_sigma_n * p.force_sigma_n),
      Eigen::Vector3d::Constant(p.torque_sigma_nm * p.torque_sigma_nm);
  const Vector6 innovation = y - H * e->theta;
  const Matrix6 S = H * e->P * H.transpose() + R;
  const Eigen::LLT<Matrix6> llt(S);
  if (llt.info() != Eigen::Success) return GraspSampleResult::kNonFinite;
  if (gate && p.gate_chi2 > 0 && e->used >= static_cast<std::uint64_t>(p.min_samples_for_gate) &&
      innovation.dot(llt.solve(innovation)) > p.gate_chi2) {
    ++e->outliers;
    return GraspSampleResult::kOutlier;
  }
  const Eigen::Matrix<double, 10, 6> K = llt.solve(H * e->P).transpose();
  const GraspMatrix IKH = GraspMatrix::Identity() - K * H;
  e->theta += K * innovation;
  e->P = IKH * e->P * IKH.transpose() + K * R * K.transpose();
  ++e->used;
  return GraspSampleResult::kUsed;
}

void measurement(const GraspEstimateParams& p, const GraspSample& s, bool tare, Phi* H, Vector6* y) {
  const Eigen::Matrix3d Rt = s.T_A_G.linear().transpose();
  const Eigen::Vector3d g_G = Rt * p.gravity_A;
  H->setZero();
  if (!tare) {
    H->block<3, 1>(0, 0) = g_G;
    for (int k = 0; k < 3; ++k) H->block<3, 1>(3, 1 + k) = -g_G.cross(Eigen::Vector3d::Unit(k));  // -[g_G]x
  }
  H->block<3, 3>(0, 4).setIdentity();
  H->block<3, 3>(3, 7).setIdentity();
  y->head<3>() = Rt * s.force_A;
  y->tail<3>() = Rt * s.torque_A;
}

GraspSampleResult add(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s, bool tare) {
  if (const GraspSampleResult r = check(*e, s); r != GraspSampleResult::kUsed) {
    ++e->refused;
    return r;
  }
  if (const GraspSampleResult r = static_check(p, e, s); r != GraspSampleResult::kUsed) return r;
  Phi H;
  Vector6 y;
  measurement(p, s, tare, &H, &y);
  return update(p, e, H, y, !tare);
}

}  // namespace grasp_detail

const char* to_string(GraspSampleResult r) {
  switch (r) {
    case GraspSampleResult::kUsed: return "used";
    case GraspSampleResult::kNonFinite: return "non-finite sample";
    case GraspSampleResult::kNotRotation: return "grasp frame rotation not orthonormal";
    case GraspSampleResult::kNotMonotonic: return "stamp not after the previous sample";
    case GraspSampleResult::kNoAcceleration: return "no previous sample to tell the acceleration";
    case GraspSampleResult::kMoving: return "grasp frame moving or accelerating";
    case GraspSampleResult::kOutlier: return "wrench beyond the innovation gate";
  }
  return "unknown";
}

std::optional<std::string> validate(const GraspEstimateParams& p) {
  if (!p.gravity_A.allFinite() || !(p.gravity_A.norm() > 0)) return "grasp estimate: gravity must be finite, non-zero";
  for (double v : {p.force_sigma_n, p.torque_sigma_nm, p.prior_mass_sigma_kg, p.prior_moment_sigma_kgm, p.max_speed,
                   p.max_angular_speed, p.max_acceleration, p.max_angular_acceleration, p.max_sample_gap_s}) {
    if (!std::isfinite(v) || !(v > 0)) return "grasp estimate: sigmas and thresholds must be positive";
  }
  for (double v : {p.prior_force_bias_sigma_n, p.prior_torque_bias_sigma_nm, p.gate_chi2}) {
    if (!std::isfinite(v) || v < 0) return "grasp estimate: bias sigmas and gate must be >= 0";
  }
  if (p.min_samples_for_gate < 0) return "grasp estimate: min_samples_for_gate must be >= 0";
  return std::nullopt;
}

GraspEstimator make_grasp_estimator(const GraspEstimateParams& p) {
  GraspEstimator e;
  e.P.diagonal() << p.prior_mass_sigma_kg * p.prior_mass_sigma_kg,
      Eigen::Vector3d::Constant(p.prior_moment_sigma_kgm * p.prior_moment_sigma_kgm),
      Eigen::Vector3d::Constant(p.prior_force_bias_sigma_n * p.prior_force_bias_sigma_n),
      Eigen::Vector3d::Constant(p.prior_torque_bias_sigma_nm * p.prior_torque_bias_sigma_nm);
  return e;
}

GraspSampleResult add_grasp_sample(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s) {
  return grasp_detail::add(p, e, s, false);
}

GraspSampleResult add_tare_sample(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s) {
  return grasp_detail::add(p, e, s, true);
}

GraspEstimate current_estimate(const GraspEstimator& e) {
  GraspEstimate out;
  out.mass_kg = e.theta(0);
  out.mass_variance = e.P(0, 0);
  out.force_bias_G = e.theta.segment<3>(4);
  out.torque_bias_G = e.theta.segment<3>(7);
  out.samples = e.used;
  const double m = e.theta(0);
  out.valid = m > 0 && m * m > 4 * e.P(0, 0);
  if (std::abs(m) > 1e-9) {
    const Eigen::Vector3d h = e.theta.segment<3>(1);
    out.com_G = h / m;
    // c = h / m: dc/dm = -h / m^2, dc/dh = I / m.
    Eigen::Matrix<double, 3, 4> J;
    J.col(0) = -h / (m * m);
    J.rightCols<3>() = Eigen::Matrix3d::Identity() / m;
    out.com_covariance = J * e.P.topLeftCorner<4, 4>() * J.transpose();
  }
  return out;
}

mesh::MassProperties body_from_estimate(const GraspEstimate& e, const Eigen::Vector3d& size) {
  mesh::MassProperties b;
  b.mass = e.mass_kg;
  b.volume = size.prod();
  b.centre_of_mass = e.com_G;
  b.inertia_com = haptics::solid_box_inertia(e.mass_kg, size);
  return b;
}

}  // namespace hemm::mapping
