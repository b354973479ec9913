// The servo task of the VPS local model (bimanual paper, Sec. 4): every
// end-effector holds a virtual object through a 6-DoF virtual coupling; each
// tick computes the contact wrenches of the three pairs (right-scene,
// left-scene, right-left; one pair with one object), steps both couplings,
// and sends each coupling's reaction to its end-effector. Written against the
// generic device API: one or two end-effectors, force-only or force+torque.
//
// Frames: the device reports end-effector poses in H; T_W_H places H in the
// scene frame W (motion scale 1, as in the paper); the object's mesh frame M
// sits at T_E_M in the end-effector frame E (the grasp). The coupling acts on
// the object's centre-of-mass frame C (mesh axes). Wrenches go to the device
// at the end-effector point, in H.
//
// Gains: design_coupling from each end-effector's limits (sampled-data
// passivity condition, peak force, stiffness), per device. A passivity
// observer per end-effector integrates the power the device delivers to the
// hand, F.v + tau.omega, over the run.
//
// Real time: the scene is static, so the task holds its model (published on
// the channel for other readers; the snapshot handed to tick() is not used);
// every per-pair state is sized at construction. tick() allocates nothing,
// takes no lock and makes no system call (the steady clock is read through
// the vDSO). The three pairs run within the tick in the time-critical mode
// (coarse to fine, all pairs per level, until the budget is spent), which
// bounds the tick's VPS work whatever the contact state. The budget is time
// (tick_budget_ns, and never past the tick's deadline less tick_margin_ns)
// turned into work units with the cost per unit measured on this machine:
// a calibration on the loaded model in the constructor, then every tick's
// own time (common/haptics/vps/work_budget.h); `budget` caps it in units.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

#include "common/haptics/vps/coupling.h"
#include "common/haptics/vps/work_budget.h"
#include "operator/servo/csv_logger.h"
#include "operator/servo/servo_loop.h"
#include "operator/servo/timing_stats.h"
#include "operator/view/device_view_record.h"
#include "operator/vps/vps_model.h"

namespace hemm::op {

struct VpsEndEffectorParams {
  Eigen::Isometry3d T_W_H = Eigen::Isometry3d::Identity();  // device frame in the scene
  Eigen::Isometry3d T_E_M = Eigen::Isometry3d::Identity();  // object mesh frame in the end-effector frame
};

// The one mapping from an end-effector's pose in H to where it wants its
// object's mesh frame in W (T_W_M = T_W_H T_H_E T_E_M), used by tick(); and
// its inverse, where the end-effector must be for the object to sit at T_W_M:
// a scene's scripted object paths become device paths through it (the rigid
// hands' replay, the SIMULATED bimanual humans' targets).
inline Eigen::Isometry3d object_pose_W(const VpsEndEffectorParams& e, const Eigen::Isometry3d& T_H_E) {
  return e.T_W_H * T_H_E * e.T_E_M;
}
inline Eigen::Isometry3d end_effector_pose_H(const VpsEndEffectorParams& e, const Eigen::Isometry3d& T_W_M) {
  return e.T_W_H.inverse() * T_W_M * e.T_E_M.inverse();
}

struct VpsTaskParams {
  std::array<VpsEndEffectorParams, device::kMaxEndEffectors> ee{};
  double period_s = 1e-3;
  // Work budget per tick (sphere nodes + points, all pairs); kUnlimitedWork:
  // no cap in units.
  std::int64_t budget = vps::kUnlimitedWork;
  // Time budget per tick of the pairs (0: none; with no work budget either,
  // the full three-pair cycle), and how long before the tick's deadline
  // (TickOutput::deadline_ns, when the loop gives one) they must end.
  std::int64_t tick_budget_ns = 200'000;
  std::int64_t tick_margin_ns = 100'000;
  int calibration_poses = 24;  // per pair, for the cost per unit at start
  vps::CouplingDesignOptions design;
  // Hand speeds the damping budget is checked at (device limits' max speed
  // when it has one).
  double max_speed = 0.1, max_angular_speed = 1.0;
};

// One record per tick for the plots (W frame for poses, H for wrenches).
struct VpsLogRecord {
  std::int64_t t_ns = 0;
  int end_effectors = 0;
  double device_W[2][3] = {};   // end-effector positions
  double object_W[2][3] = {};   // object mesh-frame origins
  double force_H[2][3] = {};    // commanded
  double torque_H[2][3] = {};
  double energy_J[2] = {};      // passivity observer: energy delivered to the hand so far
  int contacts[3] = {};         // right-scene, left-scene, right-left
  double max_penetration[3] = {};
  double rel_01[3] = {};        // object 0's mesh origin in object 1's mesh frame
  std::int64_t vps_ns = 0;      // this tick's VPS work (pairs + couplings), steady clock
  std::int64_t work = 0;        // sphere nodes + points
  int levels = 0;               // time-critical: levels completed
};
const char* vps_log_header();
std::size_t format_vps_log_record(const VpsLogRecord& r, char* buf, std::size_t size);
using VpsLogger = servo::CsvLogger<VpsLogRecord>;
inline VpsLogger make_vps_logger(std::size_t capacity = 16384) {
  return VpsLogger(capacity, vps_log_header(), &format_vps_log_record);
}

// What the task measured; read after the loop stopped (or any time: every
// field is written by the servo thread only, so a live read may be stale).
struct VpsTaskStats {
  std::uint64_t ticks = 0;
  double max_penetration[3] = {};  // per pair over the run [m]
  int max_contacts[3] = {};
  double energy_J[2] = {};         // passivity observer at the end
  double max_energy_J[2] = {};     // its maximum over the run (> 0: energy was generated)
  double min_energy_J[2] = {};     // the most the hand put in
  double max_force_N[2] = {}, max_torque_Nm[2] = {};
  std::int64_t max_work = 0;
};

class VpsServoTask final : public servo::ServoTask {
 public:
  // `model` must have at most `limits.end_effectors` objects; the couplings
  // are designed from `limits`. Throws std::invalid_argument on bad params or
  // limits. Allocates every per-tick buffer here. log may be null.
  VpsServoTask(std::shared_ptr<const VpsLocalModel> model, const device::DeviceLimits& limits,
               const VpsTaskParams& params, VpsLogger* log = nullptr);

  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& snapshot,
            servo::TickOutput& out) noexcept override;

  const VpsTaskStats& stats() const noexcept { return stats_; }
  // The time-critical budget: how often it stopped early, the levels
  // completed, the measured cost per unit (and the calibration at start).
  const vps::WorkBudgetStats& budget_stats() const noexcept { return budget_.stats(); }
  const vps::WorkRateCalibration& calibration() const noexcept { return calibration_; }
  const servo::LatencyHistogram& vps_compute() const noexcept { return vps_ns_; }
  const vps::CouplingDesign& coupling(int k) const { return design_[static_cast<std::size_t>(k)]; }
  // Servo thread (or after the loop stopped): object k's mesh-frame pose in W.
  Eigen::Isometry3d object_pose(int k) const;
  const VpsLocalModel& model() const noexcept { return *model_; }
  // A live view's feed (device_view_record.h), before the loop starts: each
  // tick is published there; `arms` (may be null) is the SIMULATED bimanual
  // device whose joint angles go with it (read on the servo thread).
  void set_view(DeviceViewMailbox* ticks, const device::bimanual::SimulatedBimanualDevice* arms) noexcept {
    view_ = ticks;
    view_arms_ = arms;
  }

 private:
  std::shared_ptr<const VpsLocalModel> model_;
  VpsTaskParams p_;
  int objects_;
  std::array<vps::CouplingDesign, device::kMaxEndEffectors> design_;
  std::array<vps::RigidBodyState, device::kMaxEndEffectors> body_;
  std::array<Eigen::Isometry3d, device::kMaxEndEffectors> T_C_M_;  // mesh frame in the centre-of-mass frame
  std::array<bool, device::kMaxEndEffectors> started_{};
  vps::BimanualState bimanual_state_;
  vps::PairState single_state_;
  vps::BimanualData data_;
  vps::WorkRateCalibration calibration_;
  vps::TickWorkBudget budget_;
  VpsTaskStats stats_;
  servo::LatencyHistogram vps_ns_;
  VpsLogger* log_;
  DeviceViewMailbox* view_ = nullptr;
  const device::bimanual::SimulatedBimanualDevice* view_arms_ = nullptr;
};

// Limits of SIMULATED rigid scripted hands as a two-end-effector device (the
// replayed paths of the paper's scenes): device::rigid_hand_limits.
device::DeviceLimits scripted_hands_limits(int end_effectors = 2);

}  // namespace hemm::op
