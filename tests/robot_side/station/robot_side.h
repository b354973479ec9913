// Test helper: the SIMULATED robot station (RobotStation behind a RobotServer
// on ephemeral loopback ports) on its own network thread, started and torn
// down the way the loopback tests need it.
#pragma once

#include <asio.hpp>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "config_robot.pb.h"
#include "robot_side/server/robot_server.h"
#include "robot_side/station/robot_station.h"
#include "tests/robot_side/station/station_io.h"

namespace hemm::test {

struct RobotSide : StationIo {
  std::unique_ptr<robot::RobotServer> server;
  std::unique_ptr<robot::RobotStation> station;
  config::RobotConfig cfg;
  std::string scene;

  // control_cpu: pin the station's control thread there (-1: not pinned).
  RobotSide(const config::RobotConfig& c, const net::Key& key, std::string scene_path, int control_cpu = -1)
      : cfg(c), scene(std::move(scene_path)) {
    server = std::make_unique<robot::RobotServer>(io, loopback_server_options(cfg, key));
    robot::RobotStationOptions so;
    so.state_rate_hz = cfg.net().state_rate_hz();
    so.control_thread.cpu = control_cpu;
    station = std::make_unique<robot::RobotStation>(io, *server, so);
  }
  void start() {
    std::string err;
    ASSERT_TRUE(server->start(&err)) << err;
    const auto load_err = station->load(cfg, scene);
    ASSERT_FALSE(load_err) << *load_err;
    ASSERT_TRUE(station->start(&err)) << err;
    run();
  }
  ~RobotSide() {
    station->stop();
    shutdown(*server);
  }
};

}  // namespace hemm::test
