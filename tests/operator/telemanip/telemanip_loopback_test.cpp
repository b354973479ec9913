// End to end over real loopback sockets, libfranka mock-server style: a FAKE
// two-arm robot (the real RobotServer on its own network thread, answering
// with ArmsState at 250 Hz where each G follows the commanded target with a
// first-order lag while the dead-man is pressed, and refusing targets out of
// its reach sphere whole, as the robot's wire says) and the operator's real
// pieces: OperatorClient, TelemanipLink, and TelemanipTask in the real servo
// loop, with a TEST DOUBLE two-hand device whose hands a test thread moves.
// Shows: the remote G follows the hand through the mapping; releasing the
// dead-man stops commands being pressed and the arm holds; indexing on the
// next press; a refusal reaches the operator's report; the servo tick
// allocates nothing with both hands rendering (the bench voxmap under both
// grippers). Timing assertions have wide margins (shared 2-core VMs).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_stream.h"
#include "common/mesh/primitives.h"
#include "operator/client/operator_client.h"
#include "operator/servo/servo_loop.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_report.h"
#include "operator/telemanip/telemanip_task.h"
#include "robot_side/server/robot_server.h"
#include "tests/operator/client/loopback_client.h"
#include "tests/operator/telemanip/fake_twoarm_robot.h"
#include "tests/operator/servo/alloc_counter.h"

namespace tele = hemm::op::telemanip;
namespace hw = hemm::wire;
namespace hn = hemm::net;
namespace hd = hemm::device;

namespace {

// A TEST DOUBLE: two hands with joystick handles (dead-man), at poses a test
// thread sets (atomics), that render force and torque; write() keeps the
// wrenches (no allocation).
class LoopTestHands final : public hd::HapticDevice {
 public:
  LoopTestHands() {
    limits_ = hd::rigid_hand_limits(2);
  }
  void read(hd::DeviceSample& out) noexcept override {
    out.end_effectors = 2;
    for (int k = 0; k < 2; ++k) {
      hd::EndEffectorSample& e = out.ee[static_cast<std::size_t>(k)];
      e.position_H = base_[static_cast<std::size_t>(k)] + Eigen::Vector3d(dx_[k].load(), 0.0, 0.0);
      e.orientation_H = Eigen::Quaterniond::Identity();
      e.handle.has_deadman = true;
      e.handle.deadman = deadman_.load();
      e.enabled = true;
    }
  }
  void write(const hd::DeviceCommand& c) noexcept override {
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d& f = c.ee[static_cast<std::size_t>(k)].force_H;
      const double n = f.norm();
      if (n > peak_[k].load()) peak_[k].store(n);
    }
  }
  const hd::DeviceLimits& limits() const noexcept override { return limits_; }
  std::string_view name() const noexcept override { return "loop-test-hands"; }

  std::array<std::atomic<double>, 2> dx_{};
  std::atomic<bool> deadman_{true};
  std::array<std::atomic<double>, 2> peak_{};

 private:
  hd::DeviceLimits limits_;
  std::array<Eigen::Vector3d, 2> base_{Eigen::Vector3d(0.3, -0.2, 0.3), Eigen::Vector3d(0.3, 0.2, 0.3)};
};

// Counts the servo thread's allocations around the real task's ticks.
class CountingTask final : public hemm::servo::ServoTask {
 public:
  explicit CountingTask(tele::TelemanipTask& t) : t_(t) {}
  void on_servo_start() noexcept override { hemm::test::count_allocations_on_this_thread(true); }
  void on_servo_stop() noexcept override { hemm::test::count_allocations_on_this_thread(false); }
  void tick(const hd::DeviceSample& in, const hemm::servo::ModelSnapshot& m,
            hemm::servo::TickOutput& out) noexcept override {
    t_.tick(in, m, out);
  }

 private:
  tele::TelemanipTask& t_;
};

// A bench whose top is 5 mm above both grippers' finger tips at the start
// (G at z 0.95, tips 2.5 cm below): both hands render contact throughout.
hemm::vps::Voxmap loop_test_bench() {
  hemm::mesh::TriangleMesh m;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.6, 0.0, 0.93 - 0.05);
  hemm::mesh::append_mesh(&m, hemm::mesh::make_box({0.3, 0.5, 0.05}, 6), T);
  hemm::vps::VoxmapParams vp;
  vp.voxel_size = 0.01;
  vp.layers_in = vp.layers_out = 4;
  hemm::vps::Voxmap vm;
  auto e = hemm::vps::build_voxmap(m, vp, &vm, nullptr);
  EXPECT_FALSE(e.has_value());
  return vm;
}

void loop_test_ramp(std::atomic<double>& x, double to, double seconds) {
  const double from = x.load();
  const int n = static_cast<int>(seconds / 0.005);
  for (int i = 1; i <= n; ++i) {
    x.store(from + (to - from) * i / n);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

}  // namespace

TEST(TelemanipLoopback, RemoteFollowsTheHandDeadManStopsItRefusalsAreReportedNoAllocation) {
  hemm::test::FakeTwoArmRobot robot;
  asio::io_context io;
  hemm::op::OperatorClient client(io, hemm::test::loopback_client_options("telemanip-test", robot.server->session_port(),
                                                                         hemm::test::fake_twoarm_key()));
  tele::TelemanipTaskParams tp;
  for (auto& m : tp.mapping) m.R_A_D = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const hd::DeviceLimits lim = hd::rigid_hand_limits(2);
  tp.limits = {lim.ee[0], lim.ee[1]};
  tele::TelemanipTask task(tp);
  const hemm::vps::Voxmap bench = loop_test_bench();
  task.set_voxmap_override(&bench, 1);
  CountingTask counting(task);
  LoopTestHands hands;
  hemm::servo::ModelChannel snapshots;
  hemm::servo::ServoConfig sc;
  sc.realtime = false;
  sc.lock_memory = false;
  hemm::servo::ServoLoop loop(hands, counting, snapshots, sc);
  tele::TelemanipLink link(io, task.setpoints(), task.remote(),
                           [&client](const hw::StreamMessage& m) { return client.streams().send(m); },
                           &hemm::steady_now_ns, tele::TelemanipLinkParams{}, [&client] { return client.link_up(); });
  link.attach(client.streams());
  std::string err;
  ASSERT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  link.start();
  loop.start();
  std::thread net([&] { io.run(); });
  // Connect; the mapping takes the remote G from the first state.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (robot.commands_in() == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const std::uint64_t allocs_before = hemm::test::counted_allocations();

  // 1. The right hand 10 cm forward (D +x = A -x): the remote right G follows; the left stays.
  loop_test_ramp(hands.dx_[0], 0.10, 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  const Eigen::Vector3d g1 = robot.g(0);
  std::printf("after 10 cm forward: remote G (%.4f, %.4f, %.4f)\n", g1.x(), g1.y(), g1.z());
  EXPECT_LT((g1 - (hemm::test::kFakeG0[0] + Eigen::Vector3d(-0.10, 0, 0))).norm(), 0.005);
  EXPECT_LT((robot.g(1) - hemm::test::kFakeG0[1]).norm(), 0.002);

  // 2. Dead-man released, the hand back 10 cm: no command pressed after the
  // release reached the robot (50 ms in flight at most), the arm holds.
  hands.deadman_.store(false);
  const std::int64_t released_ns = hemm::steady_now_ns();
  loop_test_ramp(hands.dx_[0], 0.0, 0.5);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const Eigen::Vector3d g2 = robot.g(0);
  EXPECT_LT((g2 - g1).norm(), 0.002);
  std::size_t after_release = 0, pressed_after = 0;
  {
    std::lock_guard<std::mutex> lk(robot.mu);
    for (const auto& [t, dm] : robot.deadman_log) {
      if (t < released_ns + 50'000'000) continue;
      ++after_release;
      if (dm) ++pressed_after;
    }
  }
  EXPECT_GT(after_release, 40u);  // >= 100 Hz over the 0.75 s
  EXPECT_EQ(pressed_after, 0u);

  // 3. Pressed again, 5 cm forward: the arm goes on from where it held (indexing), 15 cm in all.
  hands.deadman_.store(true);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  loop_test_ramp(hands.dx_[0], 0.05, 0.5);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  const Eigen::Vector3d g3 = robot.g(0);
  EXPECT_LT((g3 - (g2 + Eigen::Vector3d(-0.05, 0, 0))).norm(), 0.005);

  // 4. Back (A +x) past the fake robot's reach (x > 0.887 m): refused, and the operator hears it.
  loop_test_ramp(hands.dx_[0], -0.45, 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));

  loop.stop();
  const std::uint64_t allocs_after = hemm::test::counted_allocations();
  asio::post(io, [&] {
    link.stop();
    client.stop("test over");
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  io.stop();
  net.join();

  // The servo thread allocated nothing while both hands rendered.
  EXPECT_EQ(allocs_after - allocs_before, 0u);
  EXPECT_GT(task.render_stats(0).contact_ticks, 1000u);
  EXPECT_GT(task.render_stats(1).contact_ticks, 1000u);
  EXPECT_GT(hands.peak_[1].load(), 1.0);  // the left hand felt the bench it rests on

  // The refusal reached the operator's report.
  const hemm::servo::TimingSummary timing = loop.summary();
  const hemm::report::Telemanip r = tele::make_telemanip_report(link.stats(), task, task.latest_remote(), &timing);
  std::uint64_t robot_refusals = 0;
  {
    std::lock_guard<std::mutex> lk(robot.mu);
    robot_refusals = robot.refusals;
  }
  std::printf("commands %llu (pressed %llu), states %llu, refusals seen %llu of the robot's %llu (last %s index %u)\n",
              static_cast<unsigned long long>(r.commands_sent()), static_cast<unsigned long long>(r.deadman_pressed()),
              static_cast<unsigned long long>(r.states_in()), static_cast<unsigned long long>(r.refusals().refused()),
              static_cast<unsigned long long>(robot_refusals), r.refusals().last_reason().c_str(),
              r.refusals().last_index());
  std::printf("servo (beside other builds, not real-time): %llu ticks, compute median %.1f us, p99 %.1f us, max %.1f us, "
              "misses %llu\n",
              static_cast<unsigned long long>(r.timing().ticks()), r.timing().compute_us().median(),
              r.timing().compute_us().p99(), r.timing().compute_us().max(),
              static_cast<unsigned long long>(r.timing().misses()));
  ASSERT_GT(robot_refusals, 0u);
  EXPECT_GT(r.refusals().refused(), 0u);
  EXPECT_LE(r.refusals().refused(), robot_refusals);
  EXPECT_GE(r.refusals().refused() + 10, robot_refusals);  // the last few may still be in flight
  EXPECT_GT(r.refusals().out_of_reach(), 0u);
  EXPECT_EQ(r.refusals().last_reason(), "out_of_reach");
  EXPECT_EQ(r.refusals().last_index(), 0u);
  EXPECT_EQ(r.states_rejected(), 0u);
  EXPECT_GT(r.states_in(), 500u);
  EXPECT_EQ(r.hand(0).presses(), 2u);
  EXPECT_GT(r.timing().ticks(), 3000u);
  // While refused the robot kept the last target it accepted: inside its reach.
  EXPECT_LE((robot.g(0) - hemm::test::kFakeShoulder[0]).norm(), hemm::test::kFakeReach + 1e-9);
}
