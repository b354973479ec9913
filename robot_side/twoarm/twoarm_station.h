// TwoArmStation: the SIMULATED two-arm robot (TwoArmRobot, MuJoCo workbench)
// joined to the link server (RobotServer), in the shape of the mobile
// robot's RobotStation (robot_side/station/robot_station.h). Threads:
//   * the control thread owns the TwoArmRobot and steps it at 1 kHz to
//     absolute deadlines of the steady clock (or back to back with
//     realtime = false; after a stall longer than max_catch_up_ns it skips
//     ahead). Each tick it reads the link and control state, the e-stops and
//     the session mode (atomics), applies the newest already-validated
//     command from a newest-wins mailbox, steps, and at state_rate_hz (robot
//     time) copies a TwoArmSnapshot into another mailbox. It never
//     allocates, locks, logs or touches a socket;
//   * the network thread (whoever runs the io_context) owns the RobotServer:
//     it checks each ArmsCommand (controlling operator, link up, age),
//     validates it whole against the newest snapshot's readings
//     (validate_arms_command: finite, known arms and grippers, poses, the
//     jump and the inverse-kinematics reach check) and publishes it; answers
//     ModeChange/EStop frames; and sends the ArmsState of each new snapshot
//     (a timer polls the mailbox every millisecond) and every depth frame;
//   * with the head depth camera on, a worker thread casts the SIMULATED
//     camera (robot_side/sim/depth_camera.h, from the scene's head_depth
//     camera) on a copy of the geoms' poses the control thread hands over,
//     so the control step is never made late; a frame due while the last is
//     still being cast is skipped (counted).
//
// Safety is the mobile station's (docs/protocol.md, docs/security.md):
// commands count only from the authenticated controlling operator while the
// link is up; a command older than the measured round trip plus
// link.stale_margin_ms (or before there is a clock estimate) is dropped as
// stale; the watchdog counts from a command's send time. Without an operator
// or a link both arms hold in impedance and the grippers keep their grip
// (TwoArmRobot); motion resumes only after a neutral and then a pressed
// command. Engaging the e-stop needs any authenticated session, releasing it
// control; the robot's own e-stop (local_estop) is released only there.
// Until a ModeChange commands carry their own mode; after one, a command of
// another mode is dropped (commands_mode_mismatch), a real change holds the
// arms until the first command of the new mode, and losing control forgets
// the mode.
//
// Refusals: the network thread keeps the refusal record (count, newest
// reason, sequence number, index) and reports it in every ArmsState; a
// refused command never reaches the control thread, so it changes nothing
// and feeds no watchdog.
//
// Lifetime: the RobotServer and the io_context must outlive the station.
#pragma once

#include <asio.hpp>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/kinematics/arm7.h"
#include "common/realtime/realtime_setup.h"
#include "common/realtime/timing_stats.h"
#include "robot_side/server/robot_server.h"
#include "robot_side/twoarm/task_truth.h"
#include "robot_side/twoarm/twoarm_robot.h"
#include "robot_side/view/twoarm_view_feed.h"

namespace hemm::report {
class TwoArmStation;  // report.pb.h
}  // namespace hemm::report

namespace hemm::config {
class RobotConfig;
}

namespace hemm::twoarm {

struct TwoArmStationOptions {
  bool realtime = true;          // false: step back to back, faster than real time
  uint32_t state_rate_hz = 250;  // ArmsState stream rate (robot time)
  int64_t max_catch_up_ns = 100'000'000;
  rt::RealtimeRequest control_thread{};
  int64_t late_wake_threshold_ns = 500'000;
  // Called on the control thread with true before its loop and false after
  // it (e.g. a test counting that thread's heap allocations); may be empty.
  std::function<void(bool)> control_thread_hook;
  // SIMULATION ONLY: keep the task judge's look at the truth every 10 ms of
  // robot time, for up to this many seconds (0: none; memory reserved at
  // start(), about 25 kB per second; see truth_trace()).
  double truth_trace_s = 0.0;
};

// SIMULATION ONLY: one row of the truth trace (robot time; A = W here).
struct TruthTraceRow {
  double t_s = 0.0;
  // The robot's steady clock then [s] (its state stamps' time base): on one
  // host it lines up with hemm-operator --hand-trace's clock_s.
  double clock_s = 0.0;
  std::array<Eigen::Vector3d, kArms> G_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};       // the grasp sites
  std::array<Eigen::Vector3d, kArms> G_rot_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};   // their orientation (rotation vector)
  std::array<Eigen::Vector3d, kArms> target_rot_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<Eigen::Vector3d, kArms> target_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // the targets worked to
  std::array<Eigen::Vector3d, kArms> force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};   // contact on each gripper
  std::array<double, kArms> squeeze_N{};  // each gripper's two pads
  std::array<int, kArms> pads_on_object{};
  double object_env_N = 0.0;
  bool on_start = false, on_goal = false, on_other = false;
  double goal_xy_err_m = 0.0, goal_z_err_m = 0.0, tilt_rad = 0.0;
};
// The trace as CSV, a header line first.
std::string truth_trace_csv(const std::vector<TruthTraceRow>& rows);

// The robot's options from config: twoarm (impedance, limits, avoidance,
// jump) and safety.watchdog_ms. The config is validated already
// (config::load_robot_config).
TwoArmRobotOptions two_arm_robot_options(const config::RobotConfig& config);

inline constexpr int kArmsRefusalReasons = 8;  // wire::ArmsRefusalReason 0..7

struct TwoArmStationStatistics {
  uint64_t sim_steps = 0;
  uint64_t late_steps = 0;  // steps started more than one period after their deadline
  uint64_t resyncs = 0;     // skips ahead after a stall (max_catch_up_ns)
  int64_t max_lateness_ns = 0;
  double mean_lateness_ns = 0.0;
  uint64_t commands_received = 0;         // authenticated ArmsCommand datagrams
  uint64_t commands_without_control = 0;  // dropped: not the controlling operator / link down
  uint64_t commands_stale = 0;            // dropped: older than the round trip + margin (or age unknown)
  uint64_t commands_mode_mismatch = 0;    // dropped: not in the session's mode
  uint64_t commands_refused = 0;          // refused by validation (by reason below)
  std::array<uint64_t, kArmsRefusalReasons> refused_by_reason{};  // index: wire::ArmsRefusalReason
  uint64_t commands_accepted = 0;  // valid, offered to the robot (watchdog, re-arm gate)
  uint64_t commands_applied = 0;   // their targets followed (armed, dead-man pressed)
  // Arm targets taken within the reach margin (ArmsCommandLimits), not
  // reached within the joint limits, and the largest such errors.
  uint64_t targets_at_reach_edge = 0;
  double max_reach_error_m = 0.0, max_reach_error_rad = 0.0;
  int last_refusal = 0;            // wire::ArmsRefusalReason
  uint64_t last_refused_seq = 0;
  uint32_t last_refused_index = 0;
  std::string last_refusal_detail;
  rt::HistogramSummary validate;         // per command on the network thread (inverse kinematics)
  rt::HistogramSummary control_compute;  // both arms' controllers per tick (TwoArmRobot::control_compute)
  uint64_t states_sent = 0;
  uint64_t send_failures = 0;
  uint64_t depth_frames_sent = 0;  // SIMULATED head depth frames whose every chunk was sent
  uint64_t depth_chunks_sent = 0;
  uint64_t depth_frames_skipped = 0;  // due while the last was still being cast
  uint64_t depth_bytes_sent = 0;
  uint64_t mode_changes = 0;
  uint64_t estop_changes = 0;
  uint64_t requests_refused = 0;  // ModeChange/EStop answered with Ack ok=false
  bool estop = false, estop_local = false;
  int mode = 0;  // session mode (wire::Mode; 0: commands choose)
  uint32_t safety = 0;  // the newest snapshot's SafetyFlags
  bool armed = false, following = false;
  rt::TimingSummary control_timing;  // realtime pacing only
  // The direct mode (robot end): each arm's TDPA port as of the newest
  // snapshot, and what the direct commands did.
  std::array<haptics::tdpa::ArmPortSummary, kArms> passivity{};
  bool passivity_controller = true;
  uint64_t direct_commands = 0;     // applied with a DirectTwist
  uint64_t direct_stale_ticks = 0;  // direct ticks with a twist older than direct_twist_hold_ms (zeroed)
  uint64_t passivity_peer_old = 0;      // operator energies older than the newest taken
  uint64_t passivity_peer_refused = 0;  // refused on the control thread (receive_peer)
  // SIMULATION ONLY: the task judged from MuJoCo truth (config twoarm.task),
  // as of the newest state publication (and the control loop's end).
  bool task_judged = false;
  Task task = Task::kBox;
  TaskVerdict task_verdict;
  long task_ticks = 0;
  double task_lift_time_s = -1.0;
};

report::TwoArmStation to_report(const TwoArmStationStatistics& s);
std::string to_log_fields(const TwoArmStationStatistics& s);
std::string to_summary(const TwoArmStationStatistics& s);  // multi-line, ends with a newline

// SIMULATION ONLY: MuJoCo's truth at a state publication (for tests and
// evaluation, never streamed): each arm's grasp site in A.
struct TwoArmTruthSim {
  int64_t stamp_ns = 0;
  std::array<Eigen::Isometry3d, kArms> T_A_G{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
};

class TwoArmStation {
 public:
  TwoArmStation(asio::io_context& io, robot::RobotServer& server, TwoArmStationOptions o);
  ~TwoArmStation();  // stop()
  TwoArmStation(const TwoArmStation&) = delete;
  TwoArmStation& operator=(const TwoArmStation&) = delete;

  // Loads the scene with the config's two-arm block and head depth camera
  // (depth_camera: enabled, size, field of view, ranges, rate; mount unset or
  // "head": the scene's head_depth camera). Before start().
  std::optional<std::string> load(const config::RobotConfig& config, const std::string& scene_path);
  // SIMULATION ONLY: the live view's feed (robot_side/view/twoarm_view.h),
  // filled by the control thread at its state publications. After load(),
  // before start(); an error if the scene's state does not fit a frame.
  std::optional<std::string> attach_view(std::shared_ptr<robot::TwoArmViewFeed> feed);
  // Registers the handlers on the server and starts the control thread (and
  // the depth worker). Call before the io_context runs or on its thread.
  bool start(std::string* error);
  // The robot's own e-stop (any thread); only this releases it.
  void local_estop(bool engaged, const std::string& reason);
  void stop();  // joins the control thread and the worker (idempotent)
  bool running() const { return thread_.joinable(); }

  TwoArmStationStatistics statistics() const;  // any thread
  // SIMULATION ONLY: the newest truth (any thread; false before the first).
  bool truth_sim(TwoArmTruthSim* out) const;
  // SIMULATION ONLY: the truth trace (options().truth_trace_s), complete
  // once stop() returned; empty while running, without a task or with it off.
  const std::vector<TruthTraceRow>& truth_trace() const;

  bool depth_camera_enabled() const { return depth_on_; }
  int64_t timestep_ns() const;
  const TwoArmModel& model() const;  // after load()
  uint64_t frame_epoch() const { return frame_epoch_; }
  const TwoArmStationOptions& options() const { return o_; }

  struct Shared;  // state shared with the network thread (twoarm_station.cpp)
  struct DepthWorker;

 private:
  void run();

  asio::io_context& io_;
  robot::RobotServer& server_;
  TwoArmStationOptions o_;
  std::unique_ptr<TwoArmRobot> robot_;
  std::unique_ptr<const TaskTruthModel> task_model_;  // SIMULATION ONLY: the judge, if a task is set
  // Sized at start(), filled by the control thread only (no allocation
  // there), cut to the rows written when it has stopped.
  std::vector<TruthTraceRow> trace_;
  std::size_t trace_rows_ = 0;
  uint64_t trace_period_steps_ = 10;  // 10 ms of robot time in simulation steps
  bool depth_on_ = false;
  int depth_period_steps_ = 0;
  std::shared_ptr<Shared> shared_;
  std::unique_ptr<DepthWorker> depth_;
  std::shared_ptr<robot::TwoArmViewFeed> view_;
  std::thread thread_;
  int wake_latency_fd_ = -1;
  bool attached_ = false;
  uint64_t frame_epoch_ = 0;
};

}  // namespace hemm::twoarm
