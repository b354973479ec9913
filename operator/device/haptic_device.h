// The operator's haptic device as the servo thread sees it (DESIGN.md
// principle 8: one device API, several devices). A device has one or more
// end-effectors; each reports a pose, a twist and its handle's inputs, and
// takes a wrench (force, torque, and a grip force for a grip handle). All in
// the device frame H, SI units. The PHANToM Omni is a one-end-effector device
// that renders force only; the bimanual interface is two end-effectors that
// render force and torque.
//
// read() and write() run on the servo thread at 1 kHz: every backend must make
// them allocation-free, lock-free and non-blocking. Fixed-size arrays
// (kMaxEndEffectors) keep samples and commands plain values that the servo
// loop copies without allocating.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hemm::device {

struct HardwareStart;           // simulated_hardware.h
struct SimulatedHardwareStats;  // simulated_hardware.h

inline constexpr int kMaxEndEffectors = 2;

// Button bits in HandleInputs::buttons (the Omni's stylus buttons, the
// joystick handle's buttons), further bits in order.
inline constexpr std::uint32_t kButton1 = 1u << 0;
inline constexpr std::uint32_t kButton2 = 1u << 1;

// Inputs of the handle mounted on an end-effector: the bimanual paper's three
// handles (magnetic clutch, grip-force interface, joystick handle) and the
// Omni's stylus buttons. A device reports only what its handle has (has_*);
// the values of an input it lacks stay at their defaults.
struct HandleInputs {
  std::uint32_t buttons = 0;  // kButton1, kButton2, ... bits
  bool has_deadman = false;
  bool deadman = false;  // true = pressed/closed (the operator is present)
  bool has_grip = false;
  double grip_position = 0.0;  // grip-force interface: finger DoF [m], 0 = open
  double grip_velocity = 0.0;  // [m/s]
  bool has_joystick = false;
  Eigen::Vector2d joystick = Eigen::Vector2d::Zero();  // mini-joystick axes in [-1, 1]
  bool switch_on = false;                              // the joystick handle's switch
  bool has_clutch = false;
  bool attached = true;  // magnetic clutch: the hand is attached
};

// Which inputs a handle has, as bits: the `inputs` column of the servo log
// and of trajectory files.
inline constexpr std::uint32_t kHasDeadman = 1u << 0;
inline constexpr std::uint32_t kHasGrip = 1u << 1;
inline constexpr std::uint32_t kHasJoystick = 1u << 2;
inline constexpr std::uint32_t kHasClutch = 1u << 3;
inline constexpr std::uint32_t kAllHandleInputs = kHasDeadman | kHasGrip | kHasJoystick | kHasClutch;
inline std::uint32_t handle_input_bits(const HandleInputs& h) noexcept {
  return (h.has_deadman ? kHasDeadman : 0u) | (h.has_grip ? kHasGrip : 0u) |
         (h.has_joystick ? kHasJoystick : 0u) | (h.has_clutch ? kHasClutch : 0u);
}

// One end-effector's state in frame H.
struct EndEffectorSample {
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();  // [m]
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity_H = Eigen::Vector3d::Zero();          // linear [m/s]
  Eigen::Vector3d angular_velocity_H = Eigen::Vector3d::Zero();  // [rad/s]
  HandleInputs handle;
  // false: brakes engaged, hand detached or a fault; the device outputs no
  // wrench on this end-effector whatever is commanded.
  bool enabled = true;
};

// One reading of the device.
struct DeviceSample {
  std::int64_t t_ns = 0;  // steady-clock stamp; the servo loop sets it to the tick's wake time
  // When the device measured this state (steady clock), if it says: a
  // SIMULATED device's hardware thread stamps each sample it publishes;
  // 0 when the state is the device's own at the read (lock-step, replay).
  std::int64_t measured_ns = 0;
  int end_effectors = 1;  // valid entries of ee[]; the servo loop sets it to limits().end_effectors
  std::array<EndEffectorSample, kMaxEndEffectors> ee{};
};

// The wrench commanded to one end-effector, frame H.
struct EndEffectorCommand {
  Eigen::Vector3d force_H = Eigen::Vector3d::Zero();   // [N] at the end-effector point
  Eigen::Vector3d torque_H = Eigen::Vector3d::Zero();  // [N m]; ignored by force-only devices
  double grip_force = 0.0;                             // [N] to the forefinger (grip handle)
};

// What the servo task asks of the device each tick; entries beyond the
// device's end-effector count are ignored.
struct DeviceCommand {
  std::array<EndEffectorCommand, kMaxEndEffectors> ee{};
};

// What one end-effector can do. The servo task uses these to shape its
// wrenches (e.g. never command a stiffness above max_stiffness); the device
// enforces them whatever it is asked.
struct EndEffectorLimits {
  Eigen::Vector3d workspace_min_H = Eigen::Vector3d::Zero();  // reachable box in frame H [m]
  Eigen::Vector3d workspace_max_H = Eigen::Vector3d::Zero();
  double max_continuous_force = 0.0;  // [N] sustainable indefinitely
  double peak_force = 0.0;            // [N] short bursts
  double max_stiffness = 0.0;         // [N/m] highest stably renderable stiffness
  bool renders_torque = false;
  double peak_torque = 0.0;               // [N m]
  double max_rotational_stiffness = 0.0;  // [N m/rad]
  double peak_grip_force = 0.0;           // [N]; 0: the handle renders no grip force
  double max_linear_speed = 0.0;          // [m/s]; 0: not limited by the device

  bool contains(const Eigen::Vector3d& p_H, double tolerance = 0.0) const {
    return (p_H.array() >= workspace_min_H.array() - tolerance).all() &&
           (p_H.array() <= workspace_max_H.array() + tolerance).all();
  }
};

struct DeviceLimits {
  int end_effectors = 1;  // in [1, kMaxEndEffectors]
  std::array<EndEffectorLimits, kMaxEndEffectors> ee{};
};

// The PHANToM Omni as given by the HEMM paper (Sec. 2.1: 160 W x 120 H x 70 D mm)
// and the vendor's data sheet (0.88 N continuous, 3.3 N peak; stiffness
// 1.26 / 2.31 / 1.02 N/mm in x / y / z: the weakest axis bounds max_stiffness).
// The box is centred on the H origin: x right (160 mm), y up (120 mm), z towards
// the user (70 mm). One end-effector, force only (the Omni has no torque
// output), two stylus buttons.
inline DeviceLimits phantom_omni_limits() {
  DeviceLimits d;
  d.end_effectors = 1;
  EndEffectorLimits& l = d.ee[0];
  l.workspace_min_H = Eigen::Vector3d(-0.080, -0.060, -0.035);
  l.workspace_max_H = Eigen::Vector3d(0.080, 0.060, 0.035);
  l.max_continuous_force = 0.88;
  l.peak_force = 3.3;
  l.max_stiffness = 1020.0;
  return d;
}

// SIMULATED rigid scripted hands (replayed 6-DoF paths that do not yield to
// the force) as a device of `end_effectors` end-effectors: an LWR-class arm as
// the bimanual paper gives it (150 N, 25 N m per arm); its impedance figures
// are those of a Cartesian impedance controller of that class (assumed:
// 5000 N/m, 300 N m/rad); a 2 m box about the H origin.
DeviceLimits rigid_hand_limits(int end_effectors);

// A command with `force_H` on end-effector `ee` and nothing else (the common
// case of a one-end-effector, force-only device).
inline DeviceCommand force_command(const Eigen::Vector3d& force_H, int ee = 0) {
  DeviceCommand c;
  c.ee[static_cast<std::size_t>(ee)].force_H = force_H;
  return c;
}

// Checks a backend's write() applies before acting on a command (the servo
// task is not trusted to). All allocation-free.
//
// True if force, torque and grip force are all finite.
bool wrench_is_finite(const EndEffectorCommand& c) noexcept;
// Replaces the wrench of every end-effector (of the first `end_effectors`)
// that has a non-finite entry by zero; returns how many it replaced.
int zero_nonfinite_wrenches(DeviceCommand& cmd, int end_effectors) noexcept;
// Scales force to |F| <= peak_force and torque to |T| <= peak_torque, keeping
// their directions; zeroes the torque of a force-only end-effector and clamps
// the grip force to [0, peak_grip_force]. Expects a finite command.
void clamp_to_peak(EndEffectorCommand& c, const EndEffectorLimits& limits) noexcept;

// nullptr if the limits describe a usable end-effector (a finite box with
// min < max, 0 < continuous <= peak force, stiffness > 0, torque limits > 0
// when it renders torque, the rest finite and >= 0), else the first problem.
const char* check_limits(const EndEffectorLimits& limits);
// The same for every end-effector, and the count in [1, kMaxEndEffectors].
const char* check_limits(const DeviceLimits& limits);

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;

  // Fills `out` with the latest state of every end-effector and sets
  // end_effectors (t_ns is left to the caller). Allocation-free, non-blocking.
  virtual void read(DeviceSample& out) noexcept = 0;

  // Commands one wrench per end-effector, held until the next write. The
  // device enforces its own limits (peak and continuous force, torque, grip
  // force, speed, workspace) whatever is asked; an end-effector whose command
  // has a non-finite entry gets a zero wrench (counted by the backend); a
  // disabled end-effector gets none. Allocation-free, non-blocking.
  virtual void write(const DeviceCommand& cmd) noexcept = 0;

  virtual const DeviceLimits& limits() const noexcept = 0;
  virtual std::string_view name() const noexcept = 0;

  // Called by the servo loop, never on the servo thread: start() before its
  // thread starts, stop() after it stopped. A real driver would open and
  // close its connection here; a SIMULATED device asked for
  // HardwareMode::kThreaded starts (and joins) the thread its simulated
  // hardware runs on (simulated_hardware.h), appending to `warnings` what of
  // that thread's real-time set-up was refused. Default: nothing (the device
  // stays as it is, e.g. lock-step).
  virtual void start(const HardwareStart& how, std::vector<std::string>* warnings);
  virtual void stop() noexcept {}
  // The simulated hardware thread's statistics once it has been started
  // threaded (stay readable after stop()); null otherwise.
  virtual const SimulatedHardwareStats* simulated_hardware() const noexcept { return nullptr; }
};

}  // namespace hemm::device
