// The three handles of the bimanual interface (paper Sec. 2.2, Fig. 3), each
// mounted on a flange: the magnetic clutch (a bracket the hand is strapped
// to, held on the flange by magnets up to an attaching force and torque; its
// integrated dead-man switch opens when it comes off), the grip-force
// interface (one extra DoF, a lever under the forefinger with force feedback)
// and the joystick handle (mini-joystick, switch, buttons, dead-man button).
// Which handle an arm carries is configuration. Masses and sizes are ASSUMED
// (the paper gives none): a few hundred grams each.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/kinematics/arm7.h"

namespace hemm::device::bimanual {

enum class HandleKind { kMagneticClutch = 0, kGripForce = 1, kJoystick = 2 };
const char* to_string(HandleKind k);
std::optional<HandleKind> handle_from_string(std::string_view name);  // "magnetic_clutch", "grip_force", "joystick"

// The inputs a handle may have (what a config, a script or a command may ask for).
enum class HandleInput { kClutch, kGrip, kJoystickAxes, kSwitch, kButtons, kDeadman };
const char* to_string(HandleInput i);
bool has_input(HandleKind k, HandleInput i);
// nullptr if the handle has the input, else "the joystick handle has no grip" etc.
std::optional<std::string> require_input(HandleKind k, HandleInput i);

struct HandleSpec {
  HandleKind kind = HandleKind::kMagneticClutch;
  kinematics::RigidBodyInertia inertia_J7;  // the handle's mass, in the flange frame J7
  // The end-effector frame E in J7: where the hand holds it (the point whose
  // pose the device reports and where the rendered wrench acts).
  Eigen::Isometry3d T_J7_E = Eigen::Isometry3d::Identity();
  double capsule_radius = 0.04;  // collision shape: a capsule along z7 from the flange
  double capsule_length = 0.12;
  // Magnetic clutch: beyond these the bracket comes off the flange.
  double clutch_force_limit = 0.0;   // [N]
  double clutch_torque_limit = 0.0;  // [N m]
  // Grip-force interface: lever travel and the largest force it renders.
  double grip_travel = 0.0;     // [m]
  double grip_max_force = 0.0;  // [N]
  double grip_lever_mass = 0.0;  // [kg]
};

HandleSpec handle_spec(HandleKind k);

// Empty when usable.
std::optional<std::string> validate(const HandleSpec& h);

}  // namespace hemm::device::bimanual
