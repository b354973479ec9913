// The operator's servo task (HEMM Sec. 3.2, Eq. 1): one virtual proxy serves
// three modes; only the map from the stylus to the proxy's goal point changes.
//
// Frames. The device reports in H (x right, y up, z towards the user); the
// workspace maps take B (x forward = away from the user, y left, z up), so
//   p_B = R_B_H p_H with x_B = -z_H, y_B = -x_H, z_B = y_H,
// and forces go back as F_H = R_B_H^T F_B, F_B = force_W_to_B(T_W_R, F_W).
//
// Modes (button 1, rising edge: exploration -> navigation -> manipulation ->
// exploration; button 2, rising edge: toggles exploration <-> navigation,
// from manipulation it goes to navigation). Both buttons down together is the
// e-stop (counted in StationSetpoint::estop_presses; the command sender sends
// it): a press of both on the same tick switches no mode, and the robot is
// held (see "Motion hold") so that a release of the e-stop moves nothing
// until the hand does:
//  - exploration (E_T_H): the stylus point mapped around the robot's present
//    (predicted) pose is the proxy's goal; the proxy rests on the map's
//    surfaces. The robot does not move (v = omega = 0, no deadman).
//  - navigation (N_T_H): the navigation point (stylus mapped ahead of the
//    robot) is the proxy's goal. The (v, omega) command is taken from the
//    PROXY's position in B, not the stylus: when a wall holds the proxy the
//    command shrinks as the robot approaches and falls into the dead band, so
//    the robot stops short of the wall while the force (the stylus pressed
//    past the proxy) grows. The point's origin is navigation_point_origin_R
//    (ahead of the chassis). Deadman on.
//  - manipulation (M_T_H): the proxy's goal is the stylus mapped into the arm's
//    box; the arm target is the proxy (so the tool is not sent into a wall),
//    clamped to the arm's reach. Deadman on.
// At a switch the new map is re-anchored (reanchor_at_switch) so the force is
// continuous, then the anchor relaxes at relax_speed (device m/s).
//
// Motion hold. The re-anchored proxy is where the OLD mode left it, so the
// new mode's command taken from it is not what the hand asks for (switching
// exploration -> navigation with the stylus centred would back the robot up;
// with the exploration proxy far ahead it would drive at full speed). So at
// start-up and at every switch the robot is held (v = omega = 0, no arm
// target, deadman released) until the hand has moved the stylus engage_move
// from where it was when the hold began AND, in navigation, the command has
// been in its dead band at least once since (a joystick's zero-start
// interlock: motion starts from rest, never at the speed the proxy happens
// to give).
//
// Dead-man (issue 23). The setpoint carries the hand's dead-man input (the
// device's: pressed when every end-effector handle that has a dead-man
// reports it pressed; a device without one never moves the robot); the
// command sender puts it on the wire. The task's motion hold and its mode
// decide what the command asks for; the dead-man whether the robot may
// follow it.
//
// A device pose that is not finite (end-effector 0's position or
// orientation) holds all motion (no dead-man, zero command, no arm target)
// instead of being read as the device origin; the interaction point stays
// where the last finite pose put it, each such tick is counted
// (nonfinite_poses, reported by the command sender off the servo thread),
// and when the pose is finite again the robot stays held until the hand has
// moved (the motion hold).
//
// The robot pose used on each tick is the snapshot's prediction extrapolated
// to the tick time with the command acting (bounded by max_extrapolation_s).
//
// A stale model (ModelThread: its newest robot data older than RTT / 2 +
// fresh_s) is not rendered at full force: the force is scaled by a gain that
// falls linearly to zero over fade_s as the model ages, and moves at most
// 1 / fade_s per second (so fresh data after an outage brings the force back
// over fade_s, not in one tick). While stale, or while a restarted robot is
// taken in, the robot is held (the motion hold below) and the view says
// invalid; when the restarted robot's map takes over the proxy starts again
// at the goal.
// The tick never allocates, locks or blocks. Setpoints go to a newest-wins
// mailbox (StationSetpoint: the servo's ServoSetpoint has no room for the
// base / arm command), a W-frame log record into an optional logger.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

#include "common/haptics/proxy/virtual_proxy.h"
#include "common/haptics/vps/point_probe.h"
#include "common/math/workspace_maps.h"
#include "operator/model/model_thread.h"
#include "operator/servo/csv_logger.h"
#include "common/concurrency/newest_mailbox.h"
#include "operator/servo/servo_loop.h"
#include "operator/servo/servo_tick_tap.h"
#include "operator/servo/spsc_ring.h"
#include "operator/station/tool6_explorer.h"
#include "wire.pb.h"

namespace hemm::op {

// Rotation taking H coordinates into B.
Eigen::Matrix3d R_B_H();

wire::Mode to_wire_mode(math::Mode m);

struct StationSetpoint {
  std::int64_t t_ns = 0;
  std::uint64_t tick = 0;
  math::Mode mode = math::Mode::kExploration;
  double v = 0.0;       // m/s (navigation)
  double omega = 0.0;   // rad/s
  Eigen::Vector3d arm_target_R = Eigen::Vector3d::Zero();  // manipulation
  bool arm_valid = false;
  bool moves_robot = false;  // the mode (and the motion hold) command motion
  bool deadman = false;      // the hand's dead-man pressed (and the pose finite)
  std::uint64_t estop_presses = 0;  // e-stop presses on the device so far (both buttons together)
  std::uint64_t nonfinite_poses = 0;  // device samples with a non-finite pose so far (all motion held)
  // The exploring tool's goal position in W (the 6-DoF tool's goal origin or
  // the 3-DoF probe's goal) for the depth camera's gaze (operator/model/
  // gaze.h); tool_valid false when no such tool is active.
  Eigen::Vector3d tool_W = Eigen::Vector3d::Zero();
  bool tool_valid = false;
};

// The device's dead-man: pressed when every end-effector handle that has a
// dead-man input reports it pressed, and at least one has one.
bool device_deadman(const device::DeviceSample& in) noexcept;

// One record per tick, W frame, for the plots (deploy/plots/plot_run.py).
struct StationLogRecord {
  std::int64_t t_ns = 0;
  std::uint32_t mode = 0;  // wire::Mode
  double robot[3] = {0, 0, 0};      // predicted T_W_R (x, y, theta)
  double goal_W[3] = {0, 0, 0};     // interaction point (proxy goal)
  double proxy_W[2] = {0, 0};
  double force_W[2] = {0, 0};       // device newtons, W axes
  double force_H[3] = {0, 0, 0};
  double v = 0.0, omega = 0.0;
  int contacts = 0;
  std::uint64_t model_version = 0;
  std::int64_t model_age_ns = -1;
  double scale = 0.0;               // W metres per device metre of the active map
  // The newest RobotState the model had (for offline evaluation against the
  // simulation's ground truth): its local stamp, odometry and SIMULATION-ONLY
  // true pose (has_truth 0 if the robot sends none; state_stamp_ns -1: none yet).
  std::int64_t state_stamp_ns = -1;
  double odom[3] = {0, 0, 0};
  double truth[3] = {0, 0, 0};
  int has_truth = 0;
  double force_gain = 1.0;          // the stale-model fade (1: fresh)
  // The 3-DoF point probe (probe_3d, exploration): its proxy in W, the force's
  // z (fw_x / fw_y are the force's x, y), whether it touches.
  double proxy3_W[3] = {0, 0, 0};
  double force_W_z = 0.0;
  int probe3_contact = 0;
  // The 6-DoF tool (tool6_explorer.h; goal_W is its goal's origin, force_W
  // its displayed force, contacts its pointshell points in contact): the
  // goal's orientation (w, x, y, z), the tool's P origin, the displayed
  // torque (W, about the goal's centre of mass), the VPS work and levels.
  double goal_q[4] = {1, 0, 0, 0};
  double tool_W[3] = {0, 0, 0};
  double torque_W[3] = {0, 0, 0};
  std::int64_t tool_work = 0;
  int tool_levels = 0;
  int tool_model = 0;  // the tick had a voxmap
};
const char* station_log_header();
std::size_t format_station_log_record(const StationLogRecord& r, char* buf, std::size_t size);
using StationLogger = servo::CsvLogger<StationLogRecord>;
inline StationLogger make_station_logger(std::size_t capacity = 8192) {
  return StationLogger(capacity, station_log_header(), &format_station_log_record);
}


// What the operator sees on the station's display, for a SIMULATED operator
// that closes the loop (the "nav-to-goal" hand, demo_scripts.h): the robot
// pose the forces are rendered with (the snapshot's prediction extrapolated to
// the tick). The task overwrites it at the end of every tick; the hand reads
// it in its at(), which SimulatedOmni::write calls right after the tick, so it
// sees the pose of the tick just finished. SERVO THREAD ONLY: both sides run
// on the servo thread (device read/write and tick), so a plain struct needs no
// atomics, locks or allocation. A hand on another thread would need a seqlock.
struct OperatorView {
  math::Pose2 T_W_R;          // predicted robot pose in W
  std::int64_t t_ns = 0;      // the tick's time
  math::Mode mode = math::Mode::kExploration;
  bool valid = false;         // false until the model has a RobotState, and while it is stale
  std::uint64_t resyncs = 0;  // robot restarts taken in: a closed-loop hand restarts its task from the robot's state
  std::uint32_t robot_safety = 0;  // the newest RobotState's SafetyFlags (wire.proto; 0: none yet)
};

struct OperatorTaskParams {
  haptics::ProxyModel proxy;
  math::DeviceWorkspace workspace;
  double exploration_range = 4.0;   // m of W the device half extent spans (sensor range)
  double navigation_look_ahead = 2.0;  // m
  // Where the navigation point sits (in R) with the stylus centred: ahead of
  // the chassis front (0.22 m) by the probe radius and a margin, so the
  // command reaches the dead band (v = 0) while the base is still clear of
  // the surface holding the proxy.
  Eigen::Vector3d navigation_point_origin_R{0.35, 0.0, 0.0};
  Eigen::Vector3d arm_base_R{0.10, 0.0, 0.30};
  Eigen::Vector3d arm_workspace_centre_R{0.35, 0.0, 0.30};
  double arm_reach = 0.5;
  double relax_speed = 0.02;  // device m/s at which a switch's anchor fades
  // Stylus travel (device m) that counts as "the hand moved" for the motion
  // hold: well above a hand's tremor on the Omni (~0.1 mm), a quarter of the
  // navigation dead band.
  double engage_move = 0.002;
  double max_extrapolation_s = 0.5;
  math::Mode initial_mode = math::Mode::kExploration;
  // The 3-DoF point probe against the live voxmap (OperatorModelSnapshot::
  // voxmap) in place of the 2D proxy's force in exploration mode (the robot
  // stands still, HEMM Fig. 9 in 3D). Its own map: the stylus centred points
  // at probe3d_origin_R, the device's horizontal half extent spans
  // probe3d_range of W (a 1 cm voxmap needs a finer scale than the 2D
  // exploration's sensor range), z included.
  bool probe_3d = false;
  vps::PointProbeParams probe3d;  // force.period is set from proxy.period
  double probe3d_range = 0.6;
  Eigen::Vector3d probe3d_origin_R{0.9, 0.0, 0.85};
  // The 6-DoF tool against the live voxmap (tool6_explorer.h), in place of
  // the 3-DoF probe's force in exploration mode; needs a 6-DoF device.
  Tool6Params tool6;
  // Manipulation through the model (probe_3d on): the same point probe runs
  // at the arm's tool tip on the live voxmap (goal: the stylus through
  // M_T_H) and the robot is sent the PROXY as the arm target, so the
  // commanded tool stops where the model has a surface and the operator
  // feels the proxy's force before the real arm touches anything. Its
  // radius is the tool's keep-out: above the robot's own scene keep-out
  // around its seen points (link radius 0.02 + clearance 0.01 + pad 0.01 =
  // 0.04 m, robot_side/control/arm_keep_out.h), by 1 cm for the two
  // models' differences (noise, voxels), so a target on the model's surface
  // is not refused by the robot.
  double tool_probe_radius = 0.05;
};

class OperatorServoTask final : public servo::ServoTask {
 public:
  // Throws std::invalid_argument on bad params. log and view may be null;
  // view, if given, is written at the end of every tick (servo thread) and
  // must outlive the task.
  explicit OperatorServoTask(const OperatorTaskParams& p, StationLogger* log = nullptr,
                             OperatorView* view = nullptr);

  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
            servo::TickOutput& out) noexcept override;

  NewestMailbox<StationSetpoint>& setpoints() noexcept { return setpoints_; }
  // Servo-thread side (or after the loop stopped).
  math::Mode mode() const noexcept { return mode_; }
  const haptics::ProxyData& proxy() const noexcept { return proxy_; }
  const vps::PointProbeData& probe3d() const noexcept { return probe3d_; }
  // The tool probe of manipulation through the model (probe_3d on).
  const vps::PointProbeData& tool_probe() const noexcept { return tool_probe_; }
  const vps::PointProbeParams& tool_probe_params() const noexcept { return tool_probe_params_; }
  const math::ScaledMap& probe3d_map() const noexcept { return probe3d_map_; }
  const Tool6Explorer* tool6() const noexcept { return tool6_.get(); }
  const math::ModeAnchor& anchor() const noexcept { return anchor_; }
  const StationSetpoint& last_setpoint() const noexcept { return last_; }
  const math::Pose2& robot_pose() const noexcept { return T_W_R_; }
  std::uint64_t mode_switches() const noexcept { return switches_; }
  std::uint64_t estop_presses() const noexcept { return estop_presses_; }
  std::uint64_t nonfinite_poses() const noexcept { return nonfinite_poses_; }
  double force_gain() const noexcept { return force_gain_; }
  // True while motion is held (see "Motion hold" above).
  bool motion_held() const noexcept { return held_; }
  std::uint64_t motion_holds() const noexcept { return holds_; }  // holds begun
  const OperatorTaskParams& params() const noexcept { return p_; }
  // The scaled map of a mode (B -> R).
  const math::ScaledMap& map_of(math::Mode m) const noexcept;
  // For the live view (before the servo starts; both may be null): every
  // tick's record (the one the world log gets) is put into `ticks`, and
  // button bits set in `presses` (by the view's keys) are taken each tick as
  // button presses. Both are lock-free: a copy and an atomic exchange.
  void set_view_outputs(NewestMailbox<StationLogRecord>* ticks,
                        std::atomic<std::uint32_t>* presses) noexcept {
    view_ticks_ = ticks;
    view_presses_ = presses;
  }
  // For the live voxmap's ROI around the probe (before the servo starts; may
  // be null): where the 3D probe's proxy is, every tick (a copy and an atomic
  // exchange).
  void set_probe_output(NewestMailbox<ProbePosition>* out) noexcept { probe_out_ = out; }
  // For the session recorder (before the servo starts; may be null): one
  // ServoTickRecord per tick.
  void set_tick_tap(ServoTickTap* tap) noexcept { tick_tap_ = tap; }
  // For tests (before the servo starts): called on the servo thread when it
  // starts and stops (an allocation counter around the whole loop).
  using ServoThreadHook = void (*)(bool started) noexcept;
  void set_servo_thread_hook(ServoThreadHook hook) noexcept { servo_hook_ = hook; }
  void on_servo_start() noexcept override {
    if (servo_hook_ != nullptr) servo_hook_(true);
  }
  void on_servo_stop() noexcept override {
    if (servo_hook_ != nullptr) servo_hook_(false);
  }

 private:
  void switch_to(math::Mode next, const Eigen::Vector3d& p_B) noexcept;
  void hold_motion(const Eigen::Vector3d& p_B) noexcept;

  OperatorTaskParams p_;
  math::ExplorationMap explore_;
  math::NavigationMap navigate_;
  math::ManipulationMap manipulate_;
  haptics::ProxyData proxy_;
  vps::PointProbeData probe3d_;
  vps::PointProbeParams tool_probe_params_;
  vps::PointProbeData tool_probe_;
  bool tool_probe_active_ = false;  // on the last tick
  Eigen::Vector3d probe3d_goal_W_ = Eigen::Vector3d::Zero();
  math::ScaledMap probe3d_map_;
  std::unique_ptr<Tool6Explorer> tool6_;  // null unless params.tool6.enabled
  mapping::MapSnapshot empty_map_;
  math::Mode mode_;
  math::ModeAnchor anchor_;
  math::Pose2 T_W_R_;
  Eigen::Vector3d goal_W_ = Eigen::Vector3d::Zero();
  std::uint32_t buttons_prev_ = 0;
  std::uint64_t estop_presses_ = 0;
  std::uint64_t nonfinite_poses_ = 0;
  Eigen::Vector3d p_B_last_ = Eigen::Vector3d::Zero();  // the newest finite stylus point (B)
  bool first_ = true;
  std::uint64_t switches_ = 0;
  double force_gain_ = 1.0;         // stale-model fade
  std::uint64_t resyncs_seen_ = 0;
  bool held_ = true;
  bool hold_moved_ = false, hold_neutral_ = false;
  Eigen::Vector3d hold_ref_B_ = Eigen::Vector3d::Zero();
  std::uint64_t holds_ = 0;
  std::uint64_t ticks_ = 0;
  StationSetpoint last_;
  NewestMailbox<StationSetpoint> setpoints_;
  StationLogger* log_;
  OperatorView* view_;
  NewestMailbox<StationLogRecord>* view_ticks_ = nullptr;
  NewestMailbox<ProbePosition>* probe_out_ = nullptr;
  std::atomic<std::uint32_t>* view_presses_ = nullptr;
  ServoTickTap* tick_tap_ = nullptr;
  ServoThreadHook servo_hook_ = nullptr;
  ServoTickRecord tap_record_;  // filled in place (no large stack copy per tick)
};

}  // namespace hemm::op
