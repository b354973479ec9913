#include "operator/device/bimanual/simulation.h"

#include <stdexcept>

namespace hemm::device::bimanual {

std::optional<std::string> validate(const SimulationConfig& c) {
  if (auto e = validate(c.plant)) return "plant: " + *e;
  for (int a = 0; a < kArms; ++a) {
    if (auto e = validate(c.control[static_cast<std::size_t>(a)]))
      return std::string(to_string(static_cast<ArmSide>(a))) + " arm control: " + *e;
  }
  return std::nullopt;
}

namespace {
const SimulationConfig& checked(const SimulationConfig& c) {
  if (auto e = validate(c)) throw std::invalid_argument("BimanualSimulation: " + *e);
  return c;
}
}  // namespace

BimanualSimulation::BimanualSimulation(const SimulationConfig& config)
    : config_(checked(config)),
      plant_(config.plant),
      controller_(config.plant.rig, config.plant.handles, config.control, config.plant.control_period_s) {
  // Settle the controllers' state on the first readings.
  for (int a = 0; a < kArms; ++a) {
    const ArmReading& r = plant_.reading(static_cast<ArmSide>(a));
    in_[static_cast<std::size_t>(a)].q = r.q;
    in_[static_cast<std::size_t>(a)].qd = r.qd;
  }
  controller_.update(in_, out_);
  sense(readings());
}

void BimanualSimulation::sense(const ArmReadings& rd) noexcept {
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmSide side = static_cast<ArmSide>(a);
    const ArmReading& r = rd[k];
    const kinematics::Arm7Model& m = controller_.nominal(side);
    kinematics::Arm7Frames f;
    kinematics::forward_kinematics(m, r.q, f);
    const Eigen::Isometry3d& T_D_A = config_.plant.rig.T_D_A[k];
    ee_[k].T_D_E = T_D_A * f.joint(7) * controller_.handle(side).T_J7_E;
    const kinematics::Wrench6 v =
        kinematics::partial_jacobian(m, f, 7, T_D_A.inverse() * ee_[k].T_D_E.translation()) * r.qd;
    ee_[k].velocity_D = T_D_A.linear() * v.head<3>();
    ee_[k].angular_velocity_D = T_D_A.linear() * v.tail<3>();
  }
}

void BimanualSimulation::step(const std::array<HumanTarget, kArms>& human) noexcept {
  step({kinematics::Wrench6::Zero(), kinematics::Wrench6::Zero()}, {0.0, 0.0}, human);
}

std::array<HumanTarget, kArms> BimanualSimulation::resting_targets() const {
  std::array<HumanTarget, kArms> h;
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    h[k].position_D = plant_.truth().hands[k].position_D;
    h[k].orientation_D = plant_.truth().hands[k].orientation_D;
  }
  return h;
}

void BimanualSimulation::step(const std::array<kinematics::Wrench6, kArms>& w_env_D,
                              const std::array<double, kArms>& grip_force,
                              const std::array<HumanTarget, kArms>& human) noexcept {
  std::array<ArmActuation, kArms> act;
  control(readings(), w_env_D, grip_force, act);
  plant_.step(act, human);
  sense(readings());
}

void BimanualSimulation::control(const ArmReadings& rd, const std::array<kinematics::Wrench6, kArms>& w_env_D,
                                 const std::array<double, kArms>& grip_force,
                                 std::array<ArmActuation, kArms>& act) noexcept {
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmReading& r = rd[k];
    ArmInput& in = in_[k];
    in.q = r.q;
    in.qd = r.qd;
    in.ft_J7 = r.ft_J7;
    in.w_env_D = w_env_D[k];
    if (in.enabled != r.powered) controller_.reset();
    in.enabled = r.powered;
  }
  controller_.update(in_, out_);
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    act[k].tau = out_[k].tau;
    act[k].grip_force = std::isfinite(grip_force[k]) ? grip_force[k] : 0.0;
    act[k].power = true;  // the hardware interlock (dead-man, clutch) cuts it
  }
}

}  // namespace hemm::device::bimanual
