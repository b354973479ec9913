// The operator's haptic device as the servo thread sees it: a pose, velocity
// and buttons in (frame H), a 3-DoF force out (frame H), and the device's
// limits. read() and write() run on the servo thread at 1 kHz: every backend
// must make them allocation-free, lock-free and non-blocking.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string_view>

namespace hemm::device {

// Button bits in DeviceSample::buttons.
inline constexpr std::uint32_t kButton1 = 1u << 0;
inline constexpr std::uint32_t kButton2 = 1u << 1;

// One reading of the device, all in frame H (SI units).
struct DeviceSample {
  std::int64_t t_ns = 0;  // steady-clock stamp; the servo loop sets it to the tick's wake time
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity_H = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;
};

// What the device can do. The servo task uses these to shape its forces
// (e.g. never command a stiffness above max_stiffness).
struct DeviceLimits {
  Eigen::Vector3d workspace_min_H = Eigen::Vector3d::Zero();  // reachable box in frame H [m]
  Eigen::Vector3d workspace_max_H = Eigen::Vector3d::Zero();
  double max_continuous_force = 0.0;  // [N] sustainable indefinitely
  double peak_force = 0.0;            // [N] short bursts
  double max_stiffness = 0.0;         // [N/m] highest stably renderable stiffness

  bool contains(const Eigen::Vector3d& p_H, double tolerance = 0.0) const {
    return (p_H.array() >= workspace_min_H.array() - tolerance).all() &&
           (p_H.array() <= workspace_max_H.array() + tolerance).all();
  }
};

// The PHANToM Omni as given by the HEMM paper (Sec. 2.1: 160 W x 120 H x 70 D mm)
// and the vendor's data sheet (0.88 N continuous, 3.3 N peak; stiffness
// 1.26 / 2.31 / 1.02 N/mm in x / y / z: the weakest axis bounds max_stiffness).
// The box is centred on the H origin: x right (160 mm), y up (120 mm), z towards
// the user (70 mm).
inline DeviceLimits phantom_omni_limits() {
  DeviceLimits l;
  l.workspace_min_H = Eigen::Vector3d(-0.080, -0.060, -0.035);
  l.workspace_max_H = Eigen::Vector3d(0.080, 0.060, 0.035);
  l.max_continuous_force = 0.88;
  l.peak_force = 3.3;
  l.max_stiffness = 1020.0;
  return l;
}

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;

  // Fills `out` with the latest state (t_ns is left to the caller).
  // Allocation-free, non-blocking.
  virtual void read(DeviceSample& out) noexcept = 0;

  // Commands a force in frame H, held until the next write. The device
  // enforces its own limits (peak, continuous); a non-finite force is
  // treated as zero. Allocation-free, non-blocking.
  virtual void write(const Eigen::Vector3d& force_H) noexcept = 0;

  virtual const DeviceLimits& limits() const noexcept = 0;
  virtual std::string_view name() const noexcept = 0;
};

}  // namespace hemm::device
