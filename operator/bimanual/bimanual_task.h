// The servo task of the bimanual station: renders a simple local
// environment for each hand of the SIMULATED bimanual interface until VPS
// scenes arrive (next issue): a plane that pushes back (spring-damper on the
// penetration, never pulling), an orientation spring holding the handle's
// starting orientation (torque rendering), and for a grip handle a virtual
// object between the fingers. Allocation-free; nothing for a disabled
// end-effector; no setpoint for a robot.
#pragma once

#include <array>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "operator/servo/servo_loop.h"
#include "operator/view/device_view_record.h"

namespace hemm::op {

struct HandEnvironment {
  Eigen::Vector3d plane_point_H = Eigen::Vector3d(-0.7, 0.0, 0.25);
  Eigen::Vector3d plane_normal_H = Eigen::Vector3d::UnitZ();  // unit, out of the plane's solid side
  double plane_stiffness = 3000.0;       // [N/m]
  double plane_damping = 20.0;           // [N s/m], only while in contact
  double orientation_stiffness = 2.0;    // [N m/rad] to the starting orientation
  double orientation_damping = 0.02;     // [N m s/rad]
  bool grip_object = false;              // grip handle: an object between the fingers
  double grip_object_at_m = 0.01;        // lever closure where it is met
  double grip_object_stiffness = 800.0;  // [N/m]
};

class BimanualTask final : public servo::ServoTask {
 public:
  explicit BimanualTask(const std::array<HandEnvironment, device::kMaxEndEffectors>& env) : env_(env) {}

  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& model, servo::TickOutput& out) noexcept override;

  // A live view's feed (device_view_record.h), before the loop starts; `arms`
  // (may be null): the SIMULATED device whose joint angles go with each tick.
  void set_view(DeviceViewMailbox* ticks, const device::bimanual::SimulatedBimanualDevice* arms) noexcept {
    view_ = ticks;
    view_arms_ = arms;
  }
  const std::array<HandEnvironment, device::kMaxEndEffectors>& environment() const noexcept { return env_; }

 private:
  DeviceViewMailbox* view_ = nullptr;
  const device::bimanual::SimulatedBimanualDevice* view_arms_ = nullptr;
  std::uint64_t ticks_ = 0;
  std::array<HandEnvironment, device::kMaxEndEffectors> env_;
  std::array<Eigen::Quaterniond, device::kMaxEndEffectors> start_{};
  std::array<bool, device::kMaxEndEffectors> have_start_{};
};

}  // namespace hemm::op
