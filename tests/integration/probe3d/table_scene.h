// Shared by the live-voxmap loopback tests (probe3d, explore3d): the home
// scene, the SIMULATED robot standing before its table with the mast depth
// camera on, a test key, the servo thread's allocation counter hook (the world log's reader and a median: world_log.h).
#pragma once

#include <asio.hpp>

#include <algorithm>
#include <chrono>
#include <thread>
#include <utility>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include "common/net/crypto.h"
#include "config_robot.pb.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/operator/station/world_log.h"  // read_world_log, median

namespace hemm::test {

inline const std::string kHomeScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

inline net::Key table_test_key(std::uint8_t a, std::uint8_t b) {
  net::Key k{};
  for (std::size_t i = 0; i < k.size(); ++i) k[i] = static_cast<std::uint8_t>(a * i + b);
  return k;
}

// The robot at W (1.5, 1.0) facing +y (the table top 1.2 x 0.8 m at z 0.75,
// centre (1.5, 2.0)), its front 0.38 m from the table's edge; depth camera on.
inline config::RobotConfig robot_before_table() {
  config::RobotConfig c;
  c.mutable_sim()->set_start_x_m(1.5);
  c.mutable_sim()->set_start_y_m(1.0);
  c.mutable_sim()->set_start_theta_rad(std::numbers::pi / 2);
  c.mutable_depth_camera()->set_enabled(true);
  return c;
}


// Runs a started station (its client started) for at least `ms` and then
// until done() (polled every 50 ms) with the io_context on a network thread,
// then stops station, client and io. before_stop() runs just before the
// station stops. Returns the heap allocations counted meanwhile (the servo
// thread's, with count_allocations_on_this_thread as its hook).
template <class Station, class Client, class D, class F>
std::uint64_t run_station_until(asio::io_context& io, Client& client, Station& station, int ms, D&& done,
                                F&& before_stop) {
  const std::uint64_t before = counted_allocations();
  station.start();
  std::thread net([&] { io.run(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
  while (!done()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  before_stop();
  station.stop();
  const std::uint64_t allocs = counted_allocations() - before;
  asio::post(io, [&] { client.stop("test over"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  io.stop();
  net.join();
  return allocs;
}

// The same for `ms` exactly.
template <class Station, class Client, class F>
std::uint64_t run_station_for(asio::io_context& io, Client& client, Station& station, int ms, F&& before_stop) {
  return run_station_until(io, client, station, ms, [] { return true; }, std::forward<F>(before_stop));
}

}  // namespace hemm::test
