// RobotStation: the SIMULATED robot (SimulatedRobot, MuJoCo) joined to the
// link server (RobotServer). Two threads:
//   * the simulation thread owns the SimulatedRobot and steps it at 1 kHz to
//     absolute deadlines of the steady clock (or as fast as it can with
//     realtime = false); each tick it applies the newest command, the
//     session's requests (mode, e-stop) and the link/control state, steps,
//     and hands robot states (at state_rate_hz) and new scans (chunked) to
//     the network thread with asio::post; with depth_camera enabled, the
//     SIMULATED depth camera's frames (cast on a worker thread of the
//     SimulatedRobot, so the step is not made late) go the same way, cut
//     into DepthChunks on the network thread;
//   * the network thread (whoever runs the io_context) owns the RobotServer:
//     it validates commands and publishes them into a newest-wins mailbox,
//     queues ModeChange/EStop requests, and does every send.
//
// Safety: commands only count from the authenticated controlling operator
// while its link is up; without one the robot reports SAFETY_NO_OPERATOR and
// decelerates; with the link down it also reports SAFETY_LINK_LOST.
// A command older than the measured round trip plus link.stale_margin_ms
// (its stamp mapped to the robot's clock with the link's offset estimate),
// or arriving before there is an estimate, is refused (commands_stale). The
// watchdog counts from a command's send time, not its arrival: a command
// held on the path for t gets t less (docs/protocol.md, "Command age"). Mode
// changes need control; engaging the e-stop does not (any authenticated
// session may stop the robot), releasing it does. The robot station has its
// own e-stop too (local_estop), which only the robot station releases. An
// e-stop is never refused, not even with the request queue full. After any
// stop (e-stop, lost link, expired watchdog, no operator) the robot moves
// again only after a neutral command and then a pressed one
// (SimulatedRobot "Re-arm"; docs/security.md).
//
// Session mode: until the controlling operator sends a ModeChange, commands
// carry their own mode. After one, a command in another mode is dropped
// (counted as commands_mode_mismatch: it was sent before the change), and a
// real change stops motion at once (a neutral IDLE command) until the first
// command of the new mode. Losing control forgets the session mode.
//
// Lifetime: the RobotServer and the io_context must outlive the station; the
// handlers the station registers on the server and the work it posts hold
// only shared state, so they stay valid after the station is destroyed.
#pragma once

#include <asio.hpp>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "common/realtime/realtime_setup.h"
#include "common/realtime/timing_stats.h"
#include "robot_side/server/robot_server.h"
#include "robot_side/sim/sim_types.h"
#include "robot_side/sim/simulated_robot.h"
#include "robot_side/sim/wire_convert.h"
#include "robot_side/view/sim_view_feed.h"

namespace hemm::report {
class RobotStation;  // report.pb.h
}  // namespace hemm::report

namespace hemm::config {
class RobotConfig;
}

namespace hemm::robot {

struct RobotStationOptions {
  bool realtime = true;           // false: step back to back, faster than real time
  uint32_t state_rate_hz = 250;   // RobotState stream rate (robot/simulation time)
  size_t max_scan_payload_bytes = kMaxScanPayloadBytes;
  // Further behind schedule than this (a stall of the VM): skip ahead instead
  // of catching up step by step; the robot's clock jumps with the wall clock.
  int64_t max_catch_up_ns = 100'000'000;
  // The 1 kHz control (simulation) thread's real-time set-up (SCHED_FIFO,
  // pinning: common/realtime/realtime_setup.h); start() refuses a CPU this
  // process may not run on and logs what else is refused or risky.
  rt::RealtimeRequest control_thread{};
  int64_t late_wake_threshold_ns = 500'000;  // a later wake is a miss in control_timing
};

struct RobotStationStatistics {
  uint64_t sim_steps = 0;
  uint64_t late_steps = 0;          // steps started more than one period after their deadline
  uint64_t resyncs = 0;             // skips ahead after a stall (max_catch_up_ns)
  uint64_t contact_steps = 0;       // steps with the robot touching anything but the floor (a collision)
  uint64_t guard_states = 0;        // robot states (state rate) with the collision guard limiting the base
  int64_t max_lateness_ns = 0;      // worst start of a step after its deadline
  double mean_lateness_ns = 0.0;
  uint64_t commands_received = 0;        // authenticated Command datagrams
  uint64_t commands_without_control = 0; // dropped: sender not the controlling operator / link down
  uint64_t commands_malformed = 0;       // dropped: failed wire validation
  uint64_t commands_mode_mismatch = 0;   // dropped: not in the session's mode
  uint64_t commands_stale = 0;           // dropped: older than the measured round trip + margin (or age unknown)
  uint64_t commands_applied = 0;
  uint64_t commands_rejected = 0;        // rejected by the robot (limits, IK, arm keep-out)
  // Of those, arm targets refused because the arm would reach into ...
  uint64_t arm_refused_floor = 0;        // ... the floor
  uint64_t arm_refused_base = 0;         // ... the robot's base
  uint64_t arm_refused_scene = 0;        // ... something its sensors have seen
  uint64_t arm_refused_last_seq = 0;     // the newest refused command's sequence number
  // The 3D arm keep-out (depth camera on): seen voxels now, their memory,
  // the worst depth-frame integration (depth worker thread) and the worst
  // and mean arm check (simulation thread, per manipulation command).
  uint64_t seen_voxels = 0;
  uint64_t seen_voxel_bytes = 0;
  double seen_integrate_max_us = 0.0;
  double arm_check_max_us = 0.0, arm_check_mean_us = 0.0;
  // SIMULATION ONLY: steps with the arm touching a non-robot geom, and the
  // tool's smallest true clearance to the world (measured up to 0.10 m).
  uint64_t arm_contact_steps = 0;
  double tool_min_clearance_m = 0.10;
  uint64_t states_sent = 0;
  uint64_t scans_sent = 0;               // scans whose every chunk was sent
  uint64_t scan_chunks_sent = 0;
  uint64_t depth_frames_sent = 0;        // SIMULATED depth frames whose every chunk was sent
  uint64_t depth_chunks_sent = 0;
  uint64_t depth_frames_skipped = 0;     // due while the last was still being cast
  uint64_t depth_bytes_sent = 0;         // serialised DepthChunk stream messages
  uint64_t send_failures = 0;            // StreamLink::send returned false with the link up
  uint64_t mode_changes = 0;
  uint64_t estop_changes = 0;
  uint64_t requests_refused = 0;         // ModeChange/EStop answered with Ack ok=false
  bool estop = false;
  bool estop_local = false;              // engaged at the robot (local_estop), not by the operator
  int mode = 0;                          // session mode (wire::Mode; 0: commands choose)
  uint32_t safety = 0;                   // newest state's SafetyFlags
  // The control loop's deadline histograms (wake lateness, compute, period:
  // log-spaced) and its ten worst steps ("step", "state" when it published a
  // robot state, "scan" when also a scan); realtime pacing only.
  rt::TimingSummary control_timing;
};

// The statistics as a report message (proto/report.proto); hemm-robot's
// --stats-json prints it as the link report's "robot" object.
report::RobotStation to_report(const RobotStationStatistics& s);
// key=value fields on one line.
std::string to_log_fields(const RobotStationStatistics& s);
// A human-readable multi-line summary (ends with a newline).
std::string to_summary(const RobotStationStatistics& s);

class RobotStation {
 public:
  RobotStation(asio::io_context& io, RobotServer& server, RobotStationOptions o);
  ~RobotStation();  // stop()
  RobotStation(const RobotStation&) = delete;
  RobotStation& operator=(const RobotStation&) = delete;

  // Loads the scene and config into the simulated robot (before start()).
  std::optional<std::string> load(const config::RobotConfig& config, const std::string& scene_path);

  // Registers the station's handlers on the server and starts the simulation
  // thread with options().control_thread's real-time set-up (refused parts and
  // the machine's checks logged as warnings). Call before the io_context
  // runs or on its thread. False with *error if not loaded, already started,
  // or the CPU to pin to is not one this process may run on (nothing changed).
  bool start(std::string* error);
  // The robot's own e-stop (a key, a signal or a control command at the
  // robot station; any thread). While engaged the robot is stopped whatever
  // the operator says; only this releases it. The operator is told.
  void local_estop(bool engaged, const std::string& reason);
  // Stops and joins the simulation thread (idempotent; any thread, also the
  // network thread). The server keeps running: stop it (Bye) afterwards.
  void stop();
  bool running() const { return thread_.joinable(); }

  // SIMULATION ONLY: the live view's feed (robot_side/view), before start().
  // The simulation thread fills it at the state publication point.
  void attach_view(std::shared_ptr<SimViewFeed> feed) { view_ = std::move(feed); }

  RobotStationStatistics statistics() const;  // any thread
  RobotStateSim latest_state() const;         // any thread; updated at the state rate

  // Sensor description (valid after load(); constant afterwards).
  const SimLaserParams& laser_params() const { return robot_.laser_params(); }
  const SimSonarParams& sonar_params() const { return robot_.sonar_params(); }
  bool laser_enabled() const { return laser_on_; }
  bool depth_camera_enabled() const { return depth_on_; }
  bool sonar_enabled() const { return sonar_on_; }
  int64_t timestep_ns() const { return robot_.timestep_ns(); }
  const RobotStationOptions& options() const { return o_; }
  // Random, non-zero, fixed for this station's life (its odometry frame W):
  // sent with every state and scan, so the operator knows a restarted robot.
  uint64_t frame_epoch() const { return frame_epoch_; }

  struct Shared;  // state shared with the network thread (robot_station.cpp)

 private:
  void run();

  asio::io_context& io_;
  RobotServer& server_;
  RobotStationOptions o_;
  SimulatedRobot robot_;
  bool laser_on_ = false, sonar_on_ = false, depth_on_ = false;
  std::shared_ptr<Shared> shared_;
  std::shared_ptr<SimViewFeed> view_;
  std::thread thread_;
  int wake_latency_fd_ = -1;  // rt::hold_cpu_wake_latency while the control loop runs SCHED_FIFO
  bool attached_ = false;
  uint64_t frame_epoch_ = 0;
};

}  // namespace hemm::robot
