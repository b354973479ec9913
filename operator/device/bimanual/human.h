// The SIMULATED human of the bimanual device: per arm a hand and forearm (a
// rigid body of the hand's mass) that holds the handle through a stiff,
// damped grasp and is driven by the arm's muscles as a spring-damper towards
// a target pose (like the Omni's hand model in operator/device/simulated_omni.h,
// in 6 DoF). Rendered forces therefore push back on it as on a real hand: a
// constant force F displaces it by F / arm_stiffness at rest. The human also
// carries its own hand's weight, may add a known push (used to measure the
// inertia it feels), moves the grip lever with the forefinger, and works the
// joystick handle's inputs. Targets come from a script: a function of time,
// evaluated on the servo thread (const, allocation-free).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hemm::device::bimanual {

struct HumanModel {
  double hand_mass = 1.2;                       // [kg] hand + part of the forearm
  Eigen::Vector3d hand_inertia{0.004, 0.004, 0.002};  // [kg m^2] principal, about the hand's centre
  double arm_stiffness = 300.0;                 // [N/m] towards the target
  double arm_damping = 25.0;                    // [N s/m]
  double arm_rot_stiffness = 3.0;               // [N m/rad]
  double arm_rot_damping = 0.15;                // [N m s/rad]
  double grasp_stiffness = 4000.0;              // [N/m] hand <-> handle
  double grasp_damping = 40.0;                  // [N s/m]
  double grasp_rot_stiffness = 40.0;            // [N m/rad]
  double grasp_rot_damping = 0.4;               // [N m s/rad]
  double finger_stiffness = 400.0;              // [N/m] forefinger on the grip lever
  double finger_damping = 4.0;                  // [N s/m]
  bool carries_own_weight = true;               // the human holds up its own hand
  // Voluntary effort: a real hand pushes harder while its motion stalls short
  // of where it wants to be (against friction, a weight it misjudged, a
  // contact it means to seat). The integral of the position error towards
  // the target, times voluntary_gain, adds a force bounded by
  // max_voluntary_force (anti-windup: the integral is clamped there, so it
  // unwinds at once when the error turns). 0: off, the pure arm spring.
  // The gain keeps the hand-arm loop stable (Routh: voluntary_gain < arm_damping
  // x arm_stiffness / felt mass, ~3000 N/(m s) for ~2.5 kg felt).
  double max_voluntary_force = 0.0;  // [N]
  double voluntary_gain = 1000.0;    // [N/(m s)]: 1 mm of error adds 1 N per second
};

// A human co-contracting for a precise task (inserting pins, seating a
// part): stiffer arm and wrist (1000 N/m, 10 N m/rad; measured human arm
// stiffness reaches ~1000-2000 N/m and wrist stiffness 5-20 N m/rad when
// co-contracting), damping to match, and voluntary effort up to
// max_voluntary_force at 4000 N/(m s) (a quarter of a second per its error
// times stiffness; a third of the Routh bound for ~3 kg felt). The VPS
// scenes with LWR-like actuators need it: with the relaxed defaults the
// hand runs ~1 mm beside a 30 mm/s path and the pins strike a hole's rim.
HumanModel co_contracting_human(double max_voluntary_force);

// Empty when usable (finite, masses > 0, stiffness/damping >= 0).
std::optional<std::string> validate(const HumanModel& h);

// What the human does at one instant (frame D).
struct HumanTarget {
  Eigen::Vector3d position_D = Eigen::Vector3d::Zero();  // hand centre target (the handle's E point)
  Eigen::Quaterniond orientation_D = Eigen::Quaterniond::Identity();
  Eigen::Vector3d push_force_D = Eigen::Vector3d::Zero();   // extra force on the hand [N]
  Eigen::Vector3d push_torque_D = Eigen::Vector3d::Zero();  // extra torque on the hand [N m]
  bool grasp = true;             // holds the handle (false: lets go)
  double finger_position = 0.0;  // grip lever target [m] (0 = open)
  std::uint32_t buttons = 0;     // joystick handle buttons
  bool deadman = true;           // joystick handle dead-man button pressed
  Eigen::Vector2d joystick = Eigen::Vector2d::Zero();  // mini-joystick axes in [-1, 1]
  bool switch_on = false;
};

// The pose T_D_E the target asks of the hand (the handle's E frame, in D).
Eigen::Isometry3d pose_D(const HumanTarget& g);

class HumanScript {
 public:
  virtual ~HumanScript() = default;
  virtual HumanTarget at(double t_s) const noexcept = 0;
};

// Piecewise-linear in position (spherical-linear in orientation, linear in
// push, finger and joystick) between timed keys; holds the first key before
// and the last after. Buttons, dead-man, grasp and switch change at each key.
struct HumanKey {
  double t_s = 0.0;
  HumanTarget target;
};
class HumanKeyScript final : public HumanScript {
 public:
  // Non-empty, strictly increasing finite times, finite targets; throws
  // std::invalid_argument otherwise.
  explicit HumanKeyScript(std::vector<HumanKey> keys);
  HumanTarget at(double t_s) const noexcept override;

 private:
  std::vector<HumanKey> keys_;
};

}  // namespace hemm::device::bimanual
