// A VPS session of the operator station: a device in the 1 kHz servo loop
// rendering the VPS local model (vps_task.h), with no robot and no link. The
// model is loaded before the loop starts and published once on the snapshot
// channel; the 1 kHz VPS log is drained by its writer thread.
#pragma once

#include <array>
#include <atomic>
#include <memory>
#include <string>

#include "common/haptics/vps/scenes.h"
#include "operator/device/haptic_device.h"
#include "operator/budget/work_budget_report.h"
#include "operator/device/trajectory_csv.h"
#include "operator/servo/servo_loop.h"
#include "operator/vps/vps_task.h"

namespace hemm::report {
class VpsSession;  // report.pb.h
}

namespace hemm::op {

struct VpsSessionOptions {
  servo::ServoConfig servo;
  VpsTaskParams task;
  double duration_s = 0.0;  // > 0, or until *stop
  std::string log_path;     // 1 kHz VPS log CSV ("": none)
  DeviceViewTaps view;      // a live view, if any
};

struct VpsSessionSummary {
  std::string device;
  int end_effectors = 0, objects = 0;
  std::size_t model_bytes = 0;
  servo::TimingSummary timing;             // the loop's (period, wake, compute, misses)
  servo::HistogramSummary vps_compute;     // the task's VPS work per tick
  VpsTaskStats stats;
  WorkBudgetSummary budget;                // the pairs' time-critical budget
  double coupling_k[2] = {}, coupling_b[2] = {}, coupling_k_rot[2] = {};
  double passivity_lhs[2] = {}, passivity_bound[2] = {};
  Eigen::Vector3d final_rel_01 = Eigen::Vector3d::Zero();  // object 0's origin in object 1's frame
  Eigen::Vector3d final_object_W[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::uint64_t log_written = 0, log_dropped = 0;
  bool log_failed = false;
};

// Runs `device` against `model` until duration_s of servo time (ticks x
// period) or *stop. Throws std::invalid_argument / std::runtime_error on a
// bad set-up (before the loop starts).
VpsSessionSummary run_vps_session(device::HapticDevice& device, std::shared_ptr<const VpsLocalModel> model,
                                  const VpsSessionOptions& options, const std::atomic<bool>* stop = nullptr,
                                  const std::function<void(const servo::RealtimeStatus&)>& on_start = {});

std::string to_string(const VpsSessionSummary& s);
// As proto/report.proto's VpsSession, and that printed (config::to_json).
report::VpsSession to_report(const VpsSessionSummary& s);
std::string to_json(const VpsSessionSummary& s);

// The scripted hand paths of the paper's scenes (scenes.h): each held
// object's mesh-frame pose in W against time (pure, allocation-free: callable
// on the servo thread), and how long the path lasts (it holds after).
struct SceneHands {
  vps::BimanualPoses (*at)(double t_s) = nullptr;
  double duration_s = 0.0;
};
// "peg-in-hole" or "assembly"; throws std::invalid_argument otherwise.
SceneHands scene_hands(const std::string& scene);

// The SIMULATED scripted hands of the paper's scenes as a two-end-effector
// trajectory for the ReplayDevice: each end-effector's pose is where it must
// be for its object's mesh frame to be on the path (end_effector_pose_H
// through `ee`; with the default identity mappings, the mesh-frame pose in
// W), sampled at `rate_hz` with velocities by central differences. Rigid
// hands: they do not yield to the rendered force (the worst case for the
// couplings). Throws std::invalid_argument on an unknown scene or rate.
device::Trajectory scene_hands_trajectory(const std::string& scene, double rate_hz = 1000.0,
                                          const std::array<VpsEndEffectorParams, device::kMaxEndEffectors>& ee = {});

}  // namespace hemm::op
