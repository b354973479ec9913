// hemm-operator: the operator station. Connects to the robot, authenticates,
// exchanges heartbeats and ping/pong, re-opens the session after a drop; runs
// the haptic device (SIMULATED Omni with a scripted hand, or a replayed
// trajectory) in the 1 kHz servo loop against the local model built from the
// robot's scans, streams commands, and prints link and station statistics at
// exit. The e-stop: both device buttons together, a key on the terminal
// (space or e engages, R releases) when stdin is one, or
// `hemm-operator estop --control-socket PATH` against a running station
// started with --control-socket PATH. With a `vps` block in its config it renders that VPS scene (meshes,
// held objects, 6-DoF couplings) with the device instead, without a robot.
// With the SIMULATED bimanual interface (device sim-bimanual) it runs
// that device in the same servo loop against local planes, without a robot;
// with probe_3d.tool "pointshell" its right arm holds the robot's 6-DoF probe
// tool in the networked station instead (operator/station/tool6_bimanual.h).
// --view / --view-png show each of these runs (the robot's world, or the
// device, its arms and the VPS scene).
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <google/protobuf/text_format.h>
#include <atomic>
#include <cctype>
#include <csignal>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <sstream>
#include <vector>

#include "common/config/config.h"
#include "common/net/crypto.h"
#include "common/net/exit_codes.h"
#include "common/net/station_cli.h"
#include "common/net/session_connection.h"
#include "common/net/station_control.h"
#include "common/realtime/realtime_setup.h"
#include "config_operator.pb.h"
#include "operator/bimanual/bimanual_config.h"
#include "operator/bimanual/bimanual_scripts.h"
#include "operator/bimanual/bimanual_session.h"
#include "operator/client/operator_client.h"
#include "operator/record/session_mcap.h"
#include "operator/record/session_recording.h"
#include "operator/record/session_replay.h"
#include "operator/station/demo_scripts.h"
#include "operator/station/operator_station.h"
#ifdef HEMM_OPERATOR_HAVE_VPS
#include "operator/vps/vps_config.h"
#include "operator/vps/vps_session.h"
#include "report.pb.h"
#endif
#ifdef HEMM_WITH_VIEW
#include "common/view/view_options.h"
#include "operator/view/live_view.h"
#endif
#if defined(HEMM_WITH_VIEW) && defined(HEMM_OPERATOR_HAVE_VPS)
#define HEMM_DEVICE_VIEW 1  // the device-only runs' view (operator/view/device_live_view.h)
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/view/device_live_view.h"
#endif

namespace {

using namespace hemm;

// "X,Y" -> two finite numbers (nothing else on the string).
std::optional<Eigen::Vector2d> parse_goal(const std::string& s) {
  const auto comma = s.find(',');
  if (comma == std::string::npos) return std::nullopt;
  auto num = [](const std::string& t, double* out) {
    if (t.empty() || std::isspace(static_cast<unsigned char>(t.front()))) return false;
    char* end = nullptr;
    errno = 0;
    *out = std::strtod(t.c_str(), &end);
    return errno == 0 && end == t.c_str() + t.size() && std::isfinite(*out);
  };
  double x = 0, y = 0;
  if (!num(s.substr(0, comma), &x) || !num(s.substr(comma + 1), &y)) return std::nullopt;
  return Eigen::Vector2d(x, y);
}

// The servo loop's period and real-time wishes from the config (one place for
// every runner: the networked station, the VPS scene, the bimanual device).
servo::ServoConfig servo_config(const config::OperatorConfig& cfg) {
  servo::ServoConfig c;
  c.period_ns = 1'000'000'000LL / cfg.servo().rate_hz();
  c.realtime = cfg.servo().realtime_priority();
  c.lock_memory = cfg.servo().realtime_priority();
  c.cpu = cfg.servo().cpu();
  c.simulated_hardware = cfg.servo().simulated_hardware() == "lock-step" ? device::HardwareMode::kLockStep
                                                                         : device::HardwareMode::kThreaded;
  return c;
}

#ifdef HEMM_DEVICE_VIEW
// A device-only run's live view: its thread starts once the servo loop runs
// and stops (after a last picture) when the loop has stopped. Null without
// --view / --view-png.
std::unique_ptr<op::DeviceLiveView> attach_device_view(const view::ViewOptions& opts, op::DeviceSceneSetup setup,
                                                       op::DeviceViewTaps* taps) {
  if (!opts.enabled()) return nullptr;
  auto v = std::make_unique<op::DeviceLiveView>(opts, std::move(setup));
  op::DeviceLiveView* p = v.get();
  taps->ticks = &p->ticks();
  taps->started = [p](const servo::TimingStats& t) { p->start(&t); };
  taps->stopped = [p] { p->stop(); };
  return v;
}
#endif

// SIGINT/SIGTERM end a local run (VPS scene or bimanual device) between ticks.
std::atomic<bool> g_local_stop{false};
extern "C" void on_local_signal(int) { g_local_stop.store(true); }

// A local run's end: its summary on stdout and, if asked, as JSON (the
// summary's own, or `json` when given).
template <typename Summary>
int finish_local_run(const Summary& s, const std::string& station_json, const std::string& json = {}) {
  std::cout << op::to_string(s) << std::flush;
  std::string error;
  if (!station_json.empty() && !net::write_text_file(station_json, json.empty() ? op::to_json(s) : json, &error)) {
    std::cerr << "hemm-operator: --station-json: " << error << "\n";
    return net::kExitInternal;
  }
  return net::kExitOk;
}

#ifdef HEMM_OPERATOR_HAVE_VPS
// The VPS scene of the config's `vps` block with the device in the servo
// loop: no robot, no link.
int run_vps(const config::OperatorConfig& cfg, const std::string& config_path, const std::string& replay_file,
            double duration_s, const std::string& servo_log, const std::string& station_json
#ifdef HEMM_DEVICE_VIEW
            ,
            const view::ViewOptions& view_opts
#endif
) {
  op::VpsSessionOptions o;
  std::unique_ptr<device::HapticDevice> dev;
  std::shared_ptr<op::VpsLocalModel> model;
  try {
    const op::VpsSetup setup = op::vps_setup(cfg, config_path);
    dev = op::make_vps_device(cfg, replay_file);
    o.task = setup.task;
    op::VpsLoadReport report;
    model = op::load_vps_model(setup.model, &report);
    for (const auto& l : report.lines) spdlog::info("event=vps_model {}", l);
    for (const auto& w : report.warnings) spdlog::warn("event=vps_model warning=\"{}\"", w);
  } catch (const std::invalid_argument& e) {
    std::cerr << "hemm-operator: bad config: " << e.what() << "\n";
    return net::kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    return net::kExitUsage;
  }
  o.servo = servo_config(cfg);
  o.log_path = servo_log;
  o.duration_s = duration_s;
#ifdef HEMM_DEVICE_VIEW
  const auto* arms = dynamic_cast<const device::bimanual::SimulatedBimanualDevice*>(dev.get());
  const std::unique_ptr<op::DeviceLiveView> live_view = attach_device_view(
      view_opts,
      op::vps_view_setup(*model, o.task, dev->limits().end_effectors,
                         arms != nullptr ? &arms->simulation().config() : nullptr, std::string(dev->name())),
      &o.view);
#endif
  // Scripted hands end: by default the run covers their path and a hold.
  if (o.duration_s <= 0) o.duration_s = op::vps_default_duration_s(cfg);
  std::signal(SIGINT, on_local_signal);
  std::signal(SIGTERM, on_local_signal);
  op::VpsSessionSummary s;
  try {
    s = op::run_vps_session(*dev, model, o, &g_local_stop, [&](const servo::RealtimeStatus& rt) {
      for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
      spdlog::info("event=station_started device={} vps_objects={} fifo={}", dev->name(), model->object_count,
                   rt.fifo);
    });
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    return net::kExitUsage;
  }
  // The report with the servo loop's histograms, worst ticks and simulated
  // hardware (ServoTiming, as the other runs report it).
  report::VpsSession r = op::to_report(s);
  servo::fill(r.mutable_timing(), s.timing);
  std::cout << "servo worst ticks: " << rt::worst_ticks_text(s.timing.worst) << "\n";
  return finish_local_run(s, station_json, config::to_json(r));
}
#endif

// The SIMULATED bimanual interface in the servo loop against its local
// environment: no robot, no link (DeviceConfig.type "sim-bimanual").
int run_bimanual(const config::OperatorConfig& cfg, const std::string& hands, double duration_s,
                 const std::string& servo_log, const std::string& station_json
#ifdef HEMM_DEVICE_VIEW
                 ,
                 const view::ViewOptions& view_opts
#endif
) {
  op::BimanualSessionOptions o;
  try {
    o.setup = op::bimanual_setup(cfg.device().bimanual());
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: bad config: device.bimanual: " << e.what() << "\n";
    return net::kExitUsage;
  }
  if (!hands.empty()) o.setup.script = hands;
  o.servo = servo_config(cfg);
  o.setup.sim.plant.control_period_s = static_cast<double>(o.servo.period_ns) * 1e-9;
  o.log_path = servo_log;
  o.duration_s = duration_s;
#ifdef HEMM_DEVICE_VIEW
  const std::unique_ptr<op::DeviceLiveView> live_view =
      attach_device_view(view_opts, op::bimanual_view_setup(o.setup), &o.view);
#endif
  std::signal(SIGINT, on_local_signal);
  std::signal(SIGTERM, on_local_signal);
  op::BimanualSessionSummary s;
  try {
    s = op::run_bimanual_session(o, &g_local_stop, [](const servo::RealtimeStatus& rt) {
      for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
      spdlog::info("event=station_started device=sim-bimanual fifo={} memory_locked={}", rt.fifo, rt.memory_locked);
    });
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    return net::kExitUsage;
  }
  return finish_local_run(s, station_json);
}

// Loads a recording (or its MCAP export) for --replay or --export-mcap:
// false if nothing of it is readable (said on stderr); a broken file's
// readable part is used, *broke set and said.
bool load_session(const std::string& path, const char* using_it, op::Recording* rec, bool* broke) {
  const std::optional<std::string> e = op::load_recording(path, rec);
  *broke = e.has_value();
  if (e && rec->records == 0) {
    std::cerr << "hemm-operator: " << *e << "\n";
    return false;
  }
  if (e) std::cerr << "hemm-operator: " << *e << "; " << using_it << " the readable part\n";
  return true;
}

// --replay of a session recording: no link; the model and the servo task
// rebuilt from the file (operator/record/session_replay.h), optionally seen
// in the live view.
int replay_recording(const std::string& path, double speed, const std::string& json_path
#ifdef HEMM_WITH_VIEW
                     ,
                     const view::ViewOptions& view_opts
#endif
) {
  op::Recording rec;
  bool broke = false;
  if (!load_session(path, "replaying", &rec, &broke)) return net::kExitUsage;
  op::SessionReplayOptions ro;
  ro.speed = speed;
#ifdef HEMM_WITH_VIEW
  std::unique_ptr<op::OperatorLiveView> live_view;
  if (view_opts.enabled()) {
    live_view = std::make_unique<op::OperatorLiveView>(view_opts, op::LiveViewLinks{});
    op::ViewFeed& feed = live_view->feed();
    ro.on_snapshot = [&feed](const op::OperatorModelSnapshot& s) { feed.on_snapshot(s); };
    ro.ticks = &feed.ticks();
    live_view->start();
  }
#endif
  const op::SessionReplayResult r = op::replay_session(rec, ro);
  if (!r.warning.empty()) std::cerr << "hemm-operator: --replay: " << r.warning << "\n";
#ifdef HEMM_WITH_VIEW
  if (live_view) live_view->stop();
#endif
  std::cout << "replay: ticks=" << r.ticks << " model_steps=" << r.steps << " ticks_missing=" << r.ticks_missing
            << " force_mismatches=" << r.force_mismatches << " max_force_error_N=" << r.max_force_error_N
            << " mode_mismatches=" << r.mode_mismatches << " recorded_s=" << r.recorded_s << " wall_s=" << r.wall_s
            << (r.stopped.empty() ? "" : " stopped=\"" + r.stopped + "\"") << "\n";
  std::string error;
  if (!json_path.empty() && !net::write_text_file(json_path, op::to_json(r), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    return net::kExitInternal;
  }
  return broke ? net::kExitUsage : net::kExitOk;
}

// --export-mcap REC OUT: the recording (or the readable part of a broken
// one, exit 2) as MCAP (operator/record/session_mcap.h).
int export_recording_as_mcap(const std::string& in, const std::string& out) {
  op::Recording rec;
  bool broke = false;
  if (!load_session(in, "exporting", &rec, &broke)) return net::kExitUsage;
  try {
    std::cout << op::to_string(op::export_mcap(rec, out)) << std::flush;
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: --export-mcap: " << e.what() << "\n";
    return net::kExitUsage;
  }
  return broke ? net::kExitUsage : net::kExitOk;
}

int run(int argc, char** argv) {
  CLI::App app{"hemm-operator: the operator station of hemm (authenticated session, 1 kHz haptic servo loop with "
               "the virtual proxy on the local model, commands to the robot, link statistics). A config with a vps block "
               "renders that VPS scene with the device instead, without a robot (deploy/configs/operator_vps_*.pbtxt)."};
  app.footer(net::kExitCodeHelp);
  std::string config_path, key_path, robot, log_level = "info", stats_json;
  int session_port = -1, stream_port = -1;
  unsigned test_version = 0;
  double duration_s = 0.0, stats_period_s = 0.0;
  app.add_option("--config", config_path,
                 "operator config (text protobuf; default: configs/operator.pbtxt of the data directory, "
                 "docs/install.md)");
  app.add_option("--key", key_path, "pre-shared key file (64 hex chars); overrides link.key_file");
  app.add_option("--robot", robot, "robot (or relay) IP address (overrides net.robot_address)");
  app.add_option("--session-port", session_port, "robot's TCP session port (overrides net.session_port)")
      ->check(CLI::Range(1, 65535));
  app.add_option("--stream-port", stream_port,
                 "robot's UDP stream port as reachable from here, e.g. a relay's (overrides net.stream_port; "
                 "0: the port in the robot's Welcome)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--duration", duration_s, "run for this many seconds (0: until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off");
  app.add_option("--stats-period", stats_period_s, "log link statistics every this many seconds (0: never)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--stats-json", stats_json, "write the final link statistics as JSON to this file");
  std::string script = "idle", servo_log, replay_file;
  app.add_option("--script", script,
                 "SIMULATED hand script for the sim-omni device: idle, nav-to-wall (steers for --goal behind a wall "
                 "and keeps pushing), probe-cylinder (exploration: the probe sweeps --probe-line out and back), "
                 "nav-to-goal (closed loop: drives the robot to --goal and stops within 0.10 m; ~25 s). All assume "
                 "the robot starts at the W origin heading +x and the default maps (exploration 4 m, navigation "
                 "2 m); without --goal / --probe-line they aim at deploy/scenes/home.xml's wall and bin")
      ->check(CLI::IsMember(op::demo_script_names()));
  std::vector<std::string> goal_args;
  app.add_option("--goal", goal_args,
                 "nav-to-goal: goal X,Y in W metres; repeat for a route (the robot passes the earlier goals and "
                 "stops at the last; default: 2.2,0 then 2.45,-1.6). nav-to-wall: one point X,Y behind the wall "
                 "(default 4.5,1.6)")
      ->allow_extra_args(false);
  std::string probe_line_arg;
  app.add_option("--probe-line", probe_line_arg,
                 "probe-cylinder: X0,Y0,X1,Y1 in W metres, the line the probe sweeps (out and back); pass it a few "
                 "cm off the object's centre so the probe meets its seen face; within the SIMULATED Omni's reach at "
                 "the exploration scale: 1.75 m ahead or behind and 4 m to either side of the start (default "
                 "1.42,-0.8,1.42,-1.6: home.xml's bin)");
  std::string shape_completion = "on";
  app.add_option("--shape-completion", shape_completion,
                 "on: circles and wall lines fitted to the local map (PCL sample consensus) are rendered where "
                 "their fit is good (a round object's unseen back, a wall through dropouts); off: raw map segments "
                 "and shadow edges only (default on)")
      ->check(CLI::IsMember({"on", "off"}));
  std::string station_json;
  app.add_option("--station-json", station_json,
                 "write the station summary (servo timing, model, commands, logs, final predicted pose, "
                 "nav-to-goal state) as JSON to this file at exit");
  app.add_option("--log", servo_log,
                 "1 kHz servo CSV log (also FILE.world.csv per tick in W, FILE.map.csv: the final map)");
  app.add_option("--replay", replay_file,
                 "replay this device trajectory CSV (overrides device.type/replay_file), or a session recording "
                 "made with --record: then no robot is contacted; the local model is rebuilt from the recorded "
                 "inputs and the recorded hand drives the servo task, whose forces are compared with the recorded "
                 "ones tick for tick (exit 2 if the file is truncated or corrupt, after replaying what it holds)");
  std::string record_path, replay_json;
  double replay_speed = 1.0;
  app.add_option("--record", record_path,
                 "record the session to this file (length-delimited protobuf, proto/record.proto): every servo "
                 "tick, model step, stream message received (robot state, scans, depth chunks) and sent, session "
                 "frame sent");
  std::vector<std::string> export_mcap;
  app.add_option("--export-mcap", export_mcap,
                 "REC OUT.mcap: write the session recording REC as MCAP (protobuf schemas, zstd chunks; Foxglove "
                 "Studio or any MCAP reader opens it; --replay replays it as REC) and exit (docs/recording.md)")
      ->expected(2);
  app.add_option("--replay-speed", replay_speed,
                 "with --replay of a recording: recorded seconds per second (1 real time; 0 as fast as possible)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--replay-json", replay_json,
                 "with --replay of a recording: write the replay's result (ticks, force error, times) as JSON here");
  net::StationControlOptions control_options;
  net::add_station_control_options(app, "hemm-operator", &control_options);
  int servo_cpu = -1;
  app.add_option("--servo-cpu", servo_cpu,
                 "pin the 1 kHz servo thread to this CPU (overrides servo.cpu; -1: not pinned). Best an isolated one "
                 "(isolcpus=): docs/realtime.md; a CPU this process may not run on is refused");
  std::string simulated_hardware;
  app.add_option("--simulated-hardware", simulated_hardware,
                 "where a SIMULATED device's hardware runs (overrides servo.simulated_hardware): threaded (its own "
                 "thread, as on its own board) or lock-step (inside the servo tick, deterministic)")
      ->check(CLI::IsMember({"threaded", "lock-step"}));
  std::string device_type, bimanual_hands;
  app.add_option("--device", device_type,
                 "device (overrides device.type): sim-omni, replay, sim-hand6 (a SIMULATED rigid 6-DoF scripted hand for "
                 "probe_3d.tool pointshell), or sim-bimanual (the SIMULATED bimanual "
                 "interface: two 7-DoF arms in MuJoCo with scripted hands, rendering local planes, or with a vps "
                 "config the scene's VPS objects along its scripted hand paths, no robot; or with probe_3d.tool "
                 "pointshell the robot's 6-DoF probe tool in its right hand)")
      ->check(CLI::IsMember({"sim-omni", "replay", "sim-bimanual", "sim-hand6"}));
  app.add_option("--hands", bimanual_hands,
                 "SIMULATED hand script for the sim-bimanual device (overrides device.bimanual.script): features "
                 "(each feature in turn, 14 s), idle")
      ->check(CLI::IsMember(op::bimanual_script_names()));
#ifdef HEMM_WITH_VIEW
  view::ViewOptions view_opts;
  view::ViewOptionStrings view_strs;
  view::add_view_options(app, &view_opts, &view_strs);
#endif
  // Hidden: lets tests speak a wrong protocol version.
  app.add_option("--test-protocol-version", test_version, "")->group("");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? net::kExitOk : net::kExitUsage;
  }
  if (!control_options.command.empty()) return net::run_control_command("hemm-operator", control_options);
  if (!export_mcap.empty()) return export_recording_as_mcap(export_mcap[0], export_mcap[1]);
#ifdef HEMM_WITH_VIEW
  if (auto e = view::finish_view_options(view_strs, &view_opts)) {
    std::cerr << "hemm-operator: " << *e << "\n";
    return net::kExitUsage;
  }
#endif
  if (!replay_file.empty() && op::looks_like_recording(replay_file)) {
    if (!net::setup_station_logging("operator", log_level)) {
      std::cerr << "hemm-operator: bad --log-level '" << log_level << "'\n";
      return net::kExitUsage;
    }
#ifdef HEMM_WITH_VIEW
    return replay_recording(replay_file, replay_speed, replay_json, view_opts);
#else
    return replay_recording(replay_file, replay_speed, replay_json);
#endif
  }
  std::vector<Eigen::Vector2d> goal_route;
  for (const std::string& g : goal_args) {
    const auto p = parse_goal(g);
    if (!p) {
      std::cerr << "hemm-operator: --goal '" << g << "': expected X,Y (two finite numbers, metres in W)\n";
      return net::kExitUsage;
    }
    goal_route.push_back(*p);
  }
  if (!goal_route.empty() && script != "nav-to-goal" && !(script == "nav-to-wall" && goal_route.size() == 1)) {
    std::cerr << "hemm-operator: --goal needs --script nav-to-goal (or one --goal with nav-to-wall)\n";
    return net::kExitUsage;
  }
  std::vector<Eigen::Vector2d> probe_line;
  if (!probe_line_arg.empty()) {
    std::vector<double> v;
    std::stringstream ss(probe_line_arg);
    for (std::string item; std::getline(ss, item, ',');) {
      char* end = nullptr;
      const double x = std::strtod(item.c_str(), &end);
      if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(x)) {
        v.clear();
        break;
      }
      v.push_back(x);
    }
    if (v.size() != 4 || std::hypot(v[0], v[1]) > 4.0 || std::hypot(v[2], v[3]) > 4.0) {
      std::cerr << "hemm-operator: --probe-line '" << probe_line_arg
                << "': expected X0,Y0,X1,Y1 (four finite numbers, metres in W, within 4 m of the start)\n";
      return net::kExitUsage;
    }
    if (script != "probe-cylinder") {
      std::cerr << "hemm-operator: --probe-line needs --script probe-cylinder\n";
      return net::kExitUsage;
    }
    probe_line = {{v[0], v[1]}, {v[2], v[3]}};
  }
  if (!net::setup_station_logging("operator", log_level)) {
    std::cerr << "hemm-operator: bad --log-level '" << log_level << "'\n";
    return net::kExitUsage;
  }

  config::OperatorConfig cfg;
  if (config_path.empty()) config_path = net::default_station_config("operator", "operator.pbtxt");
  if (!config_path.empty()) {
    if (auto err = config::load_text_config(config_path, &op::validate_operator_config_with_bimanual, &cfg)) {
      std::cerr << "hemm-operator: bad config: " << err->to_string() << "\n";
      spdlog::error("event=bad_config error=\"{}\"", err->to_string());
      return net::kExitUsage;
    }
  }
  if (!device_type.empty()) cfg.mutable_device()->set_type(device_type);
  if (app.count("--servo-cpu") > 0) cfg.mutable_servo()->set_cpu(servo_cpu);
  if (!simulated_hardware.empty()) cfg.mutable_servo()->set_simulated_hardware(simulated_hardware);
  if (auto why = rt::check_cpu(cfg.servo().cpu())) {
    std::cerr << "hemm-operator: " << (app.count("--servo-cpu") > 0 ? "--servo-cpu" : "servo.cpu") << " "
              << cfg.servo().cpu() << ": " << *why << "\n";
    return net::kExitUsage;
  }
  if (cfg.has_vps()) {
    if (!bimanual_hands.empty()) {
      std::cerr << "hemm-operator: --hands: a VPS scene's SIMULATED hands follow its vps.hands paths\n";
      return net::kExitUsage;
    }
#ifdef HEMM_DEVICE_VIEW
    return run_vps(cfg, config_path, replay_file, duration_s, servo_log, station_json, view_opts);
#elif defined(HEMM_OPERATOR_HAVE_VPS)
    return run_vps(cfg, config_path, replay_file, duration_s, servo_log, station_json);
#else
    std::cerr << "hemm-operator: bad config: vps: this build has no VPS component\n";
    return net::kExitUsage;
#endif
  }
  // With the 6-DoF tool the bimanual device's right arm holds it in the
  // networked station (tool6_bimanual.h); without it, the device runs alone.
  const bool tool6_bimanual = cfg.device().type() == "sim-bimanual" && cfg.probe_3d().tool() == "pointshell";
  if (replay_file.empty() && cfg.device().type() == "sim-bimanual" && !tool6_bimanual) {
    if (app.count("--script") > 0 || !goal_route.empty()) {
      std::cerr << "hemm-operator: --script and --goal drive the sim-omni hand; the sim-bimanual device takes "
                   "--hands\n";
      return net::kExitUsage;
    }
#if defined(HEMM_WITH_VIEW) && !defined(HEMM_DEVICE_VIEW)
    if (view_opts.enabled()) {
      std::cerr << "hemm-operator: this build has no live view of the sim-bimanual device (no VPS component)\n";
      return net::kExitUsage;
    }
#endif
    if (const auto issues = op::validate_bimanual_config(cfg.device().bimanual()); !issues.empty()) {
      std::cerr << "hemm-operator: bad config: " << issues.front().field << ": " << issues.front().message << "\n";
      return net::kExitUsage;
    }
#ifdef HEMM_DEVICE_VIEW
    return run_bimanual(cfg, bimanual_hands, duration_s, servo_log, station_json, view_opts);
#else
    return run_bimanual(cfg, bimanual_hands, duration_s, servo_log, station_json);
#endif
  }
  if (!bimanual_hands.empty()) {
    std::cerr << (tool6_bimanual ? "hemm-operator: --hands: the 6-DoF tool's SIMULATED hand follows probe_3d.tool_hand_script\n"
                                 : "hemm-operator: --hands needs the sim-bimanual device\n");
    return net::kExitUsage;
  }
  const std::string robot_address = robot.empty() ? cfg.net().robot_address() : robot;
  const auto key =
      net::load_station_key("hemm-operator", key_path, config_path, cfg.link().key_file(), robot_address);
  if (!key) return net::kExitKey;

  op::OperatorClientOptions o;
  const auto& link = cfg.link();
  net::apply_link_config(link, *key, &o);
  o.robot_address = robot_address;
  o.session_port =
      static_cast<uint16_t>(session_port >= 0 ? session_port : static_cast<int>(cfg.net().session_port()));
  o.stream_port = static_cast<uint16_t>(stream_port >= 0 ? stream_port : static_cast<int>(cfg.net().stream_port()));
  o.bind_address = cfg.net().bind_address();
  o.local_stream_port = static_cast<uint16_t>(cfg.net().local_stream_port());
  o.want_control = cfg.net().want_control();
  if (test_version != 0) o.protocol_version = test_version;
  o.connect_timeout_ms = link.connect_timeout_ms();
  o.reconnect_for_ms = link.reconnect_for_ms();
  o.connect_for_ms = link.connect_for_ms();

  op::OperatorStationOptions so;
  so.device = replay_file.empty() ? cfg.device().type() : "replay";
  so.replay_file = !replay_file.empty() ? replay_file
                   : cfg.device().has_replay_file()
                       ? config::resolve_relative_to(config_path, cfg.device().replay_file())
                       : std::string();
  so.script = script;
  so.goal_route = goal_route;
  so.probe_line = probe_line;
  so.log_path = servo_log;
  so.model.shapes.enabled = shape_completion == "on";
  so.command_rate_hz = cfg.net().command_rate_hz();
  so.servo = servo_config(cfg);
  so.task.proxy.period = static_cast<double>(so.servo.period_ns) * 1e-9;
  op::apply_probe3d_config(cfg.probe_3d(), &so);
  so.bimanual = std::make_shared<const config::BimanualDeviceConfig>(cfg.device().bimanual());

  asio::io_context io;
  op::OperatorClient client(io, o);
  std::unique_ptr<op::OperatorStation> station;
  try {
    station = std::make_unique<op::OperatorStation>(io, client, so);
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    return net::kExitUsage;
  }
  std::unique_ptr<op::SessionRecorder> recorder;
  if (!record_path.empty()) {
    rec::Header h;
    h.set_start_ns(net::steady_now_ns());
    h.set_servo_period_ns(so.servo.period_ns);
    h.set_initial_mode(static_cast<std::uint32_t>(station->task().params().initial_mode));
    h.set_script(so.device == "sim-omni" ? so.script : so.device);
    h.set_end_effectors(station->device().limits().end_effectors);
    h.set_shape_completion_off(!so.model.shapes.enabled);
    google::protobuf::TextFormat::PrintToString(cfg, h.mutable_config_text());
    try {
      recorder = std::make_unique<op::SessionRecorder>(record_path, h);
    } catch (const std::exception& e) {
      std::cerr << "hemm-operator: --record: " << e.what() << "\n";
      return net::kExitUsage;
    }
    op::SessionRecorder* r = recorder.get();
    op::OperatorStation::SessionTaps taps;
    taps.on_step = [r](const op::ModelThread::StepInputs& in, const op::OperatorModelSnapshot& s) {
      r->model_step(in, s.version);
    };
    taps.ticks = &r->ticks();
    taps.on_stream = [r](std::int64_t t, bool out, const wire::StreamMessage& m) { r->stream(t, out, m); };
    taps.on_session = [r](std::int64_t t, bool out, const wire::SessionFrame& f) { r->session(t, out, f); };
    station->attach_session_taps(std::move(taps));
    recorder->start();
  }
#ifdef HEMM_WITH_VIEW
  std::unique_ptr<op::OperatorLiveView> live_view;  // the view thread: started after the station
  if (view_opts.enabled())
    live_view = std::make_unique<op::OperatorLiveView>(view_opts, *station, op::station_view_links(client, *station, io));
#endif
  int exit_code = net::kExitOk;
  bool stopping = false;
  asio::steady_timer grace(io);
  auto leave_soon = [&] {
    grace.expires_after(std::chrono::milliseconds(200));
    grace.async_wait([&](const asio::error_code&) { io.stop(); });
  };
  auto shutdown = [&](const std::string& why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("event=shutdown reason=\"{}\"", why);
    if (!client.ever_opened()) {
      // The run ended without ever reaching the robot: that is a failure.
      exit_code = net::kExitPeerLost;
      std::cerr << "hemm-operator: " << why << " before a session was opened (exit code " << exit_code << ")\n";
    }
    client.stop(why);
    leave_soon();
  };
  std::string error;
  const bool started = client.start(
      [&](int code, const std::string& reason) {
        if (stopping) return;
        stopping = true;
        exit_code = code;
        std::cerr << "hemm-operator: " << reason << " (exit code " << code << ")\n";
        leave_soon();
      },
      &error);
  if (!started) {
    std::cerr << "hemm-operator: " << error << "\n";
    spdlog::error("event=start_failed error=\"{}\"", error);
    return net::kExitUsage;
  }
  try {
    const servo::RealtimeStatus rt = station->start();
    for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
    spdlog::info("event=station_started device={} script={} fifo={} memory_locked={}", so.device, so.script, rt.fifo,
                 rt.memory_locked);
#ifdef HEMM_WITH_VIEW
    if (live_view) live_view->start();
#endif
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    client.stop("station failed");
    return net::kExitUsage;
  }
  // The e-stop from outside the device: a control socket, terminal keys.
  auto estop = [&](bool engaged, const std::string& via, net::ControlServer::Respond respond) {
    station->request_estop(engaged, via, [respond, via](const std::string& reply) {
      spdlog::warn("event=estop_reply via={} reply=\"{}\"", via, net::printable_text(reply));
      if (respond) respond(reply);
    });
  };
  std::unique_ptr<net::ControlServer> control;
  if (!control_options.socket.empty()) {
    control = std::make_unique<net::ControlServer>(
        io, control_options.socket, [&](const std::string& cmd, net::ControlServer::Respond respond) {
          if (cmd == "estop" || cmd == "release") {
            estop(cmd == "estop", "control socket", respond);
          } else if (cmd == "status") {
            respond(station->status_line());
          } else {
            respond("error unknown command (estop, release, status)");
          }
        });
    if (!control->start(&error)) {
      std::cerr << "hemm-operator: " << error << "\n";
      spdlog::error("event=start_failed error=\"{}\"", error);
      station->stop();
      client.stop("bad control socket");
      return net::kExitUsage;
    }
  }
  net::TerminalKeys keys(io, STDIN_FILENO, [&](char k) {
    if (k == ' ' || k == 'e' || k == 'E') estop(true, "terminal key", nullptr);
    if (k == 'R') estop(false, "terminal key", nullptr);
  });
  net::start_estop_keys(keys, control_options);
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const asio::error_code& ec, int sig) {
    if (!ec) shutdown(sig == SIGINT ? "SIGINT" : "SIGTERM");
  });
  asio::steady_timer duration(io);
  if (duration_s > 0) {
    duration.expires_after(std::chrono::milliseconds(static_cast<int64_t>(duration_s * 1000)));
    duration.async_wait([&](const asio::error_code& ec) {
      if (!ec) shutdown("duration reached");
    });
  }
  asio::steady_timer stats_timer(io);
  std::function<void()> stats_tick = [&] {
    if (stats_period_s <= 0) return;
    stats_timer.expires_after(std::chrono::milliseconds(static_cast<int64_t>(stats_period_s * 1000)));
    stats_timer.async_wait([&](const asio::error_code& ec) {
      if (ec || stopping) return;
      spdlog::info("event=stats {}", net::to_log_fields(client.statistics()));
      stats_tick();
    });
  };
  stats_tick();

  // This thread is the network thread; the servo and model threads run
  // beside it.
  io.run();
  keys.stop();
  if (control) control->stop();
  station->stop();
  if (recorder) {
    recorder->stop();
    spdlog::info("event=recorded file=\"{}\" records={} ticks_dropped={} write_failed={}", record_path,
                 recorder->records(), recorder->ticks_dropped(), recorder->write_failed());
    if (recorder->write_failed()) std::cerr << "hemm-operator: writing " << record_path << " failed\n";
  }
#ifdef HEMM_WITH_VIEW
  if (live_view) live_view->stop();  // after a last picture of the final state
#endif
  const op::OperatorStationSummary summary = station->summary();
  std::cout << op::to_string(summary);
  if (!station_json.empty() && !net::write_text_file(station_json, op::to_json(summary), &error)) {
    std::cerr << "hemm-operator: --station-json: " << error << "\n";
    if (exit_code == net::kExitOk) exit_code = net::kExitInternal;
  }

  const net::LinkStatistics st = client.statistics();
  std::cout << net::to_summary(st) << std::flush;
  if (!stats_json.empty() && !net::write_text_file(stats_json, net::to_json(st), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    if (exit_code == net::kExitOk) exit_code = net::kExitInternal;
  }
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: internal error: " << e.what() << "\n";
    return hemm::net::kExitInternal;
  }
}
