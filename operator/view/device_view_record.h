// What the live view of a device-only run reads from the servo thread (the
// VPS scene: vps_task.h; the bimanual device's local environment:
// bimanual_task.h): one fixed-size record per tick through a newest-wins
// mailbox (common/concurrency/newest_mailbox.h). The task fills the
// mailbox's back buffer in place and publishes it: one copy of the record and
// one atomic exchange per tick, no lock, allocation or system call.
//
// Frames: end-effector poses, forces and torques in H (the device frame; D
// for the bimanual device), objects' mesh-frame poses in W (the VPS scene),
// joint angles of the SIMULATED bimanual arms (read from the plant's sensors
// on the servo thread, which steps it).
#pragma once

#include <array>
#include <cstdint>
#include <functional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/concurrency/newest_mailbox.h"
#include "common/kinematics/arm7.h"
#include "operator/servo/servo_loop.h"
#include "operator/servo/timing_stats.h"

namespace hemm::device::bimanual {
class SimulatedBimanualDevice;
}

namespace hemm::op {

// Eigen's fixed-size members are not zeroed by default construction: each
// array starts from explicit values.
template <class T>
inline std::array<T, device::kMaxEndEffectors> per_end_effector(const T& v) {
  return {v, v};
}

struct DeviceViewRecord {
  std::int64_t t_ns = 0;  // the tick's device sample stamp
  std::uint64_t tick = 0;
  int end_effectors = 0;
  std::array<Eigen::Vector3d, device::kMaxEndEffectors> position_H = per_end_effector<Eigen::Vector3d>(Eigen::Vector3d::Zero());
  std::array<Eigen::Quaterniond, device::kMaxEndEffectors> orientation_H = per_end_effector(Eigen::Quaterniond::Identity());
  std::array<bool, device::kMaxEndEffectors> enabled{};
  std::array<Eigen::Vector3d, device::kMaxEndEffectors> force_H =  // commanded this tick
      per_end_effector<Eigen::Vector3d>(Eigen::Vector3d::Zero());
  std::array<Eigen::Vector3d, device::kMaxEndEffectors> torque_H = per_end_effector<Eigen::Vector3d>(Eigen::Vector3d::Zero());
  bool has_arms = false;  // the SIMULATED bimanual device: q below is valid
  std::array<kinematics::Arm7Vector, device::kMaxEndEffectors> q = per_end_effector<kinematics::Arm7Vector>(kinematics::Arm7Vector::Zero());
  int objects = 0;  // VPS objects (mesh-frame poses in W)
  std::array<Eigen::Isometry3d, device::kMaxEndEffectors> object_W = per_end_effector(Eigen::Isometry3d::Identity());
  int pairs = 0;  // right-scene, left-scene, right-left (1 with one object)
  std::array<int, 3> contacts{};
  std::array<double, 3> penetration_m{};
  std::array<double, device::kMaxEndEffectors> energy_J{};  // passivity observer so far
  std::int64_t vps_ns = 0;                                  // this tick's VPS work
};

using DeviceViewMailbox = NewestMailbox<DeviceViewRecord>;

// What a device-only run (run_vps_session, run_bimanual_session) hands a
// live view: the mailbox its task publishes to (null: no view), then the
// loop's timing once the loop runs, and the loop's end (after its last tick,
// before its timing goes away).
struct DeviceViewTaps {
  DeviceViewMailbox* ticks = nullptr;
  std::function<void(const servo::TimingStats&)> started;
  std::function<void()> stopped;
};

// The device part of a record (sample, command, the arms' joint angles if
// `arms` is not null); the task adds its own (objects, pairs). Servo thread:
// allocation-free.
void fill_device_view(const device::DeviceSample& in, const servo::TickOutput& out,
                      const device::bimanual::SimulatedBimanualDevice* arms, std::uint64_t tick,
                      DeviceViewRecord& r) noexcept;

}  // namespace hemm::op
