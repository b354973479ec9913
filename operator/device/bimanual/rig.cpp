#include "operator/device/bimanual/rig.h"

#include <cmath>
#include <numbers>

namespace hemm::device::bimanual {

namespace hk = hemm::kinematics;

const char* to_string(ArmSide s) { return s == ArmSide::kRight ? "right" : "left"; }

hk::Arm7Vector mirror_posture(const hk::Arm7Vector& q) {
  hk::Arm7Vector s;
  s << -1, 1, -1, 1, -1, 1, -1;
  return s.cwiseProduct(q);
}

Eigen::Isometry3d mirror_mount(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d M = Eigen::Vector3d(1, -1, 1).asDiagonal();  // y -> -y in D
  const Eigen::Matrix3d S = Eigen::Vector3d(1, -1, 1).asDiagonal();  // y_A -> -y_A
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = M * T.linear() * S;
  out.translation() = M * T.translation();
  return out;
}

hk::Arm7Vector RigGeometry::home(ArmSide s) const {
  return s == ArmSide::kRight ? home_right : mirror_posture(home_right);
}

RigGeometry default_rig() {
  RigGeometry r;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = Eigen::Vector3d::UnitX();
  T.linear().col(1) = Eigen::Vector3d::UnitZ();
  T.linear().col(2) = -Eigen::Vector3d::UnitY();
  T.linear() = T.linear() * Eigen::AngleAxisd(std::numbers::pi / 4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() << 0.0, -0.10, 0.55;
  r.T_D_A[0] = T;
  r.T_D_A[1] = mirror_mount(T);
  r.table.min_D << -1.0, -1.0, -0.04;
  r.table.max_D << 0.30, 1.0, 0.0;
  r.column.min_D << -0.08, -0.10, 0.0;
  r.column.max_D << 0.08, 0.10, 0.75;
  r.link_radius << 0.065, 0.065, 0.065, 0.065, 0.055, 0.05, 0.045;
  r.home_right << 0.0, 1.26, -0.57, -1.38, 0.68, -0.82, 1.68;
  return r;
}

std::optional<std::string> validate(const RigGeometry& r) {
  if (auto e = hk::validate(r.arm)) return "arm: " + *e;
  for (int a = 0; a < kArms; ++a) {
    const Eigen::Isometry3d& T = r.T_D_A[static_cast<std::size_t>(a)];
    if (!T.matrix().allFinite() || std::abs(T.linear().determinant() - 1.0) > 1e-9 ||
        !(T.linear().transpose() * T.linear()).isIdentity(1e-9))
      return std::string(to_string(static_cast<ArmSide>(a))) + " mount must be a finite rigid transform";
  }
  for (const Box* b : {&r.table, &r.column}) {
    if (!b->min_D.allFinite() || !b->max_D.allFinite() || !(b->min_D.array() < b->max_D.array()).all())
      return "table and column boxes must be finite with min < max";
  }
  if (!r.link_radius.allFinite() || !(r.link_radius.array() > 0.0).all() || (r.link_radius.array() > 0.3).any())
    return "link radii must be in (0, 0.3] m";
  if (!r.gravity_D.allFinite()) return "gravity must be finite";
  for (ArmSide s : {ArmSide::kRight, ArmSide::kLeft}) {
    if (!hk::within_limits(r.arm, r.home(s))) return "home posture outside the joint limits";
  }
  return std::nullopt;
}

}  // namespace hemm::device::bimanual
