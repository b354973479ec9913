// The RayCaster of the SIMULATED sensors: MuJoCo's mj_ray against every geom
// except the robot's own (geom group 3 in robot.xml). Includes MuJoCo: only
// for .cpp files of the simulation and its tests, never a public header.
#pragma once

#include <mujoco/mujoco.h>

#include <array>

#include "robot_side/sim/range_sensors.h"

namespace hemm::robot {

inline constexpr int kRobotGeomGroup = 3;  // robot.xml puts every robot geom here

class MujocoRayCaster final : public RayCaster {
 public:
  MujocoRayCaster(const mjModel* m, const mjData* d) : m_(m), d_(d) {
    for (int i = 0; i < mjNGROUP; ++i) groups_[static_cast<size_t>(i)] = i == kRobotGeomGroup ? 0 : 1;
  }
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& dir) const override {
    int geom = -1;
    const mjtNum pnt[3] = {o.x(), o.y(), o.z()};
    const mjtNum vec[3] = {dir.x(), dir.y(), dir.z()};
    return mj_ray(m_, d_, pnt, vec, groups_.data(), 1, -1, &geom);
  }

 private:
  const mjModel* m_;
  const mjData* d_;
  std::array<mjtByte, mjNGROUP> groups_{};
};

}  // namespace hemm::robot
