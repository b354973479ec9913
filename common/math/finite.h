// Whether a 3-vector's components are all finite: an Eigen vector or a
// message with x(), y(), z() (proto::Vec3), so that checks of decoded input
// need no proto here.
#pragma once

#include <cmath>

namespace hemm::math {

template <class Vec3>
bool finite3(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

}  // namespace hemm::math
