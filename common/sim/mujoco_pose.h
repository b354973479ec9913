// A MuJoCo frame (xpos / xmat, site_xpos / site_xmat, geom_xpos / geom_xmat
// of one body, site or geom: 3 positions and a row-major 3x3) as a pose.
// mjtNum is double in MuJoCo 2.2.2; mujoco.h stays out of this header.
#pragma once

#include <Eigen/Geometry>

namespace hemm::sim {

inline Eigen::Isometry3d mujoco_pose(const double* pos, const double* mat) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << pos[0], pos[1], pos[2];
  T.linear() << mat[0], mat[1], mat[2], mat[3], mat[4], mat[5], mat[6], mat[7], mat[8];
  return T;
}

}  // namespace hemm::sim
