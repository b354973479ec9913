// The operator station's runtime: device (SIMULATED Omni with a scripted
// hand, or a replayed trajectory) -> 1 kHz ServoLoop with the
// OperatorServoTask; a ModelThread fed by the link's RobotState / RangeScan
// streams; a CommandSender on the network thread; link statistics copied into
// the servo log and the model (clock offset, command delay = RTT / 2).
// Logs: the servo's 1 kHz CSV (frame H: device, proxy, interaction point,
// force, mode, model age, RTT/offset) and, beside it, <log>.world.csv (frame
// W: robot pose, goal, proxy, force, command) and at stop <log>.map.csv (the
// final map's segments) for deploy/plots/plot_run.py.
//
// Threads: construct, start() and stop() on any thread while the io_context
// runs elsewhere or not at all; the stream handlers and the sender run on the
// io_context's thread.
#pragma once

#include <asio.hpp>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "operator/budget/work_budget_report.h"
#include "operator/client/operator_client.h"
#include "operator/device/hand_script.h"
#include "operator/device/haptic_device.h"
#include "operator/model/model_thread.h"
#include "operator/station/demo_scripts.h"
#include "operator/servo/servo_loop.h"
#include "operator/station/arm_refusals.h"
#include "operator/station/command_sender.h"
#include "operator/station/operator_task.h"

namespace hemm::report {
class OperatorStation;  // report.pb.h
}  // namespace hemm::report

namespace hemm::config {
class Probe3dConfig;  // config_operator.pb.h
class BimanualDeviceConfig;
}  // namespace hemm::config

namespace hemm::op {

struct OperatorStationOptions {
  // or "replay", or "sim-hand6" / "sim-bimanual" (need task.tool6.enabled)
  std::string device = "sim-omni";
  // device == "sim-hand6" or "sim-bimanual": the route of the SIMULATED
  // hand, an explore6 route of the scene file hand6_route_file's header
  // (explore_route.h, tool6_explorer.h load_hand6_route).
  std::string hand6_script = "explore-table";
  std::string hand6_route_file;
  // device == "sim-bimanual" (tool6_bimanual.h): the device's block (null:
  // the defaults) and where H's origin sits in the device frame D.
  std::shared_ptr<const config::BimanualDeviceConfig> bimanual;
  Eigen::Vector3d tool_device_offset_D = Eigen::Vector3d::Zero();
  std::string replay_file;          // device == "replay"
  std::string script = "idle";      // device == "sim-omni": demo_scripts.h
  // device == "sim-omni": if set, this hand instead of the script, starting
  // in task.initial_mode (tests, custom demos).
  std::shared_ptr<const device::HandScript> hand;
  // With `hand`: the view a closed-loop hand reads (the task writes it), or null.
  std::shared_ptr<OperatorView> view;
  // script == "nav-to-goal": the route in W (empty: default_nav_goal_route());
  // "nav-to-wall": the point behind the wall (empty: nav_to_wall_target()).
  std::vector<Eigen::Vector2d> goal_route;
  // script == "probe-cylinder": the probe's line in W (empty: default_probe_line()).
  std::vector<Eigen::Vector2d> probe_line;
  std::string log_path;             // empty: no logs
  double command_rate_hz = 200.0;
  // The depth camera's gaze in every command (config probe_3d.gaze).
  bool gaze = false;
  GazeParams gaze_params;
  double stats_period_s = 0.1;      // link statistics -> servo log / model
  servo::ServoConfig servo;
  ModelThreadParams model;
  OperatorTaskParams task;          // initial_mode is taken from the script (unless hand is set)
};

struct OperatorStationSummary {
  servo::TimingSummary timing;
  ModelStats model;
  CommandSenderStats commands;
  std::uint64_t mode_switches = 0;
  std::uint64_t estop_presses = 0;  // on the device (both buttons)
  std::uint64_t device_nonfinite_poses = 0;  // device samples whose pose was not finite (all motion held)
  std::uint64_t estop_acks = 0, estop_refusals = 0;  // the robot's answers to this station's EStop frames
  int robot_estop = -1;             // as the robot last reported it: 1 engaged, 0 released, -1 never reported
  ArmRefusalSummary arm_refusals;   // arm targets the robot refused, as its states reported them
  std::uint64_t servo_log_written = 0, servo_log_dropped = 0;
  std::uint64_t world_log_written = 0, world_log_dropped = 0;
  // The robot pose the servo task predicted on its last tick (W), and whether
  // the model had a RobotState by then.
  math::Pose2 robot_pose;
  bool robot_pose_valid = false;
  // script "nav-to-goal" only (has_goal): the last goal of the route, the
  // hand's state at the end, the distance from the final predicted pose.
  bool has_goal = false;
  Eigen::Vector2d goal_W = Eigen::Vector2d::Zero();
  bool arrived = false;
  double first_arrival_s = -1.0;  // device (script) time of the first arrival; -1: never
  std::uint64_t arrivals = 0;
  std::size_t goal_index = 0, route_size = 0;
  double goal_distance_m = -1.0;
  // The 6-DoF tool's time-critical budget (probe_3d tool "pointshell").
  bool has_tool6 = false;
  WorkBudgetSummary tool6_budget;
  double tool6_inferred_force_share = 0.0;  // Tool6Explorer::inferred_force_share
  std::uint64_t tool6_contact_ticks = 0, tool6_inferred_contact_ticks = 0;
};
std::string to_string(const OperatorStationSummary& s);
// The summary as a report message (proto/report.proto: units in the keys;
// unknown values left out) and as its JSON (protobuf's printer, see
// config::to_json: 64-bit counters are quoted, non-finite numbers "NaN").
report::OperatorStation to_report(const OperatorStationSummary& s);
std::string to_json(const OperatorStationSummary& s);

class OperatorStation {
 public:
  // Throws std::invalid_argument / std::runtime_error on bad options (unknown
  // script or device, unreadable replay file, bad parameters).
  OperatorStation(asio::io_context& io, OperatorClient& client, const OperatorStationOptions& o);
  ~OperatorStation();
  OperatorStation(const OperatorStation&) = delete;
  OperatorStation& operator=(const OperatorStation&) = delete;

  // Registers the stream handlers (call before the io_context runs them),
  // opens the logs, starts the model and servo threads and the sender.
  // Returns the real-time status of the servo thread. Throws on log errors.
  servo::RealtimeStatus start();
  // Stops the servo and model threads (the sender is cancelled on the io
  // thread via post), writes the map dump, closes logs. Idempotent.
  void stop();

  // Network thread: engages or releases the robot's e-stop from this station
  // (control socket, terminal key). done(reply) is called once: "ok
  // request_id=N ..." when the robot acknowledged it, "error ..." when there
  // is no link, the robot refused it, or no Ack came within ack_timeout.
  using Reply = std::function<void(const std::string& reply)>;
  void request_estop(bool engaged, const std::string& reason, Reply done);
  // Network thread: one line for a control socket's "status".
  std::string status_line() const;
  // After stop(): everything counted.
  OperatorStationSummary summary() const;

  // The live view's taps (operator/view), before start(): the model
  // thread's snapshots, the servo task's per-tick record and button presses.
  void attach_view(ModelThread::SnapshotObserver on_snapshot, NewestMailbox<StationLogRecord>* ticks,
                   std::atomic<std::uint32_t>* presses);
  // The session recorder's taps (operator/record), before start(): every
  // model step's inputs, every servo tick, every stream message received
  // (robot state, scans, depth chunks) and sent (commands), every session frame sent; the
  // stream and session taps are called on the network thread with the local
  // time.
  struct SessionTaps {
    ModelThread::StepTap on_step;
    ServoTickTap* ticks = nullptr;
    std::function<void(std::int64_t t_ns, bool outgoing, const wire::StreamMessage&)> on_stream;
    std::function<void(std::int64_t t_ns, bool outgoing, const wire::SessionFrame&)> on_session;
  };
  void attach_session_taps(SessionTaps taps);
  // The servo loop's timing, readable from any thread while it runs.
  const servo::TimingStats& servo_stats() const { return loop_->stats(); }

  // For tests: the newest snapshot handed to the servo (model thread state).
  ModelThread& model() { return *model_; }
  OperatorServoTask& task() { return *task_; }
  device::HapticDevice& device() { return *device_; }
  const CommandSender& sender() const { return *sender_; }

 private:
  void poll_link();
  void on_ack(const wire::Ack& a);
  void on_robot_estop(const wire::EStop& e);

  asio::io_context& io_;
  OperatorClient& client_;
  OperatorStationOptions o_;
  std::unique_ptr<device::HapticDevice> device_;
  servo::ModelChannel channel_;
  std::unique_ptr<ModelThread> model_;
  std::unique_ptr<servo::ServoLogger> servo_log_;
  std::unique_ptr<StationLogger> world_log_;
  std::shared_ptr<OperatorView> view_;                 // written by the task
  std::shared_ptr<NewestMailbox<OperatorView>> view_box_;  // closed-loop hands: view_ -> the hand's copy
  std::shared_ptr<const NavGoalHand> nav_goal_;       // script nav-to-goal
  std::unique_ptr<OperatorServoTask> task_;
  std::unique_ptr<servo::ServoTask> view_task_;       // closed-loop hands: task_, then publishes view_
  std::unique_ptr<servo::ServoLoop> loop_;
  std::unique_ptr<CommandSender> sender_;
  asio::steady_timer link_timer_;
  SessionTaps taps_;
  struct PendingAck {
    bool engaged = false;
    Reply done;
    std::unique_ptr<asio::steady_timer> timer;
  };
  std::map<std::uint64_t, PendingAck> pending_acks_;  // network thread
  std::uint64_t estop_acks_ = 0, estop_refusals_ = 0;
  int robot_estop_ = -1;
  ArmRefusalMonitor arm_refusals_;  // network thread
  bool started_ = false;
  bool stopped_ = false;
};

// config probe_3d (validated) -> the model's live voxmap and the task's
// 3-DoF point probe, or with tool "pointshell" the 6-DoF tool
// (tool6_explorer.h) and the SIMULATED 6-DoF hand's script; nothing changes
// when it is not enabled.
void apply_probe3d_config(const config::Probe3dConfig& c, OperatorStationOptions* o);

// Writes the map's segments as CSV (ax,ay,bx,by,nx,ny,stamp_ns,kind).
bool write_map_csv(const mapping::LocalMap& map, const std::string& path, std::string* error);

}  // namespace hemm::op
