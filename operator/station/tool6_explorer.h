// 6-DoF exploration of the live voxmap in the networked operator station
// (issue 13, exploration mode, the robot standing still): the robot's probe
// tool (common/haptics/vps/probe_tool.h: a pointshell of its last link and
// tip) held by end-effector 0 of a 6-DoF device through the 6-DoF virtual
// coupling, rendered with VPS against the newest model snapshot's voxmap.
//
// Mapping (motion scale 1, as the bimanual paper maps its arms to objects):
// H has R's axes and its origin at origin_R in the robot frame, and the tool
// frame P is the end-effector frame E turned by R_E_P (tip at the E point,
// rod along P's z), so the hand wants the tool at
// T_W_P = T_W_R T_R_H T_H_D T_D_E R_E_P, with T_W_R the task's predicted
// robot pose and T_D_E the device's end-effector pose in its own frame D.
// The coupling's reaction goes to the device at the E point in D (force, and
// torque when the device renders it).
//
// Devices: the SIMULATED rigid 6-DoF scripted hand (device type "sim-hand6":
// a replayed pose path that does not yield to the force, with the limits of
// an LWR-class arm, device::rigid_hand_limits; D = H, P = E), or the right
// arm of the SIMULATED bimanual device ("sim-bimanual", tool6_bimanual.h:
// its SIMULATED human follows the same script mapped into D, and yields).
// Scripts: the explore6 routes of a scene file's header (explore_route.h,
// load_hand6_route), e.g. deploy/scenes/home.xml's "explore-table" (presses
// and slides on the tops and the robot-facing sides of the block, the book
// and the mug, the robot at W (1.5, 1.0) facing +y) and "explore-block" (the
// block's top, pressed, slid, tilted, and its front side).
//
// Real time: tick() allocates nothing and takes no lock; the VPS work per
// tick is bounded in time (time-critical mode, common/haptics/vps/
// work_budget.h: tick_budget_ns, never past the tick's deadline less
// tick_margin_ns, over the measured cost of a work unit: calibrated here on
// a box voxmap of the live voxmap's resolution, then updated every tick on
// the live one) and capped by `budget` in units; the pair state belongs to
// one voxmap build (the snapshot's voxmap_builds) and is reset when another
// build comes, even one published at the address of the old (freed) one;
// no voxmap -> zero wrench.
#pragma once

#include <cstdint>
#include <string>

#include "common/haptics/vps/probe_tool.h"
#include "common/haptics/vps/work_budget.h"
#include "common/math/workspace_maps.h"
#include "operator/device/haptic_device.h"
#include "operator/device/trajectory_csv.h"

namespace hemm::op {

struct StationLogRecord;  // operator_task.h

struct Tool6Params {
  bool enabled = false;
  vps::ProbeToolGeometry geometry;
  // Pressure stiffness (N/m^3): the tip pressed 2.4 mm into a plane holds
  // 10.7 N (a 3.6 mm lead of the hand on the LWR-class coupling's 3000 N/m),
  // a quarter of the 1 cm live voxmap's voxel.
  double contact_stiffness = 3e7;
  // Factor on inferred voxels' stiffness (vps::ContactParams), in (0, 1].
  double inferred_stiffness_scale = 1.0;
  std::int64_t budget = 4000;  // VPS work per tick (sphere nodes + points): time-critical mode
  // ... and in time (0: none): at most this per tick, ending tick_margin_ns
  // before the tick's deadline; the cost per unit calibrated on a box voxmap
  // of the live voxmap's voxel size and layers.
  std::int64_t tick_budget_ns = 200'000;
  std::int64_t tick_margin_ns = 100'000;
  double calibration_voxel = 0.01;
  int calibration_layers = 4;
  Eigen::Vector3d origin_R{0.85, 0.0, 0.95};  // H's origin in R
  device::EndEffectorLimits limits = device::rigid_hand_limits(1).ee[0];  // end-effector 0 (the station sets it)
  // The device's frame (D) in H, and the tool frame P in the end-effector
  // frame E (a rotation: the tip stays at the E point). Identity for
  // sim-hand6, whose frame is H and whose E is P; sim-bimanual:
  // tool6_bimanual.h (H = D shifted, P turned so the tool starts upright in
  // the hand's resting grasp).
  Eigen::Isometry3d T_H_D = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d R_E_P = Eigen::Matrix3d::Identity();
  double period_s = 1e-3;
};
std::string validate(const Tool6Params& p);

class Tool6Explorer {
 public:
  // Builds the tool and designs the coupling from p.limits (allocates);
  // throws std::invalid_argument on bad parameters.
  explicit Tool6Explorer(const Tool6Params& p);

  // Servo thread: one tick for the end-effector sample s (H), the robot pose
  // (W) and the snapshot's voxmap (null: none yet) with its build number;
  // deadline_ns: the tick's (TickOutput::deadline_ns; 0: unknown).
  void tick(const device::EndEffectorSample& s, const math::Pose2& T_W_R, const vps::Voxmap* vm,
            std::uint64_t voxmap_build, std::int64_t deadline_ns = 0) noexcept;
  // The wrench to display, scaled by gain (the stale-model fade), into c.
  void write(double gain, device::EndEffectorCommand& c) const noexcept;
  // The tick's goal pose, tool pose, displayed wrench (W) into the log record.
  void fill(double gain, StationLogRecord& r) const noexcept;

  const vps::ProbeTool& tool() const noexcept { return tool_; }
  const vps::ToolParams& tool_params() const noexcept { return params_; }
  const vps::ToolState& state() const noexcept { return state_; }
  const Eigen::Isometry3d& goal_W() const noexcept { return goal_W_; }
  const Tool6Params& params() const noexcept { return p_; }
  // The time-critical budget: calibration at start and what it did.
  const vps::WorkRateCalibration& calibration() const noexcept { return calibration_; }
  const vps::TickWorkBudget& budget() const noexcept { return budget_; }
  // The work of the last tick (0 without a voxmap).
  std::int64_t work() const noexcept { return state_.contact.nodes_visited + state_.contact.points_tested; }
  // Over the run so far: the share of the displayed force that came from
  // inferred voxels (each tick's |F| weighted by its contact's
  // vps::inferred_share), and the ticks in contact (with inferred contact).
  double inferred_force_share() const noexcept { return felt_sum_ > 0.0 ? felt_inferred_sum_ / felt_sum_ : 0.0; }
  std::uint64_t contact_ticks() const noexcept { return contact_ticks_; }
  std::uint64_t inferred_contact_ticks() const noexcept { return inferred_contact_ticks_; }

 private:
  Tool6Params p_;
  vps::ProbeTool tool_;
  vps::ToolParams params_;
  vps::ToolState state_;
  vps::WorkRateCalibration calibration_;
  vps::TickWorkBudget budget_;
  Eigen::Isometry3d goal_W_ = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d R_W_D_ = Eigen::Matrix3d::Identity();
  std::uint64_t voxmap_build_ = 0;  // the build the pair state belongs to
  double felt_sum_ = 0.0, felt_inferred_sum_ = 0.0;
  std::uint64_t contact_ticks_ = 0, inferred_contact_ticks_ = 0;
  bool valid_ = false;
};

// The tool and its parameters as key value lines (robot_side/truth/
// tool6_truth.h reads them for the SIMULATION-ONLY truth), and a voxmap's
// surface voxels (x,y,z,sdf: layer 0) as CSV for the demo's image. Off the
// servo thread; false with *error when the file cannot be written.
bool write_tool6_params(const Tool6Explorer& t, const std::string& path, std::string* error);
bool write_voxmap_csv(const vps::Voxmap& vm, const std::string& path, std::string* error);
// The voxmap and the tool's pointshell as a .vps buffer (common/haptics/vps/cache.h), for
// replaying a run against the final live voxmap offline (hemm-truth --tool6 --against).
bool write_voxmap_vps(const vps::Voxmap& vm, const vps::PointShell& shell, const std::string& path,
                      std::string* error);

// The robot pose as an SE(3) transform (z = 0, yaw theta).
Eigen::Isometry3d robot_pose3(const math::Pose2& T_W_R);

// The SIMULATED hand's pose path (H, see above) along a route of a scene
// file's header (explore_route.h: tip centres in R) for a tool whose H
// origin sits at origin_R.
struct ExploreRoute;
device::Trajectory make_hand6_trajectory(const ExploreRoute& route, const Eigen::Vector3d& origin_R);
// The route `name` of the scene file at scene_path, checked against the
// device's end-effector limits (check_route_reach); throws
// std::invalid_argument ("probe_3d.tool_hand_route: FILE:LINE: reason", or
// ...tool_hand_script: for an unknown route or one out of reach).
device::Trajectory load_hand6_route(const std::string& scene_path, const std::string& name,
                                    const Eigen::Vector3d& origin_R, const device::EndEffectorLimits& limits);

}  // namespace hemm::op
