// The SIMULATED bimanual rig as MJCF text for MuJoCo 2.2.2 (paper Fig. 1):
// table, column, two LWR-class arms from arm7_mjcf_chain with capsule
// collision shapes, a handle on each flange (body with the wrist force-torque
// sensor's site, the grip lever's slide joint on the grip-force interface),
// and a free-floating hand per arm (the simulated human; it collides with
// nothing). Pure text composition: the plant (plant.cpp) loads it.
//
// Names: prefix "r_" / "l_"; bodies <p>link1..7, <p>handle, <p>lever (grip
// handle only), <p>hand; joints <p>j1..7, <p>grip, <p>hand_free; sites
// <p>flange, <p>elbow, <p>ft (the sensor frame: at the flange, J7 axes),
// <p>ee (the handle's end-effector frame E); sensors <p>ft_force,
// <p>ft_torque. Collision bits: right arm contype 2 / conaffinity 5, left
// arm 4 / 3, table and column 1 / 6, so an arm never collides with itself
// but does with the other arm and the table. Arm geoms carry a margin with
// an equal gap: MuJoCo reports every arm-arm and arm-table pair closer than
// the margin (with its distance) without acting on it until they touch.
// Links 1-2 are excluded against the world's table and column: link 1 sits
// 3.7 cm from the column by design and neither can reach the table.
#pragma once

#include <array>
#include <string>

#include "common/kinematics/arm7.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/human.h"
#include "operator/device/bimanual/rig.h"

namespace hemm::device::bimanual {

struct SceneSpec {
  RigGeometry rig = default_rig();
  std::array<kinematics::Arm7Model, kArms> arms;   // the plant's (true) arm models
  std::array<HandleSpec, kArms> handles;
  std::array<HumanModel, kArms> humans;
  kinematics::Arm7Vector viscous_friction = kinematics::Arm7Vector::Zero();  // [N m s/rad]
  kinematics::Arm7Vector coulomb_friction = kinematics::Arm7Vector::Zero();  // [N m]
  double timestep_s = 0.0005;
  double proximity_margin_m = 0.15;
};

std::string prefix(ArmSide s);  // "r_" / "l_"
std::string bimanual_scene_mjcf(const SceneSpec& spec);

}  // namespace hemm::device::bimanual
