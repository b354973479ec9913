#include "common/mapping/contact_correction.h"

#include <cmath>
#include <limits>

namespace hemm::mapping {

namespace correction_detail {

bool rotation_ok(const Eigen::Matrix3d& R) {
  return R.isUnitary(1e-6) && R.determinant() > 0;
}

// A residual at the stored distance limit says only "at least this far".
bool saturated(const vps::Voxmap& vm, double r) {
  return r >= 0.999 * vm.far_outside_sdf() || r <= 0.999 * vm.far_inside_sdf();
}

// One scalar observation n . o_true = n . o + r.
void observe_along(const ContactCorrectionParams& p, const vps::Voxmap& vm, const Eigen::Vector3d& n, double r,
                   ContactCorrection* c) {
  if (saturated(vm, r)) {
    c->offset_A += r * n;
  } else {
    // The gain along n only: n is measured (f^, noisy by a few degrees), and
    // a full Kalman gain P n / S would leak the residual sideways through it
    // once P is small along n and still wide across. Joseph form for that gain.
    const double var = p.measurement_sigma_m * p.measurement_sigma_m;
    const double Pnn = n.dot(c->P * n);
    const Eigen::Vector3d K = (Pnn / (Pnn + var)) * n;
    c->offset_A += K * r;
    const Eigen::Matrix3d IKH = Eigen::Matrix3d::Identity() - K * n.transpose();
    c->P = IKH * c->P * IKH.transpose() + var * K * K.transpose();
  }
  const double len = c->offset_A.norm();
  if (len > p.max_offset_m) c->offset_A *= p.max_offset_m / len;
  c->last_normal_A = n;
  c->last_residual_m = r;
}

}  // namespace correction_detail

const char* to_string(ContactObservation o) {
  switch (o) {
    case ContactObservation::kNone: return "none";
    case ContactObservation::kRobotContact: return "robot contact located";
    case ContactObservation::kModelTooDeep: return "model penetrates where the robot is free";
    case ContactObservation::kNoSingleContact: return "line of action misses the gripper";
    case ContactObservation::kNonFinite: return "non-finite sample";
    case ContactObservation::kNotRotation: return "grasp frame rotation not orthonormal";
    case ContactObservation::kNotMonotonic: return "stamp not after the previous sample";
  }
  return "unknown";
}

std::optional<std::string> validate(const ContactCorrectionParams& p) {
  for (double v : {p.contact_force_n, p.free_force_n, p.line_tolerance_m, p.deep_penetration_m, p.measurement_sigma_m,
                   p.prior_sigma_m, p.max_offset_m, p.slew_m_per_s}) {
    if (!std::isfinite(v) || !(v > 0)) return "contact correction: thresholds, sigmas and limits must be positive";
  }
  if (!(p.free_force_n < p.contact_force_n)) return "contact correction: free_force_n must be below contact_force_n";
  if (!std::isfinite(p.drift_sigma_m_per_sqrt_s) || p.drift_sigma_m_per_sqrt_s < 0) {
    return "contact correction: drift sigma must be >= 0";
  }
  if (!std::isfinite(p.min_normal_cos) || p.min_normal_cos < -1 || p.min_normal_cos > 1) {
    return "contact correction: min_normal_cos must be in [-1, 1]";
  }
  if (p.persistence < 1) return "contact correction: persistence must be >= 1";
  return std::nullopt;
}

ContactCorrection make_contact_correction(const ContactCorrectionParams& p) {
  ContactCorrection c;
  c.P = Eigen::Matrix3d::Identity() * p.prior_sigma_m * p.prior_sigma_m;
  return c;
}

double corrected_sdf(const CorrectedVoxmap& map, const Eigen::Vector3d& offset_A, const Eigen::Vector3d& x_A) {
  const Eigen::Vector3d d = x_A - offset_A - map.T_A_V.translation();
  return vps::sdf_hermite(*map.voxmap, map.T_A_V.linear().transpose() * d);
}

ContactObservation observe_contact(const ContactCorrectionParams& p, const CorrectedVoxmap& map,
                                   const vps::PointShell& gripper_G, const ContactSample& s, ContactCorrection* c) {
  using namespace correction_detail;
  if (!s.T_A_G.matrix().allFinite() || !s.force_A.allFinite() || !s.torque_A.allFinite()) {
    ++c->refused;
    return ContactObservation::kNonFinite;
  }
  if (!rotation_ok(s.T_A_G.linear())) {
    ++c->refused;
    return ContactObservation::kNotRotation;
  }
  if (c->has_stamp && s.stamp_ns <= c->last_stamp_ns) {
    ++c->refused;
    return ContactObservation::kNotMonotonic;
  }
  if (c->has_stamp) {
    const double dt = 1e-9 * static_cast<double>(s.stamp_ns - c->last_stamp_ns);
    c->P.diagonal().array() += p.drift_sigma_m_per_sqrt_s * p.drift_sigma_m_per_sqrt_s * dt;
  }
  c->has_stamp = true;
  c->last_stamp_ns = s.stamp_ns;

  const double f = s.force_A.norm();
  c->contact_run = f > p.contact_force_n ? c->contact_run + 1 : 0;
  c->free_run = f < p.free_force_n ? c->free_run + 1 : 0;
  const vps::Voxmap& vm = *map.voxmap;
  const Eigen::Matrix3d& R = s.T_A_G.linear();
  const Eigen::Vector3d& p_G = s.T_A_G.translation();

  if (c->contact_run >= p.persistence) {
    // The line of action: through p_G + (f x t) / |f|^2, along f^.
    const Eigen::Vector3d fhat = s.force_A / f;
    const Eigen::Vector3d p0 = p_G + s.force_A.cross(s.torque_A) / (f * f);
    // Among the gripper points near the line that face the push, the contact
    // is the one reaching furthest along -f^ (the support point towards the
    // surface): the line itself is only known to a few millimetres at the
    // fingers (f^'s noise times the lever from G), and the nearest point to
    // it would sit up the fingertip's side, biasing the surface outwards.
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < gripper_G.size(); ++i) {
      if ((R * gripper_G.normal(i)).dot(fhat) < p.min_normal_cos) continue;
      const Eigen::Vector3d x = s.T_A_G * gripper_G.point(i);
      const Eigen::Vector3d d = x - p0;
      if ((d - d.dot(fhat) * fhat).norm() > p.line_tolerance_m) continue;
      const double reach = x.dot(fhat);
      if (reach < best) {
        best = reach;
        point = x;
      }
    }
    if (!std::isfinite(best)) {
      ++c->skipped;
      return ContactObservation::kNoSingleContact;
    }
    observe_along(p, vm, fhat, corrected_sdf(map, c->offset_A, point), c);
    c->last_point_A = point;
    ++c->robot_contacts;
    return ContactObservation::kRobotContact;
  }

  if (c->free_run >= p.persistence) {
    double deepest = std::numeric_limits<double>::infinity();
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < gripper_G.size(); ++i) {
      const Eigen::Vector3d x = s.T_A_G * gripper_G.point(i);
      const double d = corrected_sdf(map, c->offset_A, x);
      if (d < deepest) {
        deepest = d;
        point = x;
      }
    }
    if (-deepest > p.deep_penetration_m) {
      const Eigen::Vector3d x_V =
          map.T_A_V.linear().transpose() * (point - c->offset_A - map.T_A_V.translation());
      const Eigen::Vector3d g = map.T_A_V.linear() * vps::sdf_gradient(vm, x_V);
      if (g.norm() > 1e-6) {
        observe_along(p, vm, g.normalized(), deepest, c);
        c->last_point_A = point;
        ++c->model_too_deep;
        return ContactObservation::kModelTooDeep;
      }
    }
  }
  return ContactObservation::kNone;
}

Eigen::Vector3d slew_surface_offset(const ContactCorrectionParams& p, const Eigen::Vector3d& target, double dt,
                                    Eigen::Vector3d* applied_A) {
  if (!target.allFinite() || !std::isfinite(dt) || !(dt > 0)) return *applied_A;
  const Eigen::Vector3d d = target - *applied_A;
  const double step = p.slew_m_per_s * dt, len = d.norm();
  if (len <= step) {
    *applied_A = target;
  } else {
    *applied_A += (step / len) * d;
  }
  return *applied_A;
}

}  // namespace hemm::mapping
