// hemm-operator's runners, one file each, and what they share: the parsed
// command line (OperatorArgs, filled by operator/main.cpp; CLI11 stays
// there) and the set-up every runner needs (servo rate, logging, the local
// runs' stop signal, the station JSON).
//   station_runner.cpp   the networked station: SIMULATED Omni (HEMM), a
//                        replayed trajectory, the 3D probe / exploration
//                        (probe_3d), the 6-DoF tool in the bimanual device
//   vps_runner.cpp       a config's VPS scene with the device, no robot
//   bimanual_runner.cpp  the SIMULATED bimanual device alone, no robot
//   replay_runner.cpp    --replay of a session recording, --export-mcap
//   telemanip_runner.cpp the bimanual device drives the two-arm robot (telemanip block)
// Only hemm-operator's own files include this (it carries the build's
// HEMM_WITH_VIEW / HEMM_OPERATOR_HAVE_VPS choices).
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <iostream>
#include <string>
#include <vector>

#include "common/net/exit_codes.h"
#include "common/net/station_cli.h"
#include "config_operator.pb.h"
#include "operator/servo/servo_loop.h"
#ifdef HEMM_WITH_VIEW
#include "common/view/view_options.h"
#endif
#if defined(HEMM_WITH_VIEW) && defined(HEMM_OPERATOR_HAVE_VPS)
#define HEMM_DEVICE_VIEW 1  // the device-only runs' view (operator/view/device_live_view.h)
#include "operator/view/device_live_view.h"
#endif

namespace hemm::op {
struct OperatorClientOptions;  // operator/client/operator_client.h
struct Recording;              // operator/record/session_recording.h
}  // namespace hemm::op

namespace hemm::op::runner {

// The command line, parsed and checked (operator/main.cpp).
struct OperatorArgs {
  std::string config_path, key_path, robot, log_level = "info", stats_json;
  int session_port = -1, stream_port = -1;  // -1: the config's
  unsigned test_version = 0;
  double duration_s = 0.0, stats_period_s = 0.0;
  std::string script = "idle";
  bool script_given = false;  // --script was on the command line
  std::vector<Eigen::Vector2d> goal_route, probe_line;
  std::string shape_completion = "on";
  // The live voxmap's switches (empty: the config's probe_3d values).
  std::string shape_completion_3d, unknown_solid, inferred_stiffness;
  std::string station_json, servo_log, replay_file, record_path, replay_json;
  std::string hand_trace;  // telemanip: --hand-trace FILE.csv
  double replay_speed = 1.0;
  std::vector<std::string> export_mcap;  // REC OUT, or empty
  net::StationControlOptions control_options;
  std::string device_type, bimanual_hands;
  int servo_cpu = -1;              // --servo-cpu (overrides servo.cpu when given)
  bool servo_cpu_given = false;
  std::string simulated_hardware;  // --simulated-hardware, or empty
#ifdef HEMM_WITH_VIEW
  view::ViewOptions view_opts;
#endif
};

// The runners: each returns the process's exit code (common/net/exit_codes.h).
int run_station(const config::OperatorConfig& cfg, const OperatorArgs& a);
#ifdef HEMM_OPERATOR_HAVE_VPS
int run_vps(const config::OperatorConfig& cfg, const OperatorArgs& a);
#endif
int run_bimanual(const config::OperatorConfig& cfg, const OperatorArgs& a);
#ifdef HEMM_OPERATOR_HAVE_TELEMANIP
int run_telemanip(const config::OperatorConfig& cfg, const OperatorArgs& a);
// --replay of a telemanip session's recording (replay_recording hands it on).
int replay_telemanip_recording(const Recording& rec, const OperatorArgs& a);
#endif
int replay_recording(const OperatorArgs& a);
int export_recording_as_mcap(const std::string& in, const std::string& out);

// --- shared set-up ---

// The servo loop's period and real-time wishes from the config (one place for
// every runner: the networked station, the VPS scene, the bimanual device).
servo::ServoConfig servo_config(const config::OperatorConfig& cfg);

// The link client's options from the config and the command line (ports,
// --test-version): the networked station's and telemanipulation's.
OperatorClientOptions client_options(const config::OperatorConfig& cfg, const OperatorArgs& a,
                                     const std::string& robot_address, const net::Key& key);

// The station's logging at --log-level; false (said on stderr) for a bad level.
bool setup_logging(const std::string& log_level);

// SIGINT/SIGTERM end a local run (VPS scene or bimanual device) between
// ticks: installs the handlers and returns the flag they set.
std::atomic<bool>* stop_local_run_on_signals();

// Writes a summary's JSON to --station-json (nothing without it); false
// (said on stderr) if the file cannot be written.
bool write_station_json(const std::string& path, const std::string& json);

// A local run's end: its summary on stdout and, if asked, as JSON.
template <typename Summary>
int finish_local_run(const Summary& s, const std::string& station_json) {
  std::cout << to_string(s) << std::flush;
  return write_station_json(station_json, to_json(s)) ? net::kExitOk : net::kExitInternal;
}

#ifdef HEMM_DEVICE_VIEW
// A device-only run's live view: its thread starts once the servo loop runs
// and stops (after a last picture) when the loop has stopped. Null without
// --view / --view-png.
std::unique_ptr<DeviceLiveView> attach_device_view(const view::ViewOptions& opts, DeviceSceneSetup setup,
                                                   DeviceViewTaps* taps);
#endif

}  // namespace hemm::op::runner
