// The networked operator station: connects to the robot, authenticates, runs
// the device (SIMULATED Omni with a scripted hand, a replayed trajectory, the
// 3D probe or the 6-DoF tool of probe_3d, the bimanual device's right arm
// holding that tool) in the servo loop against the local model built from
// the robot's scans, streams commands, takes the e-stop from a control
// socket and the terminal, optionally records the session, and prints link
// and station statistics at exit. This thread is the network thread.
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <google/protobuf/text_format.h>
#include <chrono>
#include <csignal>
#include <functional>
#include <iostream>
#include <memory>
#include <unistd.h>

#include "common/config/config.h"
#include "common/net/session_connection.h"
#include "common/net/station_control.h"
#include "common/terminal/terminal_keys.h"
#include "operator/client/operator_client.h"
#include "operator/record/session_recording.h"
#include "operator/runners/runners.h"
#include "operator/station/operator_station.h"
#ifdef HEMM_WITH_VIEW
#include "operator/view/live_view.h"
#endif

namespace hemm::op::runner {

namespace {

OperatorStationOptions station_options(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  OperatorStationOptions so;
  so.device = a.replay_file.empty() ? cfg.device().type() : "replay";
  so.replay_file = !a.replay_file.empty() ? a.replay_file
                   : cfg.device().has_replay_file()
                       ? config::resolve_relative_to(a.config_path, cfg.device().replay_file())
                       : std::string();
  so.script = a.script;
  so.goal_route = a.goal_route;
  so.probe_line = a.probe_line;
  so.log_path = a.servo_log;
  so.model.shapes.enabled = a.shape_completion == "on";
  so.command_rate_hz = cfg.net().command_rate_hz();
  so.servo = servo_config(cfg);
  so.task.proxy.period = static_cast<double>(so.servo.period_ns) * 1e-9;
  // The 3D probe / exploration and the 6-DoF tool (probe_3d block).
  apply_probe3d_config(cfg.probe_3d(), &so);
  // The SIMULATED Omni's hand on an explore3 route (probe_3d.hand3_script; demo_scripts.h).
  if (!cfg.probe_3d().hand3_script().empty())
    so.hand = load_hand3_route(config::resolve_relative_to(a.config_path, cfg.probe_3d().hand3_route()),
                               cfg.probe_3d().hand3_script(), so.task);
  so.hand6_route_file = config::resolve_relative_to(a.config_path, so.hand6_route_file);
  so.bimanual = std::make_shared<const config::BimanualDeviceConfig>(cfg.device().bimanual());
  return so;
}

// --record: the recorder, its header from the config and station, tapped
// into the station. Null (said on stderr) if the file cannot be opened.
std::unique_ptr<SessionRecorder> attach_recorder(const std::string& path, const config::OperatorConfig& cfg,
                                                 const OperatorStationOptions& so, OperatorStation& station) {
  rec::Header h;
  h.set_start_ns(net::steady_now_ns());
  h.set_servo_period_ns(so.servo.period_ns);
  h.set_initial_mode(static_cast<std::uint32_t>(station.task().params().initial_mode));
  h.set_script(so.device == "sim-omni" ? so.script : so.device);
  h.set_end_effectors(station.device().limits().end_effectors);
  h.set_shape_completion_off(!so.model.shapes.enabled);
  google::protobuf::TextFormat::PrintToString(cfg, h.mutable_config_text());
  std::unique_ptr<SessionRecorder> recorder;
  try {
    recorder = std::make_unique<SessionRecorder>(path, h);
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: --record: " << e.what() << "\n";
    return nullptr;
  }
  SessionRecorder* r = recorder.get();
  OperatorStation::SessionTaps taps;
  taps.on_step = [r](const ModelThread::StepInputs& in, const OperatorModelSnapshot& s) {
    r->model_step(in, s.version);
  };
  taps.ticks = &r->ticks();
  taps.on_stream = [r](std::int64_t t, bool out, const wire::StreamMessage& m) { r->stream(t, out, m); };
  taps.on_session = [r](std::int64_t t, bool out, const wire::SessionFrame& f) { r->session(t, out, f); };
  station.attach_session_taps(std::move(taps));
  recorder->start();
  return recorder;
}

}  // namespace

int run_station(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  const std::string robot_address = a.robot.empty() ? cfg.net().robot_address() : a.robot;
  const auto key =
      net::load_station_key("hemm-operator", a.key_path, a.config_path, cfg.link().key_file(), robot_address);
  if (!key) return net::kExitKey;

  const OperatorClientOptions o = client_options(cfg, a, robot_address, *key);
  const OperatorStationOptions so = station_options(cfg, a);

  asio::io_context io;
  OperatorClient client(io, o);
  std::unique_ptr<OperatorStation> station;
  try {
    station = std::make_unique<OperatorStation>(io, client, so);
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    return net::kExitUsage;
  }
  std::unique_ptr<SessionRecorder> recorder;
  if (!a.record_path.empty()) {
    recorder = attach_recorder(a.record_path, cfg, so, *station);
    if (!recorder) return net::kExitUsage;
  }
#ifdef HEMM_WITH_VIEW
  std::unique_ptr<OperatorLiveView> live_view;  // the view thread: started after the station
  if (a.view_opts.enabled())
    live_view = std::make_unique<OperatorLiveView>(a.view_opts, *station, station_view_links(client, *station, io));
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
      // The run ended without ever reaching the robot: that is a failure (a
      // refusal's code if the robot, or something in its place, refused).
      exit_code = client.give_up_code();
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
  if (!a.control_options.socket.empty()) {
    control = std::make_unique<net::ControlServer>(
        io, a.control_options.socket, [&](const std::string& cmd, net::ControlServer::Respond respond) {
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
  terminal::TerminalKeys keys(io, STDIN_FILENO, [&](char k) {
    if (k == ' ' || k == 'e' || k == 'E') estop(true, "terminal key", nullptr);
    if (k == 'R') estop(false, "terminal key", nullptr);
  });
  net::start_estop_keys(keys, a.control_options);
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const asio::error_code& ec, int sig) {
    if (!ec) shutdown(sig == SIGINT ? "SIGINT" : "SIGTERM");
  });
  asio::steady_timer duration(io);
  if (a.duration_s > 0) {
    duration.expires_after(std::chrono::milliseconds(static_cast<int64_t>(a.duration_s * 1000)));
    duration.async_wait([&](const asio::error_code& ec) {
      if (!ec) shutdown("duration reached");
    });
  }
  asio::steady_timer stats_timer(io);
  std::function<void()> stats_tick = [&] {
    if (a.stats_period_s <= 0) return;
    stats_timer.expires_after(std::chrono::milliseconds(static_cast<int64_t>(a.stats_period_s * 1000)));
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
    spdlog::info("event=recorded file=\"{}\" records={} ticks_dropped={} write_failed={}", a.record_path,
                 recorder->records(), recorder->ticks_dropped(), recorder->write_failed());
    if (recorder->write_failed()) std::cerr << "hemm-operator: writing " << a.record_path << " failed\n";
  }
#ifdef HEMM_WITH_VIEW
  if (live_view) live_view->stop();  // after a last picture of the final state
#endif
  const OperatorStationSummary summary = station->summary();
  std::cout << to_string(summary);
  if (!write_station_json(a.station_json, to_json(summary)) && exit_code == net::kExitOk)
    exit_code = net::kExitInternal;

  const net::LinkStatistics st = client.statistics();
  std::cout << net::to_summary(st) << std::flush;
  if (!a.stats_json.empty() && !net::write_text_file(a.stats_json, net::to_json(st), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    if (exit_code == net::kExitOk) exit_code = net::kExitInternal;
  }
  return exit_code;
}

}  // namespace hemm::op::runner
