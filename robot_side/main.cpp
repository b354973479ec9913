// hemm-robot: the robot station. For now (foundation): listens for an
// operator, authenticates it, exchanges heartbeats and ping/pong, reports
// link loss, and prints link statistics at exit.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <iostream>

#include "common/config/config.h"
#include "common/net/crypto.h"
#include "common/net/exit_codes.h"
#include "common/net/station_cli.h"
#include "config_robot.pb.h"
#include "robot_side/server/robot_server.h"

namespace {

using namespace hemm;

int run(int argc, char** argv) {
  CLI::App app{"hemm-robot: the robot station of hemm (link foundation: authenticated session, heartbeats, "
               "ping/pong, link statistics)."};
  app.footer(net::kExitCodeHelp);
  std::string config_path, key_path, listen, log_level = "info", stats_json;
  int session_port = -1, stream_port = -1;
  double duration_s = 0.0, stats_period_s = 0.0;
  app.add_option("--config", config_path, "robot config (text protobuf, e.g. deploy/configs/robot.pbtxt)");
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
  app.add_option("--stats-json", stats_json, "write the final link statistics as JSON to this file");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? net::kExitOk : net::kExitUsage;
  }
  if (!net::setup_station_logging("robot", log_level)) {
    std::cerr << "hemm-robot: bad --log-level '" << log_level << "'\n";
    return net::kExitUsage;
  }

  config::RobotConfig cfg;
  if (!config_path.empty()) {
    if (auto err = config::load_robot_config(config_path, &cfg)) {
      std::cerr << "hemm-robot: bad config: " << err->to_string() << "\n";
      spdlog::error("event=bad_config error=\"{}\"", err->to_string());
      return net::kExitUsage;
    }
  }
  if (key_path.empty() && cfg.link().has_key_file()) {
    key_path = config::resolve_relative_to(config_path, cfg.link().key_file());
  }
  if (key_path.empty()) {
    std::cerr << "hemm-robot: no key: give --key FILE or link.key_file in the config\n";
    return net::kExitKey;
  }
  std::string key_error;
  const auto key = net::load_key_file(key_path, &key_error);
  if (!key) {
    std::cerr << "hemm-robot: bad key file: " << key_error << "\n";
    spdlog::error("event=bad_key error=\"{}\"", key_error);
    return net::kExitKey;
  }

  robot::RobotServerOptions o;
  const auto& link = cfg.link();
  o.station_name = link.station_name();
  o.listen_address = listen.empty() ? cfg.net().listen_address() : listen;
  o.session_port = static_cast<uint16_t>(session_port >= 0 ? session_port : static_cast<int>(cfg.net().session_port()));
  o.stream_port = static_cast<uint16_t>(stream_port >= 0 ? stream_port : static_cast<int>(cfg.net().stream_port()));
  o.psk = *key;
  o.heartbeat_period_ms = link.heartbeat_period_ms();
  o.ping_period_ms = link.ping_period_ms();
  o.link_timeout_ms = link.link_timeout_ms();
  o.handshake_timeout_ms = link.handshake_timeout_ms();
  o.max_frame_bytes = link.max_frame_bytes();
  o.replay_window = link.replay_window();

  asio::io_context io;
  robot::RobotServer server(io, o);
  std::string error;
  if (!server.start(&error)) {
    std::cerr << "hemm-robot: " << error << "\n";
    spdlog::error("event=start_failed error=\"{}\"", error);
    return net::kExitUsage;
  }

  bool stopping = false;
  asio::steady_timer grace(io);
  auto shutdown = [&](const std::string& why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("event=shutdown reason=\"{}\"", why);
    server.stop(why);
    // Let the Bye reach the socket, then leave.
    grace.expires_after(std::chrono::milliseconds(200));
    grace.async_wait([&](const asio::error_code&) { io.stop(); });
  };
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
      spdlog::info("event=stats {}", net::to_log_fields(server.statistics()));
      stats_tick();
    });
  };
  stats_tick();

  // This thread is the network thread for now; later the simulation and
  // controllers run on their own threads and read server.link_up().
  io.run();

  const net::LinkStatistics st = server.statistics();
  std::cout << net::to_summary(st) << std::flush;
  if (!stats_json.empty() && !net::write_text_file(stats_json, net::to_json(st), &error)) {
    std::cerr << "hemm-robot: " << error << "\n";
    return net::kExitInternal;
  }
  return net::kExitOk;
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
