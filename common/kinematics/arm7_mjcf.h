// MJCF (MuJoCo XML) text for an Arm7Model: the chain of seven bodies with
// hinge joints, the model's inertial data, optional capsule collision geoms,
// and sites at the elbow (J4) and the flange (J7). Pure text composition (no
// MuJoCo here): the SIMULATED plant of the bimanual device builds its scene
// from it, and the kinematics tests load it into MuJoCo as the independent
// reference for Arm7's kinematics and dynamics. The caller wraps the chain in
// the body that places frame A, inside a model with <compiler angle="radian"/>.
#pragma once

#include <string>

#include "common/kinematics/arm7.h"

namespace hemm::kinematics {

struct Arm7MjcfOptions {
  std::string prefix;  // bodies <prefix>link1..7, joints <prefix>j1..7, sites <prefix>elbow, <prefix>flange
  Arm7Vector damping = Arm7Vector::Zero();       // viscous joint friction [N m s/rad]
  Arm7Vector frictionloss = Arm7Vector::Zero();  // Coulomb joint friction [N m]
  bool limited = true;                           // joint ranges from q_min/q_max
  // MuJoCo's friction loss is a soft constraint; these make it stick (a
  // brake must hold, not creep). Empty: MuJoCo's defaults.
  std::string solreffriction;
  std::string solimpfriction;
  // > 0: a capsule of this radius from each joint origin to the next (link 7:
  // a short capsule behind the flange). 0: no geom on that link.
  Arm7Vector link_radius = Arm7Vector::Zero();
  int contype = 0;
  int conaffinity = 0;
  double margin = 0.0;  // geom margin with an equal gap: pairs closer are reported, not pushed apart
  std::string rgba = "0.85 0.85 0.9 1";
  std::string flange_children;  // extra MJCF placed inside the link-7 body
};

std::string arm7_mjcf_chain(const Arm7Model& model, const Arm7MjcfOptions& options);

// "%.17g" of each value separated by spaces: numbers that read back exactly.
std::string mjcf_numbers(std::initializer_list<double> values);

}  // namespace hemm::kinematics
