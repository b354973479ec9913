// A SIMULATED PHANToM Omni held by a SIMULATED hand. No hardware is involved:
// this stands in for the device in tests, demos and the loopback setup.
//
// Model (one translational body per axis, frame H):
//   (m_device + m_hand) a = k_hand (x_target - x) - (b_hand + b_device) v
//                           + F_endstop(x, v) + F_applied
// The hand grips the stylus rigidly and follows a scripted target through a
// spring (k_hand) and damper (b_hand), so forces the servo renders push back on
// the hand as on a real one: a constant force F displaces it by F / k_hand at
// steady state. The workspace box has stiff one-sided end stops (spring +
// damper, never pulling). Orientation, buttons and the stylus's dead-man
// follow the script directly (the Omni renders no torque; its angular
// velocity is reported as zero). The SIMULATED stylus has a dead-man input
// (HandleInputs::has_deadman): pressed while the hand script presses it.
// As a HapticDevice it has one end-effector that renders force only: the
// commanded torque is ignored, a grip force is ignored and counted (the stylus
// has no grip), a command with any non-finite entry acts as zero and is
// counted. Integration: semi-implicit (symplectic) Euler
// with `substeps` sub-steps per servo period, stable for the end-stop
// stiffness at 1 kHz.
//
// Force limits, applied to every commanded force before it acts:
//  - peak: |F| <= peak_force (direction kept);
//  - continuous (thermal): an exponentially weighted mean of |F|^2 with time
//    constant thermal_time_constant_s (an I^2 t motor-heating stand-in; the
//    Omni's own thermal model is not published) may never exceed
//    max_continuous_force^2. While the budget lasts the full peak is allowed;
//    a sustained demand above the continuous force is cut to exactly
//    max_continuous_force once the budget is used up, after
//    t_sat = -tau ln(1 - F_cont^2 / F^2).
// Model/Data split as in MuJoCo: a const model, mutable data, free functions.
//
// Threads (simulated_hardware.h): in lock-step (the default, and always
// before start() / after stop()) write() steps the mechanism and the hand one
// period dt_s on the calling thread, so a run is deterministic tick for tick.
// Started HardwareMode::kThreaded, the mechanism and the hand step on their
// own thread every dt_s: each step applies the newest command written (or
// holds the last) and publishes a timestamped sample, which read() takes
// (newest wins); read() and write() then only copy through the mailboxes.
// The script's at() is then called on that thread.
#pragma once

#include <cstdint>
#include <memory>

#include "common/concurrency/newest_mailbox.h"
#include "operator/device/hand_script.h"
#include "operator/device/haptic_device.h"
#include "operator/device/simulated_hardware.h"

namespace hemm::device {

struct SimulatedOmniModel {
  EndEffectorLimits limits = phantom_omni_limits().ee[0];
  double device_mass = 0.045;     // [kg] stylus + linkage, reflected at the tip
  double device_damping = 0.05;   // [N s/m] linkage friction, viscous stand-in
  double hand_mass = 0.30;        // [kg] fingers + part of the forearm
  double hand_stiffness = 200.0;  // [N/m] relaxed grip
  double hand_damping = 11.0;     // [N s/m] with the above: damping ratio ~0.66
  double end_stop_stiffness = 20000.0;  // [N/m]
  double end_stop_damping = 20.0;       // [N s/m]
  double thermal_time_constant_s = 5.0;
  double dt_s = 0.001;  // one servo period: each write() advances this much
  int substeps = 8;

  double total_mass() const { return device_mass + hand_mass; }
};

struct SimulatedOmniData {
  double t_s = 0.0;  // simulated time (dt_s per step), not the wall clock
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_H = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  std::uint32_t buttons = 0;
  bool deadman = false;  // the stylus's dead-man, as the hand holds it
  Eigen::Vector3d applied_force_H = Eigen::Vector3d::Zero();  // after the limits
  double mean_square_force = 0.0;  // thermal state [N^2]
  std::uint64_t steps = 0;
  std::uint64_t nonfinite_commands = 0;     // commands replaced by zero
  std::uint64_t ignored_grip_commands = 0;  // writes with a non-zero grip force
};

// nullptr if the model is usable, else a description of the first bad
// parameter (non-positive mass/stiffness/dt, negative damping, ...).
const char* check_model(const SimulatedOmniModel& model);

// Limits `force_cmd_H` (peak, then thermal budget) and advances the thermal
// state by dt_s. Returns the force that acts.
Eigen::Vector3d limit_force(const SimulatedOmniModel& model, SimulatedOmniData& data,
                            const Eigen::Vector3d& force_cmd_H);

// One servo period: limits the force, integrates the body towards `target`.
void simulated_omni_step(const SimulatedOmniModel& model, SimulatedOmniData& data,
                         const HandTarget& target, const Eigen::Vector3d& force_cmd_H);

class SimulatedOmni final : public HapticDevice {
 public:
  // The body starts at rest at the script's target at t = 0. Throws
  // std::invalid_argument on a bad model or a null script.
  SimulatedOmni(const SimulatedOmniModel& model, std::shared_ptr<const HandScript> script);

  void read(DeviceSample& out) noexcept override;
  // End-effector 0's force (torque ignored, grip force ignored and counted)
  // for the next period: lock-step, applied for one period dt_s as the
  // simulation steps; threaded, handed to the hardware thread.
  void write(const DeviceCommand& cmd) noexcept override;
  const DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "simulated-phantom-omni"; }
  void start(const HardwareStart& how, std::vector<std::string>* warnings) override;
  void stop() noexcept override;
  const SimulatedHardwareStats* simulated_hardware() const noexcept override {
    return hardware_ ? &hardware_->stats() : nullptr;
  }

  const SimulatedOmniModel& model() const { return model_; }
  // Lock-step: only from the thread that calls read/write; threaded: only
  // after stop() (its counters then include the commands write() refused).
  const SimulatedOmniData& data() const { return data_; }

 private:
  struct Sample {  // hardware thread -> read()
    std::int64_t t_ns = 0;  // steady clock when published
    SimulatedOmniData data;
  };
  struct Command {  // write() -> hardware thread
    std::int64_t t_ns = 0;
    Eigen::Vector3d force_H = Eigen::Vector3d::Zero();
  };
  // The force of end-effector 0's command, counting what it ignores.
  Eigen::Vector3d accepted_force(const EndEffectorCommand& c, std::uint64_t* nonfinite,
                                 std::uint64_t* ignored_grip) const noexcept;
  void hardware_step() noexcept;  // hardware thread

  SimulatedOmniModel model_;
  DeviceLimits limits_;  // one end-effector: model_.limits
  SimulatedOmniData data_;  // threaded: the hardware thread's
  std::shared_ptr<const HandScript> script_;
  // Threaded mode (see the file comment).
  bool threaded_ = false;
  NewestMailbox<Sample> samples_;
  NewestMailbox<Command> commands_;
  Command held_;  // hardware thread: the command in force
  std::uint64_t refused_nonfinite_ = 0, refused_grip_ = 0;  // servo thread, merged into data_ at stop()
  std::unique_ptr<SimulatedHardwareThread> hardware_;
};

}  // namespace hemm::device
