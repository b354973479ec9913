#include "common/haptics/held_object.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "common/math/frames.h"

namespace hemm::haptics {

namespace held_detail {

using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Vector6 = Eigen::Matrix<double, 6, 1>;

Eigen::Matrix3d skew(const Eigen::Vector3d& r) {
  Eigen::Matrix3d S;
  S << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  return S;
}

// Rotation vector of R_target R^T (the shortest way round).
Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_target, const Eigen::Matrix3d& R) {
  Eigen::Quaterniond e(R_target * R.transpose());
  if (e.w() < 0) e.coeffs() = -e.coeffs();
  const double s = e.vec().norm();
  if (s < 1e-12) return 2.0 * e.vec();
  return (2.0 * std::atan2(s, e.w()) / s) * e.vec();
}

bool finite_pose(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

bool is_rotation(const Eigen::Matrix3d& R) {
  return R.isUnitary(1e-6) && R.determinant() > 0;
}

HeldStatus check_input(const HeldHandInput& h) {
  if (!finite_pose(h.T_A_G) || !h.v_A.allFinite() || !h.omega_A.allFinite()) return HeldStatus::kNonFinite;
  if (!is_rotation(h.T_A_G.linear())) return HeldStatus::kNotRotation;
  return HeldStatus::kOk;
}

Eigen::Vector3d com_A(const HeldObjectModel& m, const HeldObjectData& d) { return d.T_A_O * m.body.centre_of_mass; }

}  // namespace held_detail

HeldCouplingGains gains_from_coupling(const vps::CouplingParams& p) {
  return HeldCouplingGains{p.k_lin, p.b_lin, p.k_rot, p.b_rot, p.linear_damping, p.angular_damping};
}

const char* to_string(HeldStatus s) {
  switch (s) {
    case HeldStatus::kOk: return "ok";
    case HeldStatus::kNotHeld: return "no hand holds the object";
    case HeldStatus::kBadHand: return "hand index out of range";
    case HeldStatus::kNonFinite: return "non-finite pose, twist or wrench";
    case HeldStatus::kNotRotation: return "pose rotation not orthonormal";
    case HeldStatus::kAlreadyHeld: return "that hand already holds the object";
  }
  return "unknown";
}

std::optional<std::string> validate(const HeldObjectModel& m) {
  const mesh::MassProperties& b = m.body;
  if (!std::isfinite(b.mass) || !(b.mass > 0)) return "held object: mass must be positive and finite";
  if (!b.centre_of_mass.allFinite()) return "held object: centre of mass not finite";
  if (!b.inertia_com.allFinite() || (b.inertia_com - b.inertia_com.transpose()).cwiseAbs().maxCoeff() >
                                        1e-9 * std::max(1.0, b.inertia_com.cwiseAbs().maxCoeff())) {
    return "held object: inertia must be finite and symmetric";
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(b.inertia_com);
  if (!(es.eigenvalues().minCoeff() > 0)) return "held object: inertia must be positive definite";
  const HeldCouplingGains& g = m.gains;
  for (double v : {g.k_lin, g.b_lin, g.k_rot, g.b_rot, g.linear_damping, g.angular_damping}) {
    if (!std::isfinite(v) || v < 0) return "held object: coupling gains must be finite and >= 0";
  }
  if (!(g.k_lin > 0)) return "held object: k_lin must be positive";
  if (!std::isfinite(m.dt) || !(m.dt > 0)) return "held object: dt must be positive";
  if (!std::isfinite(m.grip_ramp_s) || !(m.grip_ramp_s > 0)) return "held object: grip_ramp_s must be positive";
  if (!m.gravity_A.allFinite()) return "held object: gravity not finite";
  return std::nullopt;
}

bool held(const HeldObjectData& d) {
  for (const HeldHandState& h : d.hand) {
    if (h.attached) return true;
  }
  return false;
}

Eigen::Isometry3d grasp_frame_here(const HeldObjectData& d, const Eigen::Isometry3d& T_A_G) {
  return math::inverse(d.T_A_O) * T_A_G;
}

HeldStatus grasp(const HeldObjectModel& m, HeldObjectData* d, int hand, const HeldHandInput& in,
                 const Eigen::Isometry3d& T_O_G) {
  using namespace held_detail;
  if (hand < 0 || hand >= kHeldHands) return HeldStatus::kBadHand;
  if (const HeldStatus s = check_input(in); s != HeldStatus::kOk) return s;
  if (!finite_pose(T_O_G)) return HeldStatus::kNonFinite;
  if (!is_rotation(T_O_G.linear())) return HeldStatus::kNotRotation;
  HeldHandState& h = d->hand[static_cast<std::size_t>(hand)];
  if (h.attached && !h.releasing) return HeldStatus::kAlreadyHeld;
  if (!held(*d)) {
    // The first hand: the object sits on it, moving with it; what held it
    // before (the bench) hands the weight over during the ramp.
    d->T_A_O = in.T_A_G * math::inverse(T_O_G);
    const Eigen::Vector3d r = com_A(m, *d) - in.T_A_G.translation();
    d->v_A = in.v_A + in.omega_A.cross(r);
    d->omega_A = in.omega_A;
    d->gravity_scale = 0.0;
    h.weight = 1.0;
  } else if (!h.attached) {
    h.weight = 0.0;
  }
  h.attached = true;
  h.releasing = false;
  h.T_O_G = T_O_G;
  return HeldStatus::kOk;
}

HeldStatus release(HeldObjectData* d, int hand) {
  if (hand < 0 || hand >= kHeldHands) return HeldStatus::kBadHand;
  HeldHandState& h = d->hand[static_cast<std::size_t>(hand)];
  if (!h.attached) return HeldStatus::kNotHeld;
  h.releasing = true;
  return HeldStatus::kOk;
}

HeldStatus step_held_object(const HeldObjectModel& m, HeldObjectData* d,
                            const std::array<HeldHandInput, kHeldHands>& hands, const vps::Wrench* contact,
                            HeldObjectOutput* out) {
  using namespace held_detail;
  *out = HeldObjectOutput{};
  if (!held(*d)) return HeldStatus::kNotHeld;
  for (int i = 0; i < kHeldHands; ++i) {
    if (!d->hand[static_cast<std::size_t>(i)].attached) continue;
    if (const HeldStatus s = check_input(hands[static_cast<std::size_t>(i)]); s != HeldStatus::kOk) return s;
  }
  if (contact != nullptr && (!contact->force.allFinite() || !contact->torque.allFinite())) {
    return HeldStatus::kNonFinite;
  }
  const double dt = m.dt;
  // Ramps: a releasing hand fades out; the carried weight follows whether
  // any hand still means to hold.
  const double step = dt / m.grip_ramp_s;
  bool any_holding = false;
  for (HeldHandState& h : d->hand) {
    if (!h.attached) continue;
    h.weight = h.releasing ? std::max(0.0, h.weight - step) : std::min(1.0, h.weight + step);
    any_holding = any_holding || !h.releasing;
  }
  d->gravity_scale = any_holding ? std::min(1.0, d->gravity_scale + step) : std::max(0.0, d->gravity_scale - step);

  const HeldCouplingGains& g = m.gains;
  const Eigen::Matrix3d R = d->T_A_O.linear();
  const Eigen::Vector3d c = com_A(m, *d);
  const Eigen::Matrix3d I_A = R * m.body.inertia_com * R.transpose();
  Matrix6 M = Matrix6::Zero();
  M.topLeftCorner<3, 3>() = m.body.mass * Eigen::Matrix3d::Identity();
  M.bottomRightCorner<3, 3>() = I_A;
  Matrix6 D = Matrix6::Zero(), K = Matrix6::Zero();
  D.topLeftCorner<3, 3>().diagonal().array() += g.linear_damping;
  D.bottomRightCorner<3, 3>().diagonal().array() += g.angular_damping;
  Vector6 F = Vector6::Zero();
  std::array<Eigen::Matrix<double, 3, 6>, kHeldHands> J;
  std::array<Eigen::Vector3d, kHeldHands> e_lin, e_rot, p_att;
  J.fill(Eigen::Matrix<double, 3, 6>::Zero());
  e_lin.fill(Eigen::Vector3d::Zero());
  e_rot.fill(Eigen::Vector3d::Zero());
  p_att.fill(Eigen::Vector3d::Zero());
  for (int i = 0; i < kHeldHands; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const HeldHandState& h = d->hand[k];
    if (!h.attached || h.weight <= 0.0) continue;
    const HeldHandInput& in = hands[k];
    p_att[k] = d->T_A_O * h.T_O_G.translation();
    const Eigen::Vector3d r = p_att[k] - c;
    J[k].leftCols<3>().setIdentity();
    J[k].rightCols<3>() = -skew(r);
    e_lin[k] = in.T_A_G.translation() - p_att[k];
    e_rot[k] = rotation_error(in.T_A_G.linear(), R * h.T_O_G.linear());
    const Matrix6 JtJ = J[k].transpose() * J[k];
    K += h.weight * g.k_lin * JtJ;
    D += h.weight * g.b_lin * JtJ;
    K.bottomRightCorner<3, 3>().diagonal().array() += h.weight * g.k_rot;
    D.bottomRightCorner<3, 3>().diagonal().array() += h.weight * g.b_rot;
    F += h.weight * J[k].transpose() * (g.k_lin * e_lin[k] + g.b_lin * in.v_A);
    F.tail<3>() += h.weight * (g.k_rot * e_rot[k] + g.b_rot * in.omega_A);
  }
  F.head<3>() += d->gravity_scale * m.body.mass * m.gravity_A;
  if (contact != nullptr) {
    // Torque about O's origin -> about the centre of mass.
    F.head<3>() += contact->force;
    F.tail<3>() += contact->torque + (d->T_A_O.translation() - c).cross(contact->force);
  }
  F.tail<3>() -= d->omega_A.cross(I_A * d->omega_A);
  Vector6 nu;
  nu << d->v_A, d->omega_A;
  const Matrix6 A = M + dt * D + dt * dt * K;
  const Vector6 nu_new = A.llt().solve(M * nu + dt * F);
  const Eigen::Vector3d v_new = nu_new.head<3>(), w_new = nu_new.tail<3>();

  // Each coupling's wrench on the object, as the solve applied it.
  for (int i = 0; i < kHeldHands; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const HeldHandState& h = d->hand[k];
    if (!h.attached || h.weight <= 0.0) continue;
    const HeldHandInput& in = hands[k];
    const Eigen::Vector3d vp = J[k] * nu_new;
    const Eigen::Vector3d f = h.weight * (g.k_lin * (e_lin[k] - dt * vp) + g.b_lin * (in.v_A - vp));
    const Eigen::Vector3d tau = h.weight * (g.k_rot * (e_rot[k] - dt * w_new) + g.b_rot * (in.omega_A - w_new));
    out->on_object[k] = vps::Wrench{f, tau};
    out->on_hand[k] = vps::Wrench{-f, -tau};
  }
  if (d->hand[0].attached && d->hand[1].attached && d->hand[0].weight > 0 && d->hand[1].weight > 0) {
    const Eigen::Vector3d line = p_att[1] - p_att[0];
    const double len = line.norm();
    if (len > 1e-9) {
      out->grasp_line_A = line / len;
      out->squeeze_n = 0.5 * (out->on_object[0].force - out->on_object[1].force).dot(out->grasp_line_A);
    }
  }

  // Advance the pose: the centre of mass, then the orientation about it.
  const Eigen::Vector3d c_new = c + dt * v_new;
  const double angle = w_new.norm() * dt;
  Eigen::Quaterniond q(R);
  if (angle > 0.0) q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, w_new / w_new.norm())) * q;
  q.normalize();
  d->T_A_O.linear() = q.toRotationMatrix();
  d->T_A_O.translation() = c_new - d->T_A_O.linear() * m.body.centre_of_mass;
  d->v_A = v_new;
  d->omega_A = w_new;
  ++d->ticks;
  // Released hands detach once faded out; the object is put down when the
  // last one has and the weight is handed back.
  for (HeldHandState& h : d->hand) {
    if (h.attached && h.releasing && h.weight <= 0.0) h = HeldHandState{};
  }
  return HeldStatus::kOk;
}

double held_stored_energy(const HeldObjectModel& m, const HeldObjectData& d,
                          const std::array<HeldHandInput, kHeldHands>& hands) {
  using namespace held_detail;
  const Eigen::Matrix3d R = d.T_A_O.linear();
  const Eigen::Matrix3d I_A = R * m.body.inertia_com * R.transpose();
  double e = 0.5 * m.body.mass * d.v_A.squaredNorm() + 0.5 * d.omega_A.dot(I_A * d.omega_A);
  e -= d.gravity_scale * m.body.mass * m.gravity_A.dot(com_A(m, d));
  for (int i = 0; i < kHeldHands; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const HeldHandState& h = d.hand[k];
    if (!h.attached) continue;
    const Eigen::Vector3d el = hands[k].T_A_G.translation() - d.T_A_O * h.T_O_G.translation();
    const Eigen::Vector3d er = rotation_error(hands[k].T_A_G.linear(), R * h.T_O_G.linear());
    e += 0.5 * h.weight * (m.gains.k_lin * el.squaredNorm() + m.gains.k_rot * er.squaredNorm());
  }
  return e;
}

Eigen::Matrix3d solid_box_inertia(double mass, const Eigen::Vector3d& s) {
  const Eigen::Vector3d sq = s.cwiseProduct(s);
  return (mass / 12.0) * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y()).asDiagonal();
}

}  // namespace hemm::haptics
