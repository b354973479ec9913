// Test helper for both robot stations' loopback tests: the network thread
// (io_context, work guard, thread) a station's RobotServer runs on, and the
// server's options on ephemeral loopback ports.
#pragma once

#include <asio.hpp>
#include <chrono>
#include <optional>
#include <thread>

#include "config_robot.pb.h"
#include "robot_side/server/robot_server.h"

namespace hemm::test {

// A station's network thread for the loopback tests (both robot stations):
// the io_context its RobotServer and handlers run on, kept running until
// shutdown().
struct StationIo {
  asio::io_context io;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work;
  std::thread thread;

  void run() {
    work.emplace(io.get_executor());
    thread = std::thread([this] { io.run(); });
  }
  // The server says Bye on its own thread, then the loop ends.
  void shutdown(robot::RobotServer& server) {
    asio::post(io, [&server] { server.stop("test over"); });
    work.reset();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    io.stop();
    if (thread.joinable()) thread.join();
  }
};

// A server on ephemeral loopback ports with the config's link timeout.
inline robot::RobotServerOptions loopback_server_options(const config::RobotConfig& cfg, const net::Key& key) {
  robot::RobotServerOptions o;
  o.session_port = 0;
  o.stream_port = 0;
  o.psk = key;
  o.link_timeout_ms = cfg.link().link_timeout_ms();
  return o;
}

}  // namespace hemm::test
