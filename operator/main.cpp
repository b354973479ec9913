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
// This file reads the command line and picks the runner (operator/runners/,
// one file each); CLI11 stays here.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <Eigen/Core>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "common/config/config.h"
#include "common/net/exit_codes.h"
#include "common/net/station_cli.h"
#include "common/realtime/realtime_setup.h"
#include "config_operator.pb.h"
#include "operator/bimanual/bimanual_config.h"
#include "operator/bimanual/bimanual_scripts.h"
#include "operator/record/session_recording.h"
#include "operator/runners/runners.h"
#include "operator/station/demo_scripts.h"
#include "operator/station/explore_route.h"
#include "operator/station/operator_station.h"

namespace {

using namespace hemm;
using op::runner::OperatorArgs;

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

// What CLI11 fills that is checked before it becomes OperatorArgs.
struct RawArgs {
  std::vector<std::string> goal_args;
  std::string probe_line_arg;
  std::string hand6_route, hand6_script;  // override probe_3d.tool_hand_route / tool_hand_script
  bool print_hand6_route = false;
  std::string shape_log_dir;  // overrides probe_3d.shape_log_dir
  std::string hand3_route, hand3_script;  // probe_3d.hand3_route / hand3_script
  bool print_hand3_route = false;
  std::string task, task_scene;  // telemanip.task / task_scene
  std::string telemanip_mode;  // overrides telemanip.mode
#ifdef HEMM_WITH_VIEW
  view::ViewOptionStrings view_strs;
#endif
};

// The two-arm tasks' SIMULATED humans (telemanip; issue 25 part 6).
void add_task_options(CLI::App* app, RawArgs* raw, OperatorArgs* a) {
  app->add_option("--task", raw->task,
                  "telemanip: the SIMULATED humans do this two-arm task through the link from the believed remote "
                  "state (box, peg or bar; overrides telemanip.task); the run ends telemanip.task_settle_s after the "
                  "script is done (or at --duration)");
  app->add_option("--task-scene", raw->task_scene,
                  "telemanip: the scene whose task: lines give the task's objects (overrides telemanip.task_scene; "
                  "deploy/scenes/workbench.xml, or workbench_box.xml for the box)");
  app->add_option("--hand-trace", a->hand_trace,
                  "telemanip: write each hand every 10 ms (commanded and believed remote G, the force the hand was "
                  "given and its held-object share, the remote wrist force as believed, the grippers) as CSV to this "
                  "file at exit (the first 20 minutes; deploy/plots/plot_telemanip.py draws it)");
}

// --task / --task-scene into the config (the scene relative to the working
// directory): false (said on stderr) when the config is not a telemanip one.
bool apply_task_args(const RawArgs& raw, const OperatorArgs& a, config::OperatorConfig* cfg) {
  if (!a.hand_trace.empty() && !cfg->telemanip().enabled()) {
    std::cerr << "hemm-operator: --hand-trace is telemanipulation's (telemanip { enabled: true }, "
                 "deploy/configs/operator_telemanip.pbtxt); the HEMM station records with --record\n";
    return false;
  }
  if (raw.task.empty() && raw.task_scene.empty()) return true;
  if (!cfg->telemanip().enabled()) {
    std::cerr << "hemm-operator: --task / --task-scene need a telemanip config (telemanip { enabled: true }, "
                 "deploy/configs/operator_telemanip.pbtxt)\n";
    return false;
  }
  if (!raw.task.empty()) cfg->mutable_telemanip()->set_task(raw.task);
  if (!raw.task_scene.empty())
    cfg->mutable_telemanip()->set_task_scene(std::filesystem::absolute(raw.task_scene).lexically_normal().string());
  return true;  // the values are checked with the rest of the telemanip block (task_human.h check_task_config)
}

void add_options(CLI::App* app, OperatorArgs* a, RawArgs* raw) {
  app->add_option("--config", a->config_path,
                  "operator config (text protobuf; default: configs/operator.pbtxt of the data directory, "
                  "docs/install.md)");
  app->add_option("--key", a->key_path, "pre-shared key file (64 hex chars); overrides link.key_file");
  app->add_option("--robot", a->robot, "robot (or relay) IP address (overrides net.robot_address)");
  app->add_option("--session-port", a->session_port, "robot's TCP session port (overrides net.session_port)")
      ->check(CLI::Range(1, 65535));
  app->add_option("--stream-port", a->stream_port,
                  "robot's UDP stream port as reachable from here, e.g. a relay's (overrides net.stream_port; "
                  "0: the port in the robot's Welcome)")
      ->check(CLI::Range(0, 65535));
  app->add_option("--duration", a->duration_s, "run for this many seconds (0: until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app->add_option("--log-level", a->log_level, "trace, debug, info, warn, error, critical, off");
  app->add_option("--stats-period", a->stats_period_s, "log link statistics every this many seconds (0: never)")
      ->check(CLI::NonNegativeNumber);
  app->add_option("--stats-json", a->stats_json, "write the final link statistics as JSON to this file");
  app->add_option("--script", a->script,
                  "SIMULATED hand script for the sim-omni device: idle, nav-to-wall (steers for --goal behind a wall "
                  "and keeps pushing), probe-cylinder (exploration: the probe sweeps --probe-line out and back), "
                  "nav-to-goal (closed loop: drives the robot to --goal and stops within 0.10 m; ~25 s). All assume "
                  "the robot starts at the W origin heading +x and the default maps (exploration 4 m, navigation "
                  "2 m); without --goal / --probe-line they aim at deploy/scenes/home.xml's wall and bin")
      ->check(CLI::IsMember(op::demo_script_names()));
  app->add_option("--goal", raw->goal_args,
                  "nav-to-goal: goal X,Y in W metres; repeat for a route (the robot passes the earlier goals and "
                  "stops at the last; default: 2.2,0 then 2.45,-1.6). nav-to-wall: one point X,Y behind the wall "
                  "(default 4.5,1.6)")
      ->allow_extra_args(false);
  app->add_option("--probe-line", raw->probe_line_arg,
                  "probe-cylinder: X0,Y0,X1,Y1 in W metres, the line the probe sweeps (out and back); pass it a few "
                  "cm off the object's centre so the probe meets its seen face; within the SIMULATED Omni's reach at "
                  "the exploration scale: 1.75 m ahead or behind and 4 m to either side of the start (default "
                  "1.42,-0.8,1.42,-1.6: home.xml's bin)");
  app->add_option("--shape-completion", a->shape_completion,
                  "on: circles and wall lines fitted to the local map (PCL sample consensus) are rendered where "
                  "their fit is good (a round object's unseen back, a wall through dropouts); off: raw map segments "
                  "and shadow edges only (default on)")
      ->check(CLI::IsMember({"on", "off"}));
  app->add_option("--shape-completion-3d", a->shape_completion_3d,
                  "live voxmap (probe_3d): on: boxes, cylinders and spheres fitted to the seen surface (PCL sample "
                  "consensus) give objects' unseen sides their likely shape, flagged inferred; off: the raw voxmap "
                  "(overrides probe_3d.shape_completion, default off)")
      ->check(CLI::IsMember({"on", "off"}));
  app->add_option("--unknown-solid", a->unknown_solid,
                  "live voxmap (probe_3d): on: space no ray has seen is solid, flagged inferred; off: free beside the "
                  "seen surfaces (overrides probe_3d.unknown_solid, default off)")
      ->check(CLI::IsMember({"on", "off"}));
  app->add_option("--shape-log", raw->shape_log_dir,
                  "live voxmap with 3D shape completion: write each rebuild's accepted primitives to "
                  "DIR/primitives.csv and the cells they were fitted to to DIR/cells_<build>.f32 (an existing "
                  "directory; overrides probe_3d.shape_log_dir, default none)");
  app->add_option("--inferred-stiffness", a->inferred_stiffness,
                  "stiffness on inferred surfaces (a fitted primitive's unseen side, unknown space): full, or a "
                  "factor in (0, 1] (overrides probe_3d.inferred_stiffness, default full)");
  app->add_option("--station-json", a->station_json,
                  "write the station summary (servo timing, model, commands, logs, final predicted pose, "
                  "nav-to-goal state) as JSON to this file at exit");
  app->add_option("--log", a->servo_log,
                  "1 kHz servo CSV log (also FILE.world.csv per tick in W, FILE.map.csv: the final map)");
  app->add_option("--replay", a->replay_file,
                  "replay this device trajectory CSV (overrides device.type/replay_file), or a session recording "
                  "made with --record: then no robot is contacted; the local model is rebuilt from the recorded "
                  "inputs and the recorded hand drives the servo task, whose forces are compared with the recorded "
                  "ones tick for tick (exit 2 if the file is truncated or corrupt, after replaying what it holds)");
  app->add_option("--record", a->record_path,
                  "record the session to this file (length-delimited protobuf, proto/record.proto): every servo "
                  "tick, model step, stream message received (robot state, scans, depth chunks) and sent, session "
                  "frame sent");
  app->add_option("--export-mcap", a->export_mcap,
                  "REC OUT.mcap: write the session recording REC as MCAP (protobuf schemas, zstd chunks; Foxglove "
                  "Studio or any MCAP reader opens it; --replay replays it as REC) and exit (docs/recording.md)")
      ->expected(2);
  app->add_option("--replay-speed", a->replay_speed,
                  "with --replay of a recording: recorded seconds per second (1 real time; 0 as fast as possible)")
      ->check(CLI::NonNegativeNumber);
  app->add_option("--replay-json", a->replay_json,
                  "with --replay of a recording: write the replay's result (ticks, force error, times) as JSON here");
  net::add_station_control_options(*app, "hemm-operator", &a->control_options);
  app->add_option("--servo-cpu", a->servo_cpu,
                  "pin the 1 kHz servo thread to this CPU (overrides servo.cpu; -1: not pinned). Best an isolated one "
                  "(isolcpus=): docs/realtime.md; a CPU this process may not run on is refused");
  app->add_option("--simulated-hardware", a->simulated_hardware,
                  "where a SIMULATED device's hardware runs (overrides servo.simulated_hardware): threaded (its own "
                  "thread, as on its own board) or lock-step (inside the servo tick, deterministic)")
      ->check(CLI::IsMember({"threaded", "lock-step"}));
  app->add_option("--device", a->device_type,
                  "device (overrides device.type): sim-omni, replay, sim-hand6 (a SIMULATED rigid 6-DoF scripted hand for "
                  "probe_3d.tool pointshell), or sim-bimanual (the SIMULATED bimanual "
                  "interface: two 7-DoF arms in MuJoCo with scripted hands, rendering local planes, or with a vps "
                  "config the scene's VPS objects along its scripted hand paths, no robot; or with probe_3d.tool "
                  "pointshell the robot's 6-DoF probe tool in its right hand)")
      ->check(CLI::IsMember({"sim-omni", "replay", "sim-bimanual", "sim-hand6"}));
  app->add_option("--hands", a->bimanual_hands,
                  "SIMULATED hand script for the sim-bimanual device (overrides device.bimanual.script): features "
                  "(each feature in turn, 14 s), idle")
      ->check(CLI::IsMember(op::bimanual_script_names()));
  app->add_option("--hand6-route", raw->hand6_route,
                  "scene file whose header holds the 6-DoF tool's SIMULATED hand routes (overrides "
                  "probe_3d.tool_hand_route; explore6 lines, deploy/scenes/README.md \"Exploration routes\")");
  app->add_option("--hand6-script", raw->hand6_script,
                  "the route of that file the SIMULATED hand follows (overrides probe_3d.tool_hand_script)");
  app->add_flag("--print-hand6-route", raw->print_hand6_route,
                "print the chosen route (robot start, truth region, end time, features with their times) after "
                "checking it against the SIMULATED rigid hand's reach, and exit");
  app->add_option("--hand3-route", raw->hand3_route,
                  "scene file whose header holds the 3-DoF point probe's SIMULATED Omni hand routes (sets "
                  "probe_3d.hand3_route; explore3 lines, deploy/scenes/README.md \"Exploration routes\")");
  app->add_option("--hand3-script", raw->hand3_script,
                  "the explore3 route of that file the SIMULATED Omni's hand follows instead of --script (sets "
                  "probe_3d.hand3_script; device sim-omni, probe_3d.tool point)");
  app->add_flag("--print-hand3-route", raw->print_hand3_route,
                "print the chosen explore3 route (robot start, truth region, end time, features with their times) "
                "after checking it against the SIMULATED Omni's reach through probe_3d's map, and exit");
#ifdef HEMM_WITH_VIEW
  view::add_view_options(*app, &a->view_opts, &raw->view_strs);
#endif
  // Hidden: lets tests speak a wrong protocol version.
  app->add_option("--test-protocol-version", a->test_version, "")->group("");
}

// The telemanipulation's feedback mode (issue 25 part 5): kept apart from
// add_options so the telemanip options of other work merge cleanly.
void add_telemanip_mode_option(CLI::App* app, RawArgs* raw) {
  app->add_option("--telemanip-mode", raw->telemanip_mode,
                  "telemanipulation (telemanip config): model (forces from the local model, VPS) or direct (the "
                  "robot's wrench kept passive by the time-domain passivity approach, the hands' twists sent; "
                  "overrides telemanip.mode)")
      ->check(CLI::IsMember({"model", "direct"}));
}

// --telemanip-mode into the config.
void apply_telemanip_mode(const RawArgs& raw, config::OperatorConfig* cfg) {
  if (!raw.telemanip_mode.empty()) cfg->mutable_telemanip()->set_mode(raw.telemanip_mode);
}

// --goal and --probe-line parsed and checked against --script: false (said on
// stderr) if bad.
bool finish_route_args(const RawArgs& raw, OperatorArgs* a) {
  for (const std::string& g : raw.goal_args) {
    const auto p = parse_goal(g);
    if (!p) {
      std::cerr << "hemm-operator: --goal '" << g << "': expected X,Y (two finite numbers, metres in W)\n";
      return false;
    }
    a->goal_route.push_back(*p);
  }
  const std::string& script = a->script;
  if (!a->goal_route.empty() && script != "nav-to-goal" && !(script == "nav-to-wall" && a->goal_route.size() == 1)) {
    std::cerr << "hemm-operator: --goal needs --script nav-to-goal (or one --goal with nav-to-wall)\n";
    return false;
  }
  if (raw.probe_line_arg.empty()) return true;
  std::vector<double> v;
  std::stringstream ss(raw.probe_line_arg);
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
    std::cerr << "hemm-operator: --probe-line '" << raw.probe_line_arg
              << "': expected X0,Y0,X1,Y1 (four finite numbers, metres in W, within 4 m of the start)\n";
    return false;
  }
  if (script != "probe-cylinder") {
    std::cerr << "hemm-operator: --probe-line needs --script probe-cylinder\n";
    return false;
  }
  a->probe_line = {{v[0], v[1]}, {v[2], v[3]}};
  return true;
}

// The config (--config, or the data directory's default) with --device
// applied: false (said on stderr and in the log) if it does not load.
bool load_config(OperatorArgs* a, config::OperatorConfig* cfg) {
  if (a->config_path.empty()) a->config_path = net::default_station_config("operator", "operator.pbtxt");
  if (!a->config_path.empty()) {
    if (auto err = config::load_text_config(a->config_path, &op::validate_operator_config_with_bimanual, cfg)) {
      std::cerr << "hemm-operator: bad config: " << err->to_string() << "\n";
      spdlog::error("event=bad_config error=\"{}\"", err->to_string());
      return false;
    }
  }
  if (!a->device_type.empty()) cfg->mutable_device()->set_type(a->device_type);
  if (a->servo_cpu_given) cfg->mutable_servo()->set_cpu(a->servo_cpu);
  if (!a->shape_completion_3d.empty()) cfg->mutable_probe_3d()->set_shape_completion(a->shape_completion_3d == "on");
  if (!a->unknown_solid.empty()) cfg->mutable_probe_3d()->set_unknown_solid(a->unknown_solid == "on");
  if (!a->inferred_stiffness.empty()) {
    // "full" or a factor; the config's validation range applies to both.
    double f = 1.0;
    if (a->inferred_stiffness != "full") {
      char* end = nullptr;
      f = std::strtod(a->inferred_stiffness.c_str(), &end);
      if (end == a->inferred_stiffness.c_str() || *end != '\0' || !(f > 0.0 && f <= 1.0)) {
        std::cerr << "hemm-operator: --inferred-stiffness '" << a->inferred_stiffness
                  << "': \"full\" or a factor within (0, 1]\n";
        return false;
      }
    }
    cfg->mutable_probe_3d()->set_inferred_stiffness(f);
  }
  if (!a->simulated_hardware.empty()) cfg->mutable_servo()->set_simulated_hardware(a->simulated_hardware);
  if (auto why = rt::check_cpu(cfg->servo().cpu())) {
    std::cerr << "hemm-operator: " << (a->servo_cpu_given ? "--servo-cpu" : "servo.cpu") << " "
              << cfg->servo().cpu() << ": " << *why << "\n";
    return false;
  }
  return true;
}

// --hand6-route / --hand6-script into the config (a route file given on
// the command line is relative to the working directory).
void apply_hand6_args(const RawArgs& raw, config::OperatorConfig* cfg) {
  if (!raw.hand6_route.empty())
    cfg->mutable_probe_3d()->set_tool_hand_route(std::filesystem::absolute(raw.hand6_route).lexically_normal().string());
  if (!raw.hand6_script.empty()) cfg->mutable_probe_3d()->set_tool_hand_script(raw.hand6_script);
  if (!raw.shape_log_dir.empty()) cfg->mutable_probe_3d()->set_shape_log_dir(raw.shape_log_dir);
}

// --hand3-route / --hand3-script into the config, as apply_hand6_args.
void apply_hand3_args(const RawArgs& raw, config::OperatorConfig* cfg) {
  if (!raw.hand3_route.empty())
    cfg->mutable_probe_3d()->set_hand3_route(std::filesystem::absolute(raw.hand3_route).lexically_normal().string());
  if (!raw.hand3_script.empty()) cfg->mutable_probe_3d()->set_hand3_script(raw.hand3_script);
}

// The route lines deploy/explore3d.sh reads (--print-hand6-route, --print-hand3-route).
void print_route_lines(const std::string& path, const std::string& name, const op::SceneExploration& x, double end_s,
                       const std::vector<op::RouteFeature>& features) {
  const Eigen::AlignedBox3d& b = x.region_W;
  std::printf("scene %s\nroute %s\nstart %.10g %.10g %.10g\nregion %.10g %.10g %.10g %.10g %.10g %.10g\nend %.10g\n",
              path.c_str(), name.c_str(), x.start_W.x, x.start_W.y, x.start_W.theta, b.min().x(), b.min().y(),
              b.min().z(), b.max().x(), b.max().y(), b.max().z(), end_s);
  for (const op::RouteFeature& f : features) std::printf("feature %s %.10g %.10g\n", f.name.c_str(), f.t0_s, f.t1_s);
}

// An explore3 route set (probe_3d.hand3_script): it loads and the SIMULATED
// Omni reaches it (said on stderr, false, if not); with --print-hand3-route
// its lines are printed.
bool check_hand3_route(const config::OperatorConfig& cfg, const OperatorArgs& a, bool print) {
  const auto& p3 = cfg.probe_3d();
  const std::string device = a.device_type.empty() ? cfg.device().type() : a.device_type;
  if (device != "sim-omni" || !p3.enabled() || p3.tool() != "point" || a.script_given || !a.replay_file.empty()) {
    std::cerr << "hemm-operator: --hand3-script / probe_3d.hand3_script: the explore3 route is the SIMULATED Omni's "
                 "hand (device sim-omni, probe_3d { enabled: true tool: \"point\" }, no --script, no --replay)\n";
    return false;
  }
  const std::string path = config::resolve_relative_to(a.config_path, p3.hand3_route());
  op::OperatorStationOptions so;
  op::apply_probe3d_config(p3, &so);
  try {
    (void)op::load_hand3_route(path, p3.hand3_script(), so.task);
  } catch (const std::invalid_argument& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    return false;
  }
  if (print) {
    op::SceneExploration x;
    (void)op::load_scene_exploration(path, &x);  // loaded above
    const op::ExploreRoute3& r = *x.find3(p3.hand3_script());
    print_route_lines(path, r.name, x, r.keys.back().t_s, op::route_features(r));
  }
  return true;
}

// --print-hand6-route: the route as deploy/explore3d.sh reads it, one
// "key value..." line each; exit 2 (said on stderr) when it does not load or
// leaves the SIMULATED rigid hand's reach.
int print_hand6_route(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  const auto& p3 = cfg.probe_3d();
  const std::string path = config::resolve_relative_to(a.config_path, p3.tool_hand_route());
  op::SceneExploration x;
  if (auto e = op::load_scene_exploration(path, &x)) {
    std::cerr << "hemm-operator: --print-hand6-route: " << *e << "\n";
    return net::kExitUsage;
  }
  const op::ExploreRoute* r = x.find(p3.tool_hand_script());
  if (r == nullptr) {
    std::cerr << "hemm-operator: --print-hand6-route: no route '" << p3.tool_hand_script() << "' in " << path
              << " (its explore6 routes: " << x.route_names() << ")\n";
    return net::kExitUsage;
  }
  const Eigen::Vector3d origin_R(p3.origin_x_m(), 0.0, p3.origin_z_m());
  if (auto e = op::check_route_reach(*r, origin_R, device::rigid_hand_limits(1).ee[0], path)) {
    std::cerr << "hemm-operator: --print-hand6-route: " << *e << "\n";
    return net::kExitUsage;
  }
  print_route_lines(path, r->name, x, r->keys.back().t_s, op::route_features(*r));
  return net::kExitOk;
}

// The runner for this config and command line.
int dispatch(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  if (cfg.telemanip().enabled()) {
#ifdef HEMM_OPERATOR_HAVE_TELEMANIP
    return op::runner::run_telemanip(cfg, a);
#else
    std::cerr << "hemm-operator: bad config: telemanip: this build has no two-arm robot component\n";
    return net::kExitUsage;
#endif
  }
  if (cfg.has_vps()) {
    if (!a.bimanual_hands.empty()) {
      std::cerr << "hemm-operator: --hands: a VPS scene's SIMULATED hands follow its vps.hands paths\n";
      return net::kExitUsage;
    }
#ifdef HEMM_OPERATOR_HAVE_VPS
    return op::runner::run_vps(cfg, a);
#else
    std::cerr << "hemm-operator: bad config: vps: this build has no VPS component\n";
    return net::kExitUsage;
#endif
  }
  // With the 6-DoF tool the bimanual device's right arm holds it in the
  // networked station (tool6_bimanual.h); without it, the device runs alone.
  const bool tool6_bimanual = cfg.device().type() == "sim-bimanual" && cfg.probe_3d().tool() == "pointshell";
  if (a.replay_file.empty() && cfg.device().type() == "sim-bimanual" && !tool6_bimanual) {
    if (a.script_given || !a.goal_route.empty()) {
      std::cerr << "hemm-operator: --script and --goal drive the sim-omni hand; the sim-bimanual device takes "
                   "--hands\n";
      return net::kExitUsage;
    }
#if defined(HEMM_WITH_VIEW) && !defined(HEMM_DEVICE_VIEW)
    if (a.view_opts.enabled()) {
      std::cerr << "hemm-operator: this build has no live view of the sim-bimanual device (no VPS component)\n";
      return net::kExitUsage;
    }
#endif
    if (const auto issues = op::validate_bimanual_config(cfg.device().bimanual()); !issues.empty()) {
      std::cerr << "hemm-operator: bad config: " << issues.front().field << ": " << issues.front().message << "\n";
      return net::kExitUsage;
    }
    return op::runner::run_bimanual(cfg, a);
  }
  if (!a.bimanual_hands.empty()) {
    std::cerr << (tool6_bimanual ? "hemm-operator: --hands: the 6-DoF tool's SIMULATED hand follows probe_3d.tool_hand_script\n"
                                 : "hemm-operator: --hands needs the sim-bimanual device\n");
    return net::kExitUsage;
  }
  return op::runner::run_station(cfg, a);
}

int run(int argc, char** argv) {
  CLI::App app{"hemm-operator: the operator station of hemm (authenticated session, 1 kHz haptic servo loop with "
               "the virtual proxy on the local model, commands to the robot, link statistics). A config with a vps block "
               "renders that VPS scene with the device instead, without a robot (deploy/configs/operator_vps_*.pbtxt)."};
  app.footer(net::kExitCodeHelp);
  OperatorArgs a;
  RawArgs raw;
  add_options(&app, &a, &raw);
  add_task_options(&app, &raw, &a);
  add_telemanip_mode_option(&app, &raw);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? net::kExitOk : net::kExitUsage;
  }
  a.script_given = app.count("--script") > 0;
  a.servo_cpu_given = app.count("--servo-cpu") > 0;
  if (!a.control_options.command.empty()) return net::run_control_command("hemm-operator", a.control_options);
  if (!a.export_mcap.empty()) return op::runner::export_recording_as_mcap(a.export_mcap[0], a.export_mcap[1]);
#ifdef HEMM_WITH_VIEW
  if (auto e = view::finish_view_options(raw.view_strs, &a.view_opts)) {
    std::cerr << "hemm-operator: " << *e << "\n";
    return net::kExitUsage;
  }
#endif
  if (!a.replay_file.empty() && op::looks_like_recording(a.replay_file)) {
    if (!op::runner::setup_logging(a.log_level)) return net::kExitUsage;
    return op::runner::replay_recording(a);
  }
  if (!finish_route_args(raw, &a)) return net::kExitUsage;
  if (!op::runner::setup_logging(a.log_level)) return net::kExitUsage;
  config::OperatorConfig cfg;
  if (!load_config(&a, &cfg)) return net::kExitUsage;
  apply_hand6_args(raw, &cfg);
  if (!apply_task_args(raw, a, &cfg)) return net::kExitUsage;
  if (raw.print_hand6_route) return print_hand6_route(cfg, a);
  apply_hand3_args(raw, &cfg);
  apply_telemanip_mode(raw, &cfg);
  if (raw.print_hand3_route && cfg.probe_3d().hand3_script().empty()) {
    std::cerr << "hemm-operator: --print-hand3-route needs --hand3-script (or probe_3d.hand3_script)\n";
    return net::kExitUsage;
  }
  if (!cfg.probe_3d().hand3_script().empty() && !check_hand3_route(cfg, a, raw.print_hand3_route))
    return net::kExitUsage;
  if (raw.print_hand3_route) return net::kExitOk;
  return dispatch(cfg, a);
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
