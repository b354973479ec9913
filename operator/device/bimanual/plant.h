// The SIMULATED plant of the bimanual haptic interface: both arms, their
// handles and the simulated human hands in MuJoCo 2.2.2 (scene.h), stepped one
// control period at a time with joint torques in and sensor readings out, as
// the real robots' 1 kHz torque interface would be. No hardware is involved.
//
// What makes the actuators non-ideal (ActuatorModel): Coulomb (MuJoCo
// frictionloss) and viscous (damping) joint friction, torque ripple
// (tau_out = tau_cmd (1 + e sin(2 N q + phi)) + c sin(N q + psi): a
// harmonic-drive-like term proportional to the torque and a cogging term at
// the gear ratio N), saturation at the torque limits, and brakes. The plant's
// link masses, centres of mass and inertias differ from the nominal model the
// controller uses by a few per cent (ModelError, deterministic from a seed).
//
// Sensors per arm: joint positions and velocities, a torque sensor in each
// joint (the link-side torque: motor output minus friction and brake), the
// 6-axis wrist force-torque sensor between flange and handle (MuJoCo force and
// torque sensors; it also feels the handle's own weight and inertia, as a
// real one does), the grip lever's position.
//
// Brakes: the motors are powered only while commanded AND the dead-man is
// closed (a hardware interlock: the magnetic clutch's integrated switch opens
// when the bracket comes off; the joystick handle's dead-man button). Without
// power the motor torque is zero and, after brake_delay_s, the brakes grip
// with brake_torque (MuJoCo frictionloss: they stop and hold the arm).
// Restoring power releases them at once.
//
// The human (human.h): forces on the hand body and the equal and opposite
// ones on the handle are recomputed every substep. The magnetic clutch comes
// off when the grasp wrench exceeds its attaching force or torque; it
// re-attaches only by reset().
//
// step() is allocation-free after construction (mj_step1/mj_step2 use MuJoCo's
// preallocated arena); construction loads the scene and may throw.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "common/kinematics/arm7.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/human.h"
#include "operator/device/bimanual/rig.h"

namespace hemm::device::bimanual {

struct ActuatorModel {
  kinematics::Arm7Vector coulomb_friction = kinematics::Arm7Vector::Zero();  // [N m]
  kinematics::Arm7Vector viscous_friction = kinematics::Arm7Vector::Zero();  // [N m s/rad]
  double ripple_fraction = 0.0;                                              // e
  kinematics::Arm7Vector cogging_torque = kinematics::Arm7Vector::Zero();    // c [N m]
  double gear_ratio = 160.0;                                                 // N
  kinematics::Arm7Vector brake_torque = kinematics::Arm7Vector::Zero();      // [N m]
  double brake_delay_s = 0.015;
};
// LWR-class values (ASSUMED: residual friction after the joints' own torque
// control, 2 % ripple, sub-N m cogging, brakes at 80 % of the torque limits,
// 15 ms to grip).
ActuatorModel lwr_actuators(const kinematics::Arm7Model& arm);
// No friction, no ripple (the brakes are kept: they are a safety function).
ActuatorModel ideal_actuators(const kinematics::Arm7Model& arm);

// The plant's parameters relative to the nominal model: each link mass and
// inertia scaled by 1 + u * mass/inertia, each centre of mass moved by up to
// com_m, u uniform in [-1, 1] from `seed`. Zero everything for a perfect model.
struct ModelError {
  double mass = 0.04;
  double inertia = 0.05;
  double com_m = 0.004;
  std::uint64_t seed = 1;
};
kinematics::Arm7Model perturbed(const kinematics::Arm7Model& nominal, const ModelError& e, std::uint64_t stream);

struct SensorNoise {
  double ft_force_N = 0.0;  // standard deviation per reading
  double ft_torque_Nm = 0.0;
  double joint_torque_Nm = 0.0;
  std::uint64_t seed = 7;
};

struct PlantConfig {
  RigGeometry rig = default_rig();
  std::array<HandleKind, kArms> handles{HandleKind::kMagneticClutch, HandleKind::kMagneticClutch};
  std::array<HumanModel, kArms> humans{};
  ActuatorModel actuators = lwr_actuators(kinematics::lwr_arm_model());
  ModelError model_error{};
  SensorNoise noise{};
  double control_period_s = 0.001;
  int substeps = 2;
  double proximity_margin_m = 0.15;  // MuJoCo reports arm-arm / arm-table pairs closer than this
};

// Empty when usable.
std::optional<std::string> validate(const PlantConfig& c);

struct ArmActuation {
  kinematics::Arm7Vector tau = kinematics::Arm7Vector::Zero();  // commanded joint torques [N m]
  double grip_force = 0.0;  // grip handle: force against the forefinger [N], clamped to [0, grip_max_force]
  bool power = true;        // false: motors off, brakes engage
};

struct ArmReading {
  kinematics::Arm7Vector q = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector qd = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector tau_J = kinematics::Arm7Vector::Zero();  // joint torque sensors
  // Wrist F/T sensor: the wrench the handle exerts on the flange, about the
  // flange centre, in J7 axes (force, torque).
  kinematics::Wrench6 ft_J7 = kinematics::Wrench6::Zero();
  double grip_position = 0.0;  // [m], 0 = open
  double grip_velocity = 0.0;
  // The handle's inputs as the human works them (only what the handle has).
  std::uint32_t buttons = 0;
  Eigen::Vector2d joystick = Eigen::Vector2d::Zero();
  bool switch_on = false;
  bool attached = true;        // magnetic clutch on the flange
  bool deadman_closed = true;  // clutch attached / dead-man button pressed (true if the handle has none)
  bool powered = true;
  bool brakes_engaged = false;
};

// SIMULATION truth, for tests and logs (never for control).
struct HandTruth {
  Eigen::Vector3d position_D = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_D = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_velocity_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d grasp_force_D = Eigen::Vector3d::Zero();   // handle -> hand
  Eigen::Vector3d grasp_torque_D = Eigen::Vector3d::Zero();
  bool grasping = true;
};
struct PlantTruth {
  double t_s = 0.0;
  std::array<HandTruth, kArms> hands;
  // Smallest surface distance in the last period (MuJoCo's collision
  // detection; +infinity when no pair came within proximity_margin_m).
  double min_arm_arm_m = 0.0;
  double min_arm_table_m = 0.0;  // table or column
  std::uint64_t arm_arm_contact_steps = 0;    // substeps with an arm-arm penetration, since start
  std::uint64_t arm_table_contact_steps = 0;  // substeps with an arm-table/column penetration
};

class BimanualPlant {
 public:
  // Throws std::invalid_argument on a bad config, std::runtime_error if
  // MuJoCo rejects the scene. The arms start at rest at the rig's home
  // postures, each hand on its handle.
  explicit BimanualPlant(const PlantConfig& config);
  ~BimanualPlant();
  BimanualPlant(const BimanualPlant&) = delete;
  BimanualPlant& operator=(const BimanualPlant&) = delete;

  // One control period (substeps of MuJoCo). Allocation-free.
  void step(const std::array<ArmActuation, kArms>& actuation, const std::array<HumanTarget, kArms>& human) noexcept;

  const ArmReading& reading(ArmSide s) const noexcept;
  const PlantTruth& truth() const noexcept;
  double time_s() const noexcept;

  // Back to rest at `q` per arm (hands on their handles, clutches attached,
  // power on, brakes off).
  void reset(const std::array<kinematics::Arm7Vector, kArms>& q);

  const PlantConfig& config() const noexcept;
  const kinematics::Arm7Model& true_arm(ArmSide s) const noexcept;  // the plant's own (perturbed) parameters
  const HandleSpec& true_handle(ArmSide s) const noexcept;
  const std::string& scene_xml() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hemm::device::bimanual
