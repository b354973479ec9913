// The SIMULATED bimanual haptic interface as a HapticDevice (DESIGN.md
// principle 8): two end-effectors, one per arm, frame H = D of rig.h, each
// reporting the pose and twist of its handle's end-effector frame E and the
// handle's inputs, and taking a force and torque at E (and a grip force on
// the grip-force interface). Behind the API: the arms' controllers
// (impedance with gravity compensation, null-space elbow force, feed-forward
// inertia reduction, collision avoidance, the device's limits) and the MuJoCo
// plant with the simulated human hands following scripts (simulation.h).
//
// Threading: write() runs both controllers and steps the plant one servo
// period on the calling (servo) thread. Why not a plant thread of its own:
// the real arms take one command per 1 kHz cycle and report the state the
// next cycle, which is exactly this; one thread keeps the simulation
// deterministic and tick-locked (tests replay it exactly); and it needs no
// second clock or lock-free exchange. It costs ~0.1 ms of the 1 ms period
// (bimanual_bench); read() and write() allocate nothing (tested).
//
// write() enforces, per end-effector: non-finite force, torque or grip force
// -> zero wrench (counted); peak force and torque (clamp_to_peak); a grip
// force on a handle without a grip lever is an input the handle does not
// have: ignored and counted; a disabled end-effector (brakes on, clutch off,
// dead-man open) gets nothing. The controllers add the speed, workspace,
// joint-range and joint-torque limits.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "operator/device/bimanual/simulation.h"
#include "operator/device/haptic_device.h"

namespace hemm::device::bimanual {

// The limits the device reports for a configuration (end-effector k = arm k).
DeviceLimits bimanual_limits(const SimulationConfig& config);

struct BimanualDeviceCounters {
  std::uint64_t writes = 0;
  std::uint64_t nonfinite_commands = 0;    // end-effector commands replaced by zero
  std::uint64_t missing_input_commands = 0;  // grip force asked of a handle without a grip
  std::uint64_t limited_commands = 0;       // clamped to the peak force/torque
  std::uint64_t disabled_commands = 0;      // a wrench asked of a disabled end-effector
};

class SimulatedBimanualDevice final : public HapticDevice {
 public:
  // One script per arm (right, left). The hands start on their handles at
  // the rig's home postures. Throws std::invalid_argument on a bad config or
  // a null script.
  SimulatedBimanualDevice(const SimulationConfig& config, std::array<std::shared_ptr<const HumanScript>, kArms> hands);

  void read(DeviceSample& out) noexcept override;
  void write(const DeviceCommand& cmd) noexcept override;
  const DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "simulated-bimanual-lwr"; }

  // Only from the thread that calls read/write (or after it stopped).
  const BimanualSimulation& simulation() const noexcept { return sim_; }
  BimanualSimulation& simulation() noexcept { return sim_; }
  const BimanualDeviceCounters& counters() const noexcept { return counters_; }
  // The SIMULATED human's script of arm s (what it asks of its hand).
  const HumanScript& hand(ArmSide s) const noexcept { return *hands_[static_cast<std::size_t>(index(s))]; }
  // Smallest gaps over the run so far (the controller's and MuJoCo's), and
  // MuJoCo's contact substeps (SIMULATION truth).
  double min_arm_arm_m() const noexcept { return min_arm_arm_m_; }
  double min_arm_table_m() const noexcept { return min_arm_table_m_; }

 private:
  BimanualSimulation sim_;
  std::array<std::shared_ptr<const HumanScript>, kArms> hands_;
  DeviceLimits limits_;
  BimanualDeviceCounters counters_;
  double min_arm_arm_m_, min_arm_table_m_;
};

}  // namespace hemm::device::bimanual
