// The SIMULATED bimanual interface in one object: the MuJoCo plant (plant.h)
// and the arms' controllers (arm_control.h) at the servo rate. step() takes
// what the renderer asks for (a wrench at each end-effector, a grip force)
// and what the simulated human does, runs both controllers on the latest
// sensor readings and advances the plant one period. The HapticDevice
// backend (simulated_bimanual_device.h) and the tests drive it.
#pragma once

#include <array>

#include "operator/device/bimanual/arm_control.h"
#include "operator/device/bimanual/plant.h"

namespace hemm::device::bimanual {

// An end-effector's state from the latest joint readings (nominal kinematics,
// frame D): where the handle's E frame is and how it moves.
struct EndEffectorState {
  Eigen::Isometry3d T_D_E = Eigen::Isometry3d::Identity();
  Eigen::Vector3d velocity_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_velocity_D = Eigen::Vector3d::Zero();
};

struct SimulationConfig {
  PlantConfig plant{};
  std::array<ArmControlParams, kArms> control{default_arm_control(), default_arm_control()};
};

// Empty when usable.
std::optional<std::string> validate(const SimulationConfig& c);

using ArmReadings = std::array<ArmReading, kArms>;

class BimanualSimulation {
 public:
  // Throws std::invalid_argument on a bad config.
  explicit BimanualSimulation(const SimulationConfig& config);

  // One servo period: control() on the plant's readings, the plant steps
  // one period with those torques, sense() on its new readings.
  // Allocation-free.
  void step(const std::array<kinematics::Wrench6, kArms>& w_env_D, const std::array<double, kArms>& grip_force,
            const std::array<HumanTarget, kArms>& human) noexcept;
  // The two halves of a period apart, for a plant stepped on a thread of its
  // own (simulated_bimanual_device.h, threaded): the device backend's work
  // (hemm's) is control() and sense(); the plant's is plant().step().
  // control(): both controllers' joint torques into `act` (motors powered:
  // the handles' interlocks cut them in the plant) from joint readings `r`
  // and the wrench and grip force the renderer asks; output() holds the
  // controllers' view. sense(): end_effector() from readings `r` (nominal
  // forward kinematics). Both allocation-free.
  void control(const ArmReadings& r, const std::array<kinematics::Wrench6, kArms>& w_env_D,
               const std::array<double, kArms>& grip_force, std::array<ArmActuation, kArms>& act) noexcept;
  void sense(const ArmReadings& r) noexcept;
  // The plant's readings now, both arms.
  ArmReadings readings() const noexcept { return {plant_.reading(ArmSide::kRight), plant_.reading(ArmSide::kLeft)}; }
  // One servo period with nothing rendered (free space, no grip force).
  void step(const std::array<HumanTarget, kArms>& human) noexcept;

  // The arm runs (motors powered, dead-man closed); false: braked or braking.
  bool enabled(ArmSide s) const noexcept { return plant_.reading(s).powered; }
  const ArmReading& reading(ArmSide s) const noexcept { return plant_.reading(s); }
  const ArmOutput& output(ArmSide s) const noexcept { return out_[static_cast<std::size_t>(index(s))]; }
  // The end-effector after the last step (output() holds the controller's
  // view from before it).
  const EndEffectorState& end_effector(ArmSide s) const noexcept { return ee_[static_cast<std::size_t>(index(s))]; }
  const PlantTruth& truth() const noexcept { return plant_.truth(); }
  double time_s() const noexcept { return plant_.time_s(); }
  // What the human holds at the start: each end-effector's pose.
  std::array<HumanTarget, kArms> resting_targets() const;

  BimanualPlant& plant() noexcept { return plant_; }
  BimanualController& controller() noexcept { return controller_; }
  const BimanualController& controller() const noexcept { return controller_; }
  const SimulationConfig& config() const noexcept { return config_; }

 private:
  SimulationConfig config_;
  BimanualPlant plant_;
  BimanualController controller_;
  std::array<ArmInput, kArms> in_{};
  std::array<ArmOutput, kArms> out_{};
  std::array<EndEffectorState, kArms> ee_{};
};

}  // namespace hemm::device::bimanual
