#pragma once
// Frames and rigid transforms. Naming follows the HEMM paper: T_A_B maps
// points of frame B into frame A (p_A = T_A_B * p_B). SI units, radians.
#include <cmath>
#include <numbers>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hemm::math {

// Wraps an angle to (-pi, pi].
inline double wrap_angle(double a) {
  if (!std::isfinite(a)) return a;
  a = std::remainder(a, 2.0 * std::numbers::pi);  // [-pi, pi]
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

// Planar pose (x, y, theta): an element of SE(2). As T_A_B it maps points of
// B into A: p_A = R(theta) p_B + (x, y).
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;
};

inline bool is_finite(const Pose2& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.theta);
}

inline Eigen::Matrix2d rotation2(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

inline Eigen::Vector2d translation(const Pose2& T) { return {T.x, T.y}; }

// p_A = T_A_B * p_B
inline Eigen::Vector2d apply(const Pose2& T_A_B, const Eigen::Vector2d& p_B) {
  const double c = std::cos(T_A_B.theta), s = std::sin(T_A_B.theta);
  return {c * p_B.x() - s * p_B.y() + T_A_B.x, s * p_B.x() + c * p_B.y() + T_A_B.y};
}

// Rotates a free vector (no translation), e.g. a force or a normal.
inline Eigen::Vector2d rotate(const Pose2& T_A_B, const Eigen::Vector2d& v_B) {
  const double c = std::cos(T_A_B.theta), s = std::sin(T_A_B.theta);
  return {c * v_B.x() - s * v_B.y(), s * v_B.x() + c * v_B.y()};
}

// T_A_C = T_A_B * T_B_C
inline Pose2 compose(const Pose2& T_A_B, const Pose2& T_B_C) {
  const Eigen::Vector2d t = apply(T_A_B, translation(T_B_C));
  return {t.x(), t.y(), wrap_angle(T_A_B.theta + T_B_C.theta)};
}

// T_B_A from T_A_B.
inline Pose2 inverse(const Pose2& T_A_B) {
  const double c = std::cos(T_A_B.theta), s = std::sin(T_A_B.theta);
  return {-(c * T_A_B.x + s * T_A_B.y), -(-s * T_A_B.x + c * T_A_B.y), wrap_angle(-T_A_B.theta)};
}

// SE(2) as a planar rigid motion in SE(3): rotation about z, no z offset.
inline Eigen::Isometry3d to_isometry3(const Pose2& T) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(T.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  out.translation() = Eigen::Vector3d(T.x, T.y, 0.0);
  return out;
}

inline Eigen::Isometry2d to_isometry2(const Pose2& T) {
  Eigen::Isometry2d out = Eigen::Isometry2d::Identity();
  out.linear() = rotation2(T.theta);
  out.translation() = translation(T);
  return out;
}

// Projects an SE(3) transform onto the plane: keeps x, y and the yaw of the
// rotated x axis (exact when the rotation is about z).
inline Pose2 to_pose2(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d x_axis = T.linear().col(0);
  return {T.translation().x(), T.translation().y(), std::atan2(x_axis.y(), x_axis.x())};
}

// Builds T_A_B from a rotation and a translation.
inline Eigen::Isometry3d make_transform(const Eigen::Matrix3d& R_A_B, const Eigen::Vector3d& t_A_B) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = R_A_B;
  out.translation() = t_A_B;
  return out;
}

// Inverse of a rigid transform without a general matrix inverse.
inline Eigen::Isometry3d inverse(const Eigen::Isometry3d& T_A_B) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = T_A_B.linear().transpose();
  out.translation() = -(out.linear() * T_A_B.translation());
  return out;
}

// A point of frame R (3D, z up) placed in W through a planar robot pose.
inline Eigen::Vector3d apply(const Pose2& T_W_R, const Eigen::Vector3d& p_R) {
  const Eigen::Vector2d xy = apply(T_W_R, Eigen::Vector2d(p_R.x(), p_R.y()));
  return {xy.x(), xy.y(), p_R.z()};
}

inline Eigen::Vector3d rotate(const Pose2& T_W_R, const Eigen::Vector3d& v_R) {
  const Eigen::Vector2d xy = rotate(T_W_R, Eigen::Vector2d(v_R.x(), v_R.y()));
  return {xy.x(), xy.y(), v_R.z()};
}

}  // namespace hemm::math
