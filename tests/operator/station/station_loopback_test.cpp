// End to end over real loopback sockets: a FAKE robot (RobotServer on its own
// network thread, streaming a SIMULATED wall scan and a still RobotState) and
// the real operator station (OperatorClient + OperatorStation: simulated Omni
// with a scripted hand, servo loop, model thread, command sender). Shows that
// commands arrive at >= 100 Hz, the mode change arrives, the operator's model
// holds the wall, and pushing the probe into it gives a force.
// Timing assertions use wide margins: the VM is shared and stalls for ms.
#include <gtest/gtest.h>
#include <numbers>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <mutex>
#include <utility>
#include <optional>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "operator/client/operator_client.h"
#include "operator/station/operator_station.h"
#include "robot_side/server/robot_server.h"
#include "tests/operator/client/loopback_client.h"

namespace ho = hemm::op;
namespace hw = hemm::wire;
namespace hn = hemm::net;
namespace hm = hemm::math;

namespace {

hn::Key test_key() {
  hn::Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(31 * i + 7);
  return k;
}

constexpr double kWallX = 1.0;  // W, the robot sits at the origin heading +x

// Robot side: RobotServer + timers streaming state (200 Hz) and a laser scan
// of the wall x = kWallX in two chunks (20 Hz); records commands.
struct FakeRobot {
  asio::io_context io;
  std::unique_ptr<hemm::robot::RobotServer> server;
  asio::steady_timer timer{io};
  std::thread thread;
  std::mutex mu;
  std::vector<std::int64_t> command_recv_ns;
  std::vector<hw::Command> commands;
  std::vector<hw::ModeChange> modes;
  std::uint32_t tick = 0;
  std::uint32_t scan_id = 0;

  FakeRobot() {
    hemm::robot::RobotServerOptions o;
    o.session_port = 0;
    o.stream_port = 0;
    o.psk = test_key();
    server = std::make_unique<hemm::robot::RobotServer>(io, o);
    server->streams().on(hw::StreamMessage::kCommand,
                         [this](const hn::DatagramHeader&, int64_t recv, const hw::StreamMessage& m) {
                           std::lock_guard<std::mutex> lk(mu);
                           command_recv_ns.push_back(recv);
                           commands.push_back(m.command());
                         });
    server->on_session_frame(hw::SessionFrame::kModeChange, [this](const hw::SessionFrame& f) {
      {
        std::lock_guard<std::mutex> lk(mu);
        modes.push_back(f.mode_change());
      }
      hw::SessionFrame ack;
      ack.mutable_ack()->set_request_id(f.mode_change().request_id());
      ack.mutable_ack()->set_ok(true);
      server->send_session_frame(ack);
    });
    std::string err;
    EXPECT_TRUE(server->start(&err)) << err;
    stream();
    thread = std::thread([this] { io.run(); });
  }
  ~FakeRobot() {
    asio::post(io, [this] {
      timer.cancel();
      server->stop("test over");
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    io.stop();
    thread.join();
  }
  void stream() {
    timer.expires_after(std::chrono::milliseconds(5));
    timer.async_wait([this](const asio::error_code& ec) {
      if (ec) return;
      if (server->link_up()) {
        hw::StreamMessage m;
        auto* st = m.mutable_robot_state();
        st->set_stamp_ns(hemm::steady_now_ns());
        st->mutable_t_w_r_odom()->set_x(0.0);
        st->set_mode(hw::MODE_EXPLORATION);
        server->streams().send(m);
        if (tick % 10 == 0) send_scan();
      }
      ++tick;
      stream();
    });
  }
  void send_scan() {
    const std::uint32_t n = 181;
    const double a0 = -std::numbers::pi / 2, step = std::numbers::pi / 180;
    ++scan_id;
    for (std::uint32_t first : {0u, 91u}) {
      hw::StreamMessage m;
      auto* s = m.mutable_range_scan();
      s->set_stamp_ns(hemm::steady_now_ns());
      s->set_scan_id(scan_id);
      s->set_sensor(hw::RANGE_SENSOR_LASER);
      s->mutable_t_w_r()->set_x(0.0);
      s->mutable_t_r_s()->mutable_orientation()->set_w(1.0);
      s->set_angle_min(a0);
      s->set_angle_step(step);
      s->set_beam_count(n);
      s->set_first_beam(first);
      s->set_range_min(0.05);
      s->set_range_max(10.0);
      const std::uint32_t end = first == 0 ? 91u : n;
      for (std::uint32_t i = first; i < end; ++i) {
        const double c = std::cos(a0 + i * step);
        const double r = c > 1e-3 ? kWallX / c : 20.0;
        s->add_ranges(static_cast<float>(std::min(r, 20.0)));
        s->add_valid(r < 10.0);
      }
      server->streams().send(m);
    }
  }
};

TEST(StationLoopback, CommandsFlowModelHoldsTheWallAndTheProbeFeelsIt) {
  FakeRobot robot;
  asio::io_context io;
  ho::OperatorClient client(io, hemm::test::loopback_client_options("station-test", robot.server->session_port(), test_key()));
  ho::OperatorStationOptions so = hemm::test::loopback_station_options("station_loopback_test.csv");
  // Exploration (scale 50): the hand moves the stylus 22 mm forward -> 1.1 m
  // ahead, 0.13 m past the proxy's stop at the wall.
  so.task.initial_mode = hm::Mode::kExploration;
  const Eigen::Vector3d fwd_H = ho::R_B_H().transpose() * Eigen::Vector3d(0.022, 0.0, 0.0);
  so.hand = std::make_shared<hemm::device::LineScript>(Eigen::Vector3d::Zero(), fwd_H, 0.03, 0.5);
  ho::OperatorStation station(io, client, so);
  // What a session recording would get: every session frame, both ways.
  std::mutex tap_mu;
  std::vector<std::pair<bool, hw::SessionFrame>> frames;  // (outgoing, frame)
  ho::OperatorStation::SessionTaps taps;
  taps.on_session = [&](std::int64_t, bool outgoing, const hw::SessionFrame& f) {
    std::lock_guard<std::mutex> lk(tap_mu);
    frames.emplace_back(outgoing, f);
  };
  station.attach_session_taps(std::move(taps));

  std::string err;
  ASSERT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  station.start();
  std::thread net([&] { io.run(); });
  const std::int64_t t0 = hemm::steady_now_ns();
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  const bool link_was_up = client.link_up();
  station.stop();
  asio::post(io, [&] { client.stop("test over"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  io.stop();
  net.join();
  EXPECT_TRUE(link_was_up);

  // Commands at >= 100 Hz once the link is up (nominal 200 Hz).
  std::vector<std::int64_t> recv;
  std::vector<hw::Command> cmds;
  std::vector<hw::ModeChange> modes;
  {
    std::lock_guard<std::mutex> lk(robot.mu);
    recv = robot.command_recv_ns;
    cmds = robot.commands;
    modes = robot.modes;
  }
  ASSERT_GT(recv.size(), 50u);
  const double span_s = static_cast<double>(recv.back() - recv.front()) * 1e-9;
  const double rate = static_cast<double>(recv.size() - 1) / span_s;
  std::vector<std::int64_t> gaps;
  for (std::size_t i = 1; i < recv.size(); ++i) gaps.push_back(recv[i] - recv[i - 1]);
  std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
  const double median_gap_ms = static_cast<double>(gaps[gaps.size() / 2]) * 1e-6;
  std::printf("commands: %zu over %.2f s = %.1f Hz, median gap %.2f ms (first after %.0f ms)\n", recv.size(),
              span_s, rate, median_gap_ms, (recv.front() - t0) * 1e-6);
  EXPECT_GE(rate, 100.0);
  EXPECT_LE(median_gap_ms, 10.0);
  for (const auto& c : cmds) {
    EXPECT_EQ(c.mode(), hw::MODE_EXPLORATION);
    EXPECT_FALSE(c.deadman());  // exploration never moves the robot
  }
  ASSERT_FALSE(modes.empty());
  EXPECT_EQ(modes.front().mode(), hw::MODE_EXPLORATION);
  // The session taps saw the mode change go out and the robot's ack come in.
  {
    std::lock_guard<std::mutex> lk(tap_mu);
    std::uint64_t sent_id = 0;
    bool acked = false;
    for (const auto& [outgoing, f] : frames) {
      if (outgoing && f.has_mode_change()) sent_id = f.mode_change().request_id();
      if (!outgoing && f.has_ack() && f.ack().request_id() == sent_id && f.ack().ok()) acked = true;
    }
    EXPECT_NE(sent_id, 0u);
    EXPECT_TRUE(acked) << frames.size() << " session frames tapped";
  }

  // The operator's model holds the wall x = 1 (and nothing else).
  const auto& segs = station.model().map().segments;
  ASSERT_GT(segs.size(), 10u);
  for (const auto& s : segs) {
    EXPECT_NEAR(s.a.x(), kWallX, 0.02);
    EXPECT_NEAR(s.b.x(), kWallX, 0.02);
  }
  const ho::ModelStats ms = station.model().stats();
  EXPECT_GT(ms.scans_in, 10u);
  EXPECT_EQ(ms.scans_rejected, 0u);
  EXPECT_GT(ms.states_in, 10u);

  // The probe is pushed into the wall: the proxy rests on it, the force pushes back (-x in W).
  const auto& proxy = station.task().proxy();
  std::printf("proxy (%.3f, %.3f), force_W (%.3f, %.3f) N\n", proxy.proxy_W.x(), proxy.proxy_W.y(),
              proxy.force_W.x(), proxy.force_W.y());
  EXPECT_NEAR(proxy.proxy_W.x(), kWallX - 0.03, 0.01);
  // At rest the simulated hand's spring (200 N/m) and the proxy's (300 N/m)
  // share the commanded penetration: F = (k_h k / (k_h + k)) * 0.13 m / 50.
  const double f_expected = 200.0 * 300.0 / 500.0 * (1.1 - (kWallX - 0.03)) / 50.0;
  EXPECT_NEAR(proxy.force_W.x(), -f_expected, 0.03);
  EXPECT_NEAR(proxy.force_W.y(), 0.0, 0.05);

  const ho::OperatorStationSummary sum = station.summary();
  std::printf("%s", ho::to_string(sum).c_str());
  EXPECT_GT(sum.timing.ticks, 1500u);
  EXPECT_GT(sum.servo_log_written, 1000u);
  EXPECT_GT(sum.world_log_written, 1000u);
  std::ifstream map_csv(so.log_path + ".map.csv");
  EXPECT_TRUE(map_csv.good());
}

// Issue 23 item 2: the wire's dead-man is the hand's dead-man input, not
// "the mode moves the robot". The SIMULATED hand drives in navigation (the
// stylus 20 mm forward: well out of the dead band) but never presses the
// dead-man: no command may carry it, and none asks for motion.
TEST(StationLoopback, InNavigationWithTheDeadManReleasedNoCommandCarriesTheDeadManOrAsksForMotion) {
  FakeRobot robot;
  asio::io_context io;
  ho::OperatorClient client(io, hemm::test::loopback_client_options("station-test", robot.server->session_port(), test_key()));
  ho::OperatorStationOptions so = hemm::test::loopback_station_options("station_loopback_deadman_test.csv");
  so.task.initial_mode = hm::Mode::kNavigation;
  const Eigen::Vector3d fwd_H = ho::R_B_H().transpose() * Eigen::Vector3d(0.020, 0.0, 0.0);
  so.hand = std::make_shared<hemm::device::LineScript>(Eigen::Vector3d::Zero(), fwd_H, 0.03, 0.5);
  ho::OperatorStation station(io, client, so);
  std::string err;
  ASSERT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  station.start();
  std::thread net([&] { io.run(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));
  station.stop();
  asio::post(io, [&] { client.stop("test over"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  io.stop();
  net.join();
  std::vector<hw::Command> cmds;
  {
    std::lock_guard<std::mutex> lk(robot.mu);
    cmds = robot.commands;
  }
  ASSERT_GT(cmds.size(), 100u);
  std::size_t pressed = 0, moving = 0;
  for (const auto& c : cmds) {
    EXPECT_EQ(c.mode(), hw::MODE_NAVIGATION);
    pressed += c.deadman();
    moving += c.v() != 0.0 || c.omega() != 0.0;
  }
  std::printf("%zu commands: %zu with the dead-man, %zu asking for motion; the task's last setpoint v = %.3f m/s\n",
              cmds.size(), pressed, moving, station.task().last_setpoint().v);
  EXPECT_GT(station.task().last_setpoint().v, 0.05) << "the hand did drive (the task's command)";
  EXPECT_EQ(pressed, 0u);
  EXPECT_EQ(moving, 0u);
}

}  // namespace
