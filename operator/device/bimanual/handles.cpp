#include "operator/device/bimanual/handles.h"

#include <cmath>

namespace hemm::device::bimanual {

const char* to_string(HandleKind k) {
  switch (k) {
    case HandleKind::kMagneticClutch:
      return "magnetic_clutch";
    case HandleKind::kGripForce:
      return "grip_force";
    case HandleKind::kJoystick:
      return "joystick";
  }
  return "?";
}

std::optional<HandleKind> handle_from_string(std::string_view n) {
  for (HandleKind k : {HandleKind::kMagneticClutch, HandleKind::kGripForce, HandleKind::kJoystick}) {
    if (n == to_string(k)) return k;
  }
  return std::nullopt;
}

const char* to_string(HandleInput i) {
  switch (i) {
    case HandleInput::kClutch:
      return "clutch";
    case HandleInput::kGrip:
      return "grip";
    case HandleInput::kJoystickAxes:
      return "joystick axes";
    case HandleInput::kSwitch:
      return "switch";
    case HandleInput::kButtons:
      return "buttons";
    case HandleInput::kDeadman:
      return "dead-man switch";
  }
  return "?";
}

bool has_input(HandleKind k, HandleInput i) {
  switch (k) {
    case HandleKind::kMagneticClutch:
      // The clutch's dead-man switch is integrated: it is closed while attached.
      return i == HandleInput::kClutch || i == HandleInput::kDeadman;
    case HandleKind::kGripForce:
      return i == HandleInput::kGrip;
    case HandleKind::kJoystick:
      return i == HandleInput::kJoystickAxes || i == HandleInput::kSwitch || i == HandleInput::kButtons ||
             i == HandleInput::kDeadman;
  }
  return false;
}

std::optional<std::string> require_input(HandleKind k, HandleInput i) {
  if (has_input(k, i)) return std::nullopt;
  return std::string("the ") + to_string(k) + " handle has no " + to_string(i);
}

HandleSpec handle_spec(HandleKind k) {
  HandleSpec h;
  h.kind = k;
  auto body = [](double mass, double com_z, double radius, double length) {
    kinematics::RigidBodyInertia b;
    b.mass = mass;
    b.com = Eigen::Vector3d(0.0, 0.0, com_z);
    b.inertia = kinematics::cylinder_inertia(mass, radius, length);
    return b;
  };
  switch (k) {
    case HandleKind::kMagneticClutch:
      // Bracket with the forearm strap: the hand's centre 8 cm out.
      h.inertia_J7 = body(0.25, 0.04, 0.04, 0.08);
      h.T_J7_E.translation() = Eigen::Vector3d(0.0, 0.0, 0.08);
      h.clutch_force_limit = 60.0;
      h.clutch_torque_limit = 6.0;
      break;
    case HandleKind::kGripForce:
      h.inertia_J7 = body(0.35, 0.05, 0.03, 0.10);
      h.T_J7_E.translation() = Eigen::Vector3d(0.0, 0.0, 0.07);
      h.grip_travel = 0.025;
      h.grip_max_force = 10.0;
      h.grip_lever_mass = 0.02;
      break;
    case HandleKind::kJoystick:
      h.inertia_J7 = body(0.30, 0.05, 0.03, 0.11);
      h.T_J7_E.translation() = Eigen::Vector3d(0.0, 0.0, 0.07);
      break;
  }
  return h;
}

std::optional<std::string> validate(const HandleSpec& h) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!pos(h.inertia_J7.mass) || h.inertia_J7.mass > 5.0) return "handle mass must be in (0, 5] kg";
  if (!h.inertia_J7.com.allFinite() || !h.inertia_J7.inertia.allFinite()) return "handle inertia must be finite";
  if (!h.T_J7_E.matrix().allFinite() || h.T_J7_E.translation().norm() > 0.5)
    return "handle end-effector offset must be finite, within 0.5 m of the flange";
  if (!pos(h.capsule_radius) || !pos(h.capsule_length)) return "handle capsule radius and length must be > 0";
  if (h.kind == HandleKind::kMagneticClutch && (!pos(h.clutch_force_limit) || !pos(h.clutch_torque_limit)))
    return "magnetic clutch force and torque limits must be > 0";
  if (h.kind == HandleKind::kGripForce && (!pos(h.grip_travel) || !pos(h.grip_max_force) || !pos(h.grip_lever_mass)))
    return "grip travel, maximum force and lever mass must be > 0";
  return std::nullopt;
}

}  // namespace hemm::device::bimanual
