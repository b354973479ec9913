#include "common/view/primitives.h"

namespace hemm::view {

void PrimitiveList::box(const Eigen::Vector3d& centre, double yaw, const Eigen::Vector3d& half, Rgba c) {
  box(centre, Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix(), half, c);
}

void PrimitiveList::box(const Eigen::Vector3d& centre, const Eigen::Matrix3d& R, const Eigen::Vector3d& half, Rgba c) {
  Primitive p;
  p.shape = Shape::kBox;
  p.pos = centre;
  p.R = R;
  p.size = half;
  p.rgba = c;
  items_.push_back(p);
}

void PrimitiveList::sphere(const Eigen::Vector3d& centre, double radius, Rgba c) {
  box(centre, 0.0, Eigen::Vector3d(radius, radius, radius), c);
  items_.back().shape = Shape::kSphere;
}

void PrimitiveList::cylinder(const Eigen::Vector3d& centre, double radius, double half_height, Rgba c) {
  box(centre, 0.0, Eigen::Vector3d(radius, radius, half_height), c);
  items_.back().shape = Shape::kCylinder;
}

void PrimitiveList::connector(Shape shape, const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width,
                              Rgba c) {
  Primitive p;
  p.shape = shape;
  p.pos = from;
  p.to = to;
  p.width = width;
  p.rgba = c;
  items_.push_back(p);
}

void PrimitiveList::arrow(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width, Rgba c) {
  if ((to - from).norm() < 1e-9) return;
  connector(Shape::kArrow, from, to, width, c);
}

void PrimitiveList::capsule(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius, Rgba c) {
  if ((to - from).norm() < 1e-9) return sphere(from, radius, c);
  connector(Shape::kCapsule, from, to, radius, c);
}

void PrimitiveList::line(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width_px, Rgba c) {
  connector(Shape::kLine, from, to, width_px, c);
}

}  // namespace hemm::view
