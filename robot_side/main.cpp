// hemm-robot: the robot station. Runs the SIMULATED robot (MuJoCo scene,
// 1 kHz, real time) behind the link: listens for an operator, authenticates
// it, streams robot state and range scans, applies the controlling operator's
// commands, mode changes and e-stop, stops the robot when the link is lost,
// and prints link and robot statistics at exit. The config's kind picks the
// robot: "mobile" (the Pioneer base with the 5-DoF arm, robot_station.h) or
// "twoarm" (the SIMULATED two-arm robot at the workbench, twoarm_station.h;
// docs/telemanipulation.md). The robot's own (local)
// e-stop: a key on the terminal (space or e engages, R releases) when stdin
// is one, or `hemm-robot estop|release --control-socket PATH` against a
// running station started with --control-socket PATH; only the robot
// station releases it.
#include <CLI/CLI.hpp>

#include <cmath>
#include <functional>
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <iostream>

#include "common/config/config.h"
#include "common/net/crypto.h"
#include "common/net/exit_codes.h"
#include "common/net/station_cli.h"
#include "common/net/station_control.h"
#include "common/terminal/terminal_keys.h"
#include "config_robot.pb.h"
#include "report.pb.h"
#include "robot_side/server/robot_server.h"
#include "robot_side/station/robot_station.h"
#include "robot_side/twoarm/twoarm_station.h"
#ifdef HEMM_WITH_VIEW
#include "common/view/view_options.h"
#include "robot_side/view/robot_view.h"
#include "robot_side/view/twoarm_view.h"
#endif

namespace {

using namespace hemm;

// The link statistics with the robot station's counters as its "robot"
// object (the two-arm station's as "twoarm").
std::string stats_json_text(const net::LinkStatistics& link, const robot::RobotStationStatistics& rs) {
  report::Link r = net::to_report(link);
  *r.mutable_robot() = robot::to_report(rs);
  return config::to_json(r);
}
std::string stats_json_text(const net::LinkStatistics& link, const twoarm::TwoArmStationStatistics& rs) {
  report::Link r = net::to_report(link);
  *r.mutable_twoarm() = twoarm::to_report(rs);
  return config::to_json(r);
}

struct ServeOptions {
  double duration_s = 0.0, stats_period_s = 0.0;
  std::string stats_json, station_json;
  net::StationControlOptions control;
};

// Runs a loaded station (RobotStation or TwoArmStation) behind the started
// server on this thread (the network thread) until a signal or the duration:
// the robot's own e-stop (control socket, terminal keys), periodic stats,
// and the summary and JSON files at exit.
template <class Station>
int serve(asio::io_context& io, robot::RobotServer& server, Station& station, const ServeOptions& so,
          const std::function<void()>& after_start, const std::function<void()>& before_exit) {
  std::string error;
  if (!station.start(&error)) {
    std::cerr << "hemm-robot: " << error << "\n";
    spdlog::error("event=start_failed error=\"{}\"", error);
    return net::kExitInternal;
  }
  if (after_start) after_start();

  bool stopping = false;
  asio::steady_timer grace(io);
  auto shutdown = [&](const std::string& why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("event=shutdown reason=\"{}\"", why);
    station.stop();  // the robot stops being simulated before the operator is told Bye
    server.stop(why);
    // Let the Bye reach the socket, then leave.
    grace.expires_after(std::chrono::milliseconds(200));
    grace.async_wait([&](const asio::error_code&) { io.stop(); });
  };
  // The robot's own e-stop: a control socket, terminal keys.
  std::unique_ptr<net::ControlServer> control;
  if (!so.control.socket.empty()) {
    control = std::make_unique<net::ControlServer>(
        io, so.control.socket, [&](const std::string& cmd, net::ControlServer::Respond respond) {
          if (cmd == "estop" || cmd == "release") {
            station.local_estop(cmd == "estop", "control socket");
            respond(cmd == "estop" ? "ok e-stop engaged at the robot" : "ok e-stop at the robot released");
          } else if (cmd == "status") {
            const auto rs = station.statistics();
            respond(std::string("ok estop=") + (rs.estop ? "engaged" : "released") +
                    " local=" + (rs.estop_local ? "engaged" : "released") + " link=" +
                    (server.link_up() ? "up" : "down") + " operator=" +
                    (server.operator_in_control() ? "in_control" : "none"));
          } else {
            respond("error unknown command (estop, release, status)");
          }
        });
    if (!control->start(&error)) {
      std::cerr << "hemm-robot: " << error << "\n";
      spdlog::error("event=start_failed error=\"{}\"", error);
      station.stop();
      server.stop("bad control socket");
      return net::kExitUsage;
    }
  }
  terminal::TerminalKeys keys(io, STDIN_FILENO, [&](char k) {
    if (k == ' ' || k == 'e' || k == 'E') station.local_estop(true, "terminal key");
    if (k == 'R') station.local_estop(false, "terminal key");
  });
  net::start_estop_keys(keys, so.control);
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const asio::error_code& ec, int sig) {
    if (!ec) shutdown(sig == SIGINT ? "SIGINT" : "SIGTERM");
  });
  asio::steady_timer duration(io);
  if (so.duration_s > 0) {
    duration.expires_after(std::chrono::milliseconds(static_cast<int64_t>(so.duration_s * 1000)));
    duration.async_wait([&](const asio::error_code& ec) {
      if (!ec) shutdown("duration reached");
    });
  }
  asio::steady_timer stats_timer(io);
  std::function<void()> stats_tick = [&] {
    if (so.stats_period_s <= 0) return;
    stats_timer.expires_after(std::chrono::milliseconds(static_cast<int64_t>(so.stats_period_s * 1000)));
    stats_timer.async_wait([&](const asio::error_code& ec) {
      if (ec || stopping) return;
      spdlog::info("event=stats {}", net::to_log_fields(server.statistics()));
      spdlog::info("event=robot_stats {}", to_log_fields(station.statistics()));
      stats_tick();
    });
  };
  stats_tick();

  // This thread is the network thread; the simulation runs on the station's
  // own thread and reads server.link_up() / operator_in_control().
  io.run();
  keys.stop();
  if (control) control->stop();
  station.stop();
  if (before_exit) before_exit();

  const net::LinkStatistics st = server.statistics();
  const auto rs = station.statistics();
  std::cout << net::to_summary(st) << to_summary(rs) << std::flush;
  if (!so.stats_json.empty() && !net::write_text_file(so.stats_json, stats_json_text(st, rs), &error)) {
    std::cerr << "hemm-robot: " << error << "\n";
    return net::kExitInternal;
  }
  if (!so.station_json.empty() && !net::write_text_file(so.station_json, config::to_json(to_report(rs)), &error)) {
    std::cerr << "hemm-robot: --station-json: " << error << "\n";
    return net::kExitInternal;
  }
  return net::kExitOk;
}

int run(int argc, char** argv) {
  CLI::App app{"hemm-robot: the robot station of hemm: the SIMULATED robot (MuJoCo) behind the link "
               "(authenticated session, state and scan streams, commands, e-stop, link statistics). The config's "
               "kind picks the robot: \"mobile\" (base and 5-DoF arm, the default) or \"twoarm\" (two 7-DoF arms "
               "with grippers at a workbench, head depth camera; deploy/configs/robot_twoarm.pbtxt, "
               "docs/telemanipulation.md)."};
  app.footer(net::kExitCodeHelp);
  std::string config_path, key_path, listen, log_level = "info", stats_json;
  int session_port = -1, stream_port = -1;
  double duration_s = 0.0, stats_period_s = 0.0;
  app.add_option("--config", config_path,
                 "robot config (text protobuf; default: configs/robot.pbtxt of the data directory, docs/install.md)");
  app.add_option("--key", key_path, "pre-shared key file (64 hex chars); overrides link.key_file");
  app.add_option("--listen", listen, "address to listen on (overrides net.listen_address)");
  app.add_option("--session-port", session_port, "TCP session port (overrides net.session_port; 0: any)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--stream-port", stream_port, "UDP stream port (overrides net.stream_port; 0: any)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--duration", duration_s, "run for this many seconds (0: until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off");
  app.add_option("--stats-period", stats_period_s, "log link statistics every this many seconds (0: never)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--stats-json", stats_json,
                 "write the final link statistics (with a \"robot\" object) as JSON to this file");
  std::string scene_path;
  bool no_realtime = false;
  app.add_option("--scene", scene_path,
                 "MJCF scene of the SIMULATED robot (overrides sim.scene; kind twoarm without sim.scene: "
                 "../scenes/workbench.xml of the config)");
  std::vector<double> start;
  app.add_option("--start", start,
                 "X,Y,THETA: the SIMULATED robot's start pose in W (m, rad; overrides sim.start_* and the scene's "
                 "robot_start site)")
      ->delimiter(',')
      ->expected(3);
  app.add_flag("--no-realtime", no_realtime,
               "step the simulation as fast as possible instead of in real time (stamps are simulation time)");
  int control_cpu = -1;
  app.add_option("--control-cpu", control_cpu,
                 "pin the 1 kHz control (simulation) thread to this CPU (overrides sim.control_cpu; -1: not pinned); "
                 "a CPU this process may not run on is refused (docs/realtime.md)");
  std::string station_json;
  app.add_option("--station-json", station_json,
                 "write the robot station's summary (the \"robot\" object of --stats-json: counters, the control "
                 "loop's deadline histograms and worst ticks) as JSON to this file at exit");
  std::string truth_trace;
  app.add_option("--truth-trace", truth_trace,
                 "kind twoarm with twoarm.task set: write the task judge's SIMULATION ONLY truth every 10 ms (grasp "
                 "sites and targets with their orientations, contact force on each gripper, squeezes, object contacts, goal errors) as CSV to "
                 "this file at exit (the first 20 minutes of robot time)");
  net::StationControlOptions control_options;
  net::add_station_control_options(app, "hemm-robot", &control_options);
#ifdef HEMM_WITH_VIEW
  view::ViewOptions view_opts;  // SIMULATION ONLY: the scene as simulated
  view::ViewOptionStrings view_strs;
  view::add_view_options(app, &view_opts, &view_strs);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? net::kExitOk : net::kExitUsage;
  }
  if (!control_options.command.empty()) return net::run_control_command("hemm-robot", control_options);
#ifdef HEMM_WITH_VIEW
  if (auto e = view::finish_view_options(view_strs, &view_opts)) {
    std::cerr << "hemm-robot: " << *e << "\n";
    return net::kExitUsage;
  }
#endif
  if (!net::setup_station_logging("robot", log_level)) {
    std::cerr << "hemm-robot: bad --log-level '" << log_level << "'\n";
    return net::kExitUsage;
  }

  config::RobotConfig cfg;
  if (config_path.empty()) config_path = net::default_station_config("robot", "robot.pbtxt");
  if (!config_path.empty()) {
    if (auto err = config::load_robot_config(config_path, &cfg)) {
      std::cerr << "hemm-robot: bad config: " << err->to_string() << "\n";
      spdlog::error("event=bad_config error=\"{}\"", err->to_string());
      return net::kExitUsage;
    }
  }
  if (!start.empty()) {
    if (start.size() != 3 || !std::isfinite(start[0]) || !std::isfinite(start[1]) || !std::isfinite(start[2])) {
      std::cerr << "hemm-robot: --start: expected X,Y,THETA (three finite numbers)\n";
      return net::kExitUsage;
    }
    cfg.mutable_sim()->set_start_x_m(start[0]);
    cfg.mutable_sim()->set_start_y_m(start[1]);
    cfg.mutable_sim()->set_start_theta_rad(start[2]);
  }
  if (cfg.kind() != "mobile" && cfg.kind() != "twoarm") {
    // load_robot_config refuses it already; a config built otherwise too.
    std::cerr << "hemm-robot: kind \"" << cfg.kind() << "\": must be mobile or twoarm\n";
    return net::kExitUsage;
  }
  if (cfg.kind() == "twoarm" && !start.empty()) {
    std::cerr << "hemm-robot: --start is the mobile robot's start pose; kind twoarm stands at its workbench\n";
    return net::kExitUsage;
  }
  if (cfg.kind() != "twoarm" && !truth_trace.empty()) {
    std::cerr << "hemm-robot: --truth-trace is the two-arm station's (kind twoarm with a task)\n";
    return net::kExitUsage;
  }
  const std::string listen_address = listen.empty() ? cfg.net().listen_address() : listen;
  const auto key =
      net::load_station_key("hemm-robot", key_path, config_path, cfg.link().key_file(), listen_address);
  if (!key) return net::kExitKey;

  robot::RobotServerOptions o;
  net::apply_link_config(cfg.link(), *key, &o);
  o.listen_address = listen_address;
  o.session_port = static_cast<uint16_t>(session_port >= 0 ? session_port : static_cast<int>(cfg.net().session_port()));
  o.stream_port = static_cast<uint16_t>(stream_port >= 0 ? stream_port : static_cast<int>(cfg.net().stream_port()));

  ServeOptions serve_options;
  serve_options.duration_s = duration_s;
  serve_options.stats_period_s = stats_period_s;
  serve_options.stats_json = stats_json;
  serve_options.station_json = station_json;
  serve_options.control = control_options;
  rt::RealtimeRequest control_thread;
  control_thread.fifo = cfg.sim().control_fifo_priority() > 0;
  control_thread.fifo_priority = cfg.sim().control_fifo_priority();
  control_thread.cpu = app.count("--control-cpu") > 0 ? control_cpu : cfg.sim().control_cpu();
  if (auto why = rt::check_cpu(control_thread.cpu)) {
    std::cerr << "hemm-robot: " << (app.count("--control-cpu") > 0 ? "--control-cpu" : "sim.control_cpu") << " "
              << control_thread.cpu << ": " << *why << "\n";
    return net::kExitUsage;
  }
  const bool realtime = cfg.sim().realtime() && !no_realtime;

  asio::io_context io;
  robot::RobotServer server(io, o);
  std::string error;
  if (cfg.kind() == "twoarm") {
    // The SIMULATED two-arm robot: the workbench unless the config or --scene names another.
    if (scene_path.empty())
      scene_path = config::resolve_relative_to(config_path, cfg.sim().has_scene() ? cfg.sim().scene()
                                                                                 : "../scenes/workbench.xml");
    if (!truth_trace.empty() && cfg.twoarm().task().empty()) {
      std::cerr << "hemm-robot: --truth-trace needs a task to judge (twoarm.task in the config)\n";
      return net::kExitUsage;
    }
    twoarm::TwoArmStationOptions to;
    to.truth_trace_s = truth_trace.empty() ? 0.0 : 1200.0;
    to.realtime = realtime;
    to.state_rate_hz = cfg.net().state_rate_hz();
    to.control_thread = control_thread;
    twoarm::TwoArmStation station(io, server, to);
    if (auto err = station.load(cfg, scene_path)) {
      std::cerr << "hemm-robot: cannot load the two-arm robot from '" << scene_path << "': " << *err << "\n";
      spdlog::error("event=bad_scene scene=\"{}\" error=\"{}\"", scene_path, *err);
      return net::kExitUsage;
    }
    spdlog::info("event=robot_sim kind=twoarm scene=\"{}\" timestep_ms={} realtime={} state_rate_hz={} watchdog_ms={} "
                 "head_depth_camera={}",
                 scene_path, station.timestep_ns() * 1e-6, to.realtime, to.state_rate_hz, cfg.safety().watchdog_ms(),
                 station.depth_camera_enabled());
#ifdef HEMM_WITH_VIEW
    std::unique_ptr<robot::TwoArmLiveView> twoarm_view;
    if (view_opts.enabled()) {
      twoarm_view = std::make_unique<robot::TwoArmLiveView>(view_opts, scene_path);
      if (auto err = station.attach_view(twoarm_view->feed())) {
        std::cerr << "hemm-robot: --view: " << *err << "\n";
        return net::kExitUsage;
      }
    }
#endif
    if (!server.start(&error)) {
      std::cerr << "hemm-robot: " << error << "\n";
      spdlog::error("event=start_failed error=\"{}\"", error);
      return net::kExitUsage;
    }
    bool trace_failed = false;
    const auto before_exit = [&] {
#ifdef HEMM_WITH_VIEW
      if (twoarm_view) twoarm_view->stop();
#endif
      if (truth_trace.empty()) return;
      std::string e;
      if (!net::write_text_file(truth_trace, twoarm::truth_trace_csv(station.truth_trace()), &e)) {
        std::cerr << "hemm-robot: --truth-trace: " << e << "\n";
        trace_failed = true;
      }
    };
    std::function<void()> view_start;
#ifdef HEMM_WITH_VIEW
    view_start = [&] {
      if (twoarm_view) twoarm_view->start();
    };
#endif
    const int rc = serve(io, server, station, serve_options, view_start, before_exit);
    return rc == 0 && trace_failed ? net::kExitInternal : rc;
  }

  // The SIMULATED mobile robot: the scene relative to the config file unless given.
  if (scene_path.empty()) scene_path = config::resolve_relative_to(config_path, cfg.sim().scene());
  robot::RobotStationOptions so;
  so.realtime = realtime;
  so.state_rate_hz = cfg.net().state_rate_hz();
  so.control_thread = control_thread;
  robot::RobotStation station(io, server, so);
  if (auto err = station.load(cfg, scene_path)) {
    std::cerr << "hemm-robot: cannot load scene '" << scene_path << "': " << *err << "\n";
    spdlog::error("event=bad_scene scene=\"{}\" error=\"{}\"", scene_path, *err);
    return net::kExitUsage;
  }
  {
    const auto& lp = station.laser_params();
    const auto& sp = station.sonar_params();
    spdlog::info("event=robot_sim scene=\"{}\" timestep_ms={} realtime={} state_rate_hz={} watchdog_ms={}", scene_path,
                 station.timestep_ns() * 1e-6, so.realtime, so.state_rate_hz, cfg.safety().watchdog_ms());
    spdlog::info("event=sensor name=laser enabled={} beams={} rate_hz={} range_m={}..{}", station.laser_enabled(),
                 lp.beams, lp.rate_hz, lp.range_min, lp.range_max);
    spdlog::info("event=sensor name=sonar enabled={} count={} rays_per_cone={} rate_hz={} range_m={}..{}",
                 station.sonar_enabled(), sp.count, sp.rays_per_cone, sp.rate_hz, sp.range_min, sp.range_max);
  }
#ifdef HEMM_WITH_VIEW
  std::unique_ptr<robot::RobotLiveView> live_view;
  if (view_opts.enabled()) {
    live_view = std::make_unique<robot::RobotLiveView>(view_opts, scene_path);
    station.attach_view(live_view->feed());
  }
#endif
  if (!server.start(&error)) {
    std::cerr << "hemm-robot: " << error << "\n";
    spdlog::error("event=start_failed error=\"{}\"", error);
    return net::kExitUsage;
  }
  std::function<void()> after_start, before_exit;
#ifdef HEMM_WITH_VIEW
  after_start = [&] {
    if (live_view) live_view->start();
  };
  before_exit = [&] {
    if (live_view) live_view->stop();
  };
#endif
  return serve(io, server, station, serve_options, after_start, before_exit);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "hemm-robot: internal error: " << e.what() << "\n";
    return hemm::net::kExitInternal;
  }
}
