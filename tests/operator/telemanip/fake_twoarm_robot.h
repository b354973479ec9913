// A FAKE two-arm robot over real sockets for the telemanipulation tests
// (libfranka mock-server style): the real RobotServer on its own network
// thread, answering with ArmsState at 250 Hz where each G follows the
// commanded target with a first-order lag while the dead-man is pressed,
// refusing a command whole when a target lies outside its reach sphere
// (ARMS_REFUSAL_OUT_OF_REACH, as the robot's wire says), and recording what
// it was told. Not a simulation of the robot: docs/telemanipulation.md has
// the real one.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/clock/steady_clock.h"
#include "common/mapping/depth_image.h"
#include "common/mapping/depth_stream.h"
#include "robot_side/server/robot_server.h"

namespace hemm::test {

namespace fake_twoarm_hw = hemm::wire;
namespace fake_twoarm_hn = hemm::net;

inline fake_twoarm_hn::Key fake_twoarm_key() {
  fake_twoarm_hn::Key k{};
  std::uint32_t x = 0x9e3779b9u;  // xorshift: the operator refuses a counting pattern as weak
  for (size_t i = 0; i < k.size(); ++i) {
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    k[i] = static_cast<uint8_t>(x >> 24);
  }
  return k;
}

inline Eigen::Quaterniond fake_twoarm_down() {
  return Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
}

// The fake robot's arms: G starts here (A), reach: within kFakeReach of the shoulder.
inline const std::array<Eigen::Vector3d, 2> kFakeG0{Eigen::Vector3d(0.60, -0.25, 0.95), Eigen::Vector3d(0.60, 0.25, 0.95)};
inline const std::array<Eigen::Vector3d, 2> kFakeShoulder{Eigen::Vector3d(0.2, -0.25, 1.25), Eigen::Vector3d(0.2, 0.25, 1.25)};
inline constexpr double kFakeReach = 0.75;
inline constexpr double kFakeLagS = 0.04;  // first-order lag of G behind its target

struct FakeTwoArmRobot {
  asio::io_context io;
  std::unique_ptr<hemm::robot::RobotServer> server;
  asio::steady_timer timer{io};
  std::thread thread;
  std::mutex mu;
  // Under mu:
  std::array<Eigen::Vector3d, 2> G = kFakeG0, target = kFakeG0;
  bool following = false;
  std::uint64_t commands = 0, pressed = 0, refusals = 0, last_refused_seq = 0, last_seq = 0;
  std::uint32_t last_refused_index = 0;
  std::vector<std::pair<std::int64_t, bool>> deadman_log;  // (receive time, dead-man)
  std::int64_t last_ns = 0;
  // A head depth camera (off unless set before the first frame): a flat
  // top at surface_z over surface_box (A = W), seen from above at 15 Hz.
  std::atomic<bool> depth_camera{false};
  double surface_z = 0.93;
  Eigen::AlignedBox2d surface_box{Eigen::Vector2d(0.3, -0.5), Eigen::Vector2d(0.95, 0.5)};
  std::uint32_t cloud_id = 0;
  std::uint64_t depth_chunks_sent = 0;
  double min_opening_0 = 1.0;               // gripper 0's smallest commanded opening
  double max_dx_0 = 0.0;                    // arm 0's G: largest x from its start

  FakeTwoArmRobot() {
    hemm::robot::RobotServerOptions o;
    o.session_port = 0;
    o.stream_port = 0;
    o.psk = fake_twoarm_key();
    server = std::make_unique<hemm::robot::RobotServer>(io, o);
    server->streams().on(fake_twoarm_hw::StreamMessage::kArmsCommand,
                         [this](const fake_twoarm_hn::DatagramHeader& h, int64_t recv, const fake_twoarm_hw::StreamMessage& m) {
                           on_command(h.seq, recv, m.arms_command());
                         });
    std::string err;
    EXPECT_TRUE(server->start(&err)) << err;
    stream();
    thread = std::thread([this] { io.run(); });
  }
  ~FakeTwoArmRobot() {
    asio::post(io, [this] {
      timer.cancel();
      server->stop("test over");
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    io.stop();
    thread.join();
  }
  // Refused whole when a target is out of reach (nothing changes); applied
  // with the dead-man pressed; released: the arms hold where they are.
  void on_command(std::uint64_t seq, std::int64_t recv, const fake_twoarm_hw::ArmsCommand& c) {
    std::lock_guard<std::mutex> lk(mu);
    ++commands;
    last_seq = seq;
    deadman_log.emplace_back(recv, c.deadman());
    std::array<Eigen::Vector3d, 2> t = target;
    for (const fake_twoarm_hw::ArmTarget& a : c.arm()) {
      Eigen::Isometry3d T;
      if (a.index() > 1 || hemm::mapping::pose3_from_wire(a.t_a_g(), &T)) return;
      if ((T.translation() - kFakeShoulder[a.index()]).norm() > kFakeReach) {
        ++refusals;
        last_refused_seq = seq;
        last_refused_index = a.index();
        return;
      }
      t[a.index()] = T.translation();
    }
    if (c.deadman())
      for (const fake_twoarm_hw::GripperTarget& g : c.gripper())
        if (g.index() == 0) min_opening_0 = std::min(min_opening_0, g.opening_m());
    if (c.deadman()) {
      ++pressed;
      target = t;
      following = true;
    } else {
      if (following) target = G;  // hold where G is
      following = false;
    }
  }
  void stream() {
    timer.expires_after(std::chrono::milliseconds(4));
    timer.async_wait([this](const asio::error_code& ec) {
      if (ec) return;
      fake_twoarm_hw::StreamMessage m;
      {
        std::lock_guard<std::mutex> lk(mu);
        const std::int64_t now = hemm::steady_now_ns();
        const double dt = last_ns == 0 ? 0.0 : (now - last_ns) * 1e-9;
        last_ns = now;
        const double a = 1.0 - std::exp(-dt / kFakeLagS);
        for (int k = 0; k < 2; ++k)
          if (following) G[k] += a * (target[k] - G[k]);
        max_dx_0 = std::max(max_dx_0, G[0].x() - kFakeG0[0].x());
        auto* s = m.mutable_arms_state();
        s->set_stamp_ns(now);
        s->set_mode(fake_twoarm_hw::MODE_MANIPULATION);
        s->set_frame_epoch(7);
        s->set_last_command_seq(last_seq);
        s->set_refusals(refusals);
        if (refusals > 0) {
          s->set_last_refusal(fake_twoarm_hw::ARMS_REFUSAL_OUT_OF_REACH);
          s->set_last_refused_seq(last_refused_seq);
          s->set_last_refused_index(last_refused_index);
        }
        for (std::uint32_t k = 0; k < 2; ++k) {
          fake_twoarm_hw::ArmState* as = s->add_arm();
          as->set_index(k);
          for (int j = 0; j < 7; ++j) {
            as->add_q(0.1 * j);
            as->add_qd(0.0);
            as->add_tau(0.0);
          }
          Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
          T.linear() = fake_twoarm_down().toRotationMatrix();
          T.translation() = G[k];
          hemm::mapping::pose3_to_wire(T, as->mutable_t_a_g());
          hemm::mapping::pose3_to_wire(T, as->mutable_t_a_g_target());
          as->mutable_v_a();
          as->mutable_omega_a();
          as->mutable_force_a();
          as->mutable_torque_a();
          fake_twoarm_hw::GripperState* g = s->add_gripper();
          g->set_index(k);
          g->set_opening_m(0.08);
        }
      }
      if (server->link_up()) {
        server->streams().send(m);
        if (depth_camera && tick % 16 == 0) send_depth();
      }
      ++tick;
      stream();
    });
  }
  std::uint32_t tick = 0;
  // One frame of the flat top through a pinhole camera 0.6 m above it
  // (the truth pose is the pose: a fake robot has no odometry error).
  void send_depth() {
    hemm::mapping::DepthImage img;
    img.stamp_ns = hemm::steady_now_ns();
    img.cloud_id = ++cloud_id;
    img.K = hemm::mapping::intrinsics_from_hfov(80, 60, 1.2, 0.1, 3.0);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.62, 0.0, surface_z + 0.6);
    T.linear() = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();  // z down
    img.T_W_S = img.T_W_S_truth = T;
    const std::size_t n = static_cast<std::size_t>(img.K.width * img.K.height);
    img.depth.assign(n, 0.0f);
    img.status.assign(n, hemm::mapping::DepthStatus::kNoReturn);
    for (int v = 0; v < img.K.height; ++v)
      for (int u = 0; u < img.K.width; ++u) {
        const Eigen::Vector3d d_W = T.linear() * hemm::mapping::pixel_ray_z1(img.K, u, v);
        if (d_W.z() >= -1e-9) continue;
        const double t = (surface_z - T.translation().z()) / d_W.z();  // depth: the ray's z in S is 1
        const Eigen::Vector3d p = T.translation() + t * d_W;
        if (!surface_box.contains(p.head<2>()) || t * d_W.norm() > img.K.range_max) continue;
        const std::size_t i = static_cast<std::size_t>(v * img.K.width + u);
        img.depth[i] = static_cast<float>(t);
        img.status[i] = hemm::mapping::DepthStatus::kValid;
      }
    std::vector<fake_twoarm_hw::DepthChunk> chunks;
    if (hemm::mapping::encode_depth_chunks(img, "head_depth", {}, &chunks)) return;
    for (const fake_twoarm_hw::DepthChunk& c : chunks) {
      fake_twoarm_hw::StreamMessage m;
      *m.mutable_depth_chunk() = c;
      if (server->streams().send(m)) ++depth_chunks_sent;
    }
  }
  std::uint64_t commands_in() {
    std::lock_guard<std::mutex> lk(mu);
    return commands;
  }
  Eigen::Vector3d g(int k) {
    std::lock_guard<std::mutex> lk(mu);
    return G[static_cast<std::size_t>(k)];
  }
};

}  // namespace hemm::test
