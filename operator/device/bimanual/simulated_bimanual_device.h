// The SIMULATED bimanual haptic interface as a HapticDevice (DESIGN.md
// principle 8): two end-effectors, one per arm, frame H = D of rig.h, each
// reporting the pose and twist of its handle's end-effector frame E and the
// handle's inputs, and taking a force and torque at E (and a grip force on
// the grip-force interface). Behind the API: the arms' controllers
// (impedance with gravity compensation, null-space elbow force, feed-forward
// inertia reduction, collision avoidance, the device's limits) and the MuJoCo
// plant with the simulated human hands following scripts (simulation.h).
//
// Threading (simulated_hardware.h): the controllers are the device
// backend's (hemm's work) and always run in write() on the servo thread;
// what stands in for hardware, the MuJoCo plant and the simulated human
// hands, runs
//  - in lock-step (the default, and before start() / after stop()): stepped
//    one servo period inside write() too, deterministic and tick-locked
//    (tests replay it exactly; the tick then pays the plant's ~45 us);
//  - threaded (start() with HardwareMode::kThreaded, as the shipped configs
//    run): on a thread of its own at the plant's period, as the real arms'
//    joint controllers run on their own boards. Each plant step applies the
//    newest joint torques write() published (or holds the last) and
//    publishes the timestamped joint readings; read() takes the newest
//    (newest wins) and runs the backend's forward kinematics on it. The
//    hands' scripts are then called on that thread.
// read() and write() allocate nothing, lock nothing and never wait (tested).
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

#include "common/concurrency/newest_mailbox.h"
#include "operator/device/bimanual/simulation.h"
#include "operator/device/haptic_device.h"
#include "operator/device/simulated_hardware.h"

namespace hemm::device::bimanual {

// The limits the device reports for a configuration (end-effector k = arm k).
DeviceLimits bimanual_limits(const SimulationConfig& config);

struct BimanualDeviceCounters {
  std::uint64_t writes = 0;
  std::uint64_t nonfinite_commands = 0;    // end-effector commands replaced by zero
  std::uint64_t missing_input_commands = 0;  // grip force asked of a handle without a grip
  std::uint64_t limited_commands = 0;       // clamped to the peak force/torque
  std::uint64_t disabled_commands = 0;      // a wrench asked of a disabled end-effector
  // Per arm, the writes in which the device's own limits pushed back on the
  // hand (what a stalled hand runs into, beside the rendered wrench): the
  // joint-range springs and speed damping (|tau_limits| > 0.5 N m), the
  // workspace and speed walls at E (|force| > 1 N), the arm-arm and
  // arm-table avoidance (|tau_collision| > 0.5 N m); and each one's peak.
  // Beside them, the writes with the elbow (joint 4) within 0.1 rad of
  // straight: the arm at the end of its reach, a singularity no limit term
  // reports, where the hand goes no further from the shoulder.
  std::array<std::uint64_t, kArms> joint_limit_writes{}, wall_writes{}, collision_writes{}, stretched_writes{};
  std::array<double, kArms> peak_joint_limit_nm{}, peak_wall_n{}, peak_collision_nm{};
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
  void start(const HardwareStart& how, std::vector<std::string>* warnings) override;
  void stop() noexcept override;
  const SimulatedHardwareStats* simulated_hardware() const noexcept override {
    return hardware_ ? &hardware_->stats() : nullptr;
  }

  // The joint readings the backend works from (the thread that calls
  // read/write): lock-step, the plant's; threaded, the newest sample read()
  // took from the plant's thread.
  const ArmReading& reading(ArmSide s) const noexcept;
  // Lock-step: only from the thread that calls read/write; threaded: only
  // after stop() (the plant is the hardware thread's while it runs).
  const BimanualSimulation& simulation() const noexcept { return sim_; }
  BimanualSimulation& simulation() noexcept { return sim_; }
  const BimanualDeviceCounters& counters() const noexcept { return counters_; }
  // The SIMULATED human's script of arm s (what it asks of its hand).
  const HumanScript& hand(ArmSide s) const noexcept { return *hands_[static_cast<std::size_t>(index(s))]; }
  // Smallest gaps over the run so far (the controller's and MuJoCo's), and
  // MuJoCo's contact substeps (SIMULATION truth). Threaded: after stop().
  double min_arm_arm_m() const noexcept { return min_arm_arm_m_; }
  double min_arm_table_m() const noexcept { return min_arm_table_m_; }

 private:
  struct Sample {  // plant thread -> read()
    std::int64_t t_ns = 0;  // steady clock when published
    ArmReadings readings{};
  };
  struct Command {  // write() -> plant thread
    std::int64_t t_ns = 0;
    std::array<ArmActuation, kArms> act{};
  };
  void hardware_step() noexcept;  // plant thread
  void count_limits(const ArmReadings& r) noexcept;  // write()'s: the limit terms and the elbow into counters_

  BimanualSimulation sim_;
  std::array<std::shared_ptr<const HumanScript>, kArms> hands_;
  DeviceLimits limits_;
  BimanualDeviceCounters counters_;
  double min_arm_arm_m_, min_arm_table_m_;
  // Threaded mode (see the file comment).
  bool threaded_ = false;
  ArmReadings readings_{};  // servo thread: the newest sample taken
  NewestMailbox<Sample> samples_;
  NewestMailbox<Command> commands_;
  std::array<ArmActuation, kArms> held_{};         // plant thread: the torques in force
  double plant_min_arm_arm_m_, plant_min_arm_table_m_;  // plant thread, merged at stop()
  std::unique_ptr<SimulatedHardwareThread> hardware_;
};

}  // namespace hemm::device::bimanual
