// The servo loop on this VM, end to end: a simulated Omni pushed into a
// virtual wall from published snapshots, the setpoint mailbox drained by a
// "network" thread, the 1 kHz log written to CSV, and every allocation on the
// servo thread counted (must be zero). Timing is asserted on the median only,
// with wide margins (shared 2-core VM); p99 and max are printed.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <linux/capability.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "operator/device/simulated_omni.h"
#include "operator/servo/servo_loop.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::servo {
namespace {

using Eigen::Vector3d;

// A half-space wall {x > position}: the model thread's snapshot.
struct WallSnapshot final : ModelSnapshot {
  double wall_x = 0.0;
  double stiffness = 0.0;
};

// Penalty force from the newest wall; counts its own ticks (servo thread only).
class WallTask final : public ServoTask {
 public:
  void on_servo_start() noexcept override { test::count_allocations_on_this_thread(true); }
  void on_servo_stop() noexcept override { test::count_allocations_on_this_thread(false); }
  void tick(const device::DeviceSample& in, const ModelSnapshot& model,
            TickOutput& out) noexcept override {
    ++ticks;
    if (model.version == 0) return;  // no model yet: no force
    if (model.version < last_version) ++versions_backwards;
    last_version = model.version;
    const auto& wall = static_cast<const WallSnapshot&>(model);
    const double pen = in.position_H.x() - wall.wall_x;
    out.proxy_position_H = in.position_H;
    if (pen > 0.0) {
      out.force_H = Vector3d(-wall.stiffness * pen, 0, 0);
      out.proxy_position_H.x() = wall.wall_x;
      out.mode = 1;
    }
    out.interaction_point_H = out.proxy_position_H;
  }
  std::uint64_t ticks = 0, last_version = 0, versions_backwards = 0;
};

std::unique_ptr<const ModelSnapshot> make_wall(std::uint64_t version) {
  auto w = std::make_unique<WallSnapshot>();
  w->version = version;
  w->stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now().time_since_epoch())
                    .count();
  w->wall_x = 0.02;
  w->stiffness = 500.0;
  return w;
}

TEST(ServoLoop, RunsTwoSecondsAtOneKilohertzWithoutAllocating) {
  const std::string log_path = testing::TempDir() + "servo_loop_test_log.csv";
  // The hand pushes 1 mm into the wall at x = 0.02 and holds.
  const double target_x = 0.021;
  auto script = std::make_shared<device::LineScript>(Vector3d::Zero(), Vector3d(target_x, 0, 0), 0.1);
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  WallTask task;
  ModelChannel models;
  models.publish(make_wall(1));
  auto logger = make_servo_logger(8192);
  ASSERT_FALSE(logger.start(log_path));

  ServoConfig cfg;  // 1 kHz, SCHED_FIFO + mlockall if permitted
  ServoLoop loop(omni, task, models, cfg, &logger);
  const std::uint64_t allocs_before = test::counted_allocations();
  const std::uint64_t frees_before = test::counted_frees();

  std::atomic<bool> done{false};
  std::uint64_t takes = 0, setpoint_backwards = 0, last_tick = 0;
  bool any_taken = false;
  std::thread network([&] {  // the setpoint consumer
    ServoSetpoint sp;
    while (!done.load()) {
      if (loop.setpoints().take(sp)) {
        if (any_taken && sp.tick <= last_tick) ++setpoint_backwards;
        any_taken = true;
        last_tick = sp.tick;
        ++takes;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  std::uint64_t published = 1;
  const auto t0 = std::chrono::steady_clock::now();
  const RealtimeStatus rt = loop.start();
  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  std::printf("realtime: fifo=%d mlock=%d\n", rt.fifo, rt.memory_locked);
  loop.set_link_stats(2'500'000, -42);
  // The model thread: a new snapshot every 5 ms for 2 s.
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    models.publish(make_wall(++published));
  }
  loop.stop();
  const double elapsed_ns = static_cast<double>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0)
          .count());
  done.store(true);
  network.join();
  logger.stop();

  const TimingSummary s = loop.summary();
  std::printf("servo: %s\n", to_string(s).c_str());
  std::printf("servo: elapsed %.1f ms, published %llu snapshots, %llu setpoints taken, log written %llu dropped %llu\n",
              elapsed_ns * 1e-6, static_cast<unsigned long long>(published),
              static_cast<unsigned long long>(takes),
              static_cast<unsigned long long>(logger.written()),
              static_cast<unsigned long long>(logger.dropped()));

  // Not one allocation or free on the servo thread (retired snapshots are
  // freed by the model thread).
  EXPECT_EQ(test::counted_allocations() - allocs_before, 0u)
      << (test::malloc_is_hooked() ? "(malloc + operator new counted)" : "(operator new counted)");
  EXPECT_EQ(test::counted_frees() - frees_before, 0u)
      << (test::malloc_is_hooked() ? "(free + operator delete counted)" : "(operator delete counted)");

  // Timing: the median period within 5 % of 1 ms.
  EXPECT_NEAR(s.period.median_us, 1000.0, 50.0);
  // Every deadline is accounted for: ticks run plus deadlines skipped.
  const double deadlines = elapsed_ns / static_cast<double>(cfg.period_ns);
  EXPECT_NEAR(static_cast<double>(s.ticks + s.skipped_periods), deadlines, 0.05 * deadlines + 10);
  EXPECT_GT(static_cast<double>(s.ticks), 0.5 * deadlines);  // mostly real ticks
  EXPECT_LE(s.misses, s.ticks);

  // The force was computed and written at every tick.
  EXPECT_EQ(task.ticks, s.ticks);
  EXPECT_EQ(omni.data().steps, s.ticks);
  EXPECT_EQ(task.versions_backwards, 0u);
  EXPECT_GT(task.last_version, published / 2);  // it saw recent snapshots
  // Closed form: hand spring against the wall spring at rest,
  // x = (k_h x_t + k_w x_w) / (k_h + k_w), after ~2000 simulated ms.
  const double kh = omni.model().hand_stiffness, kw = 500.0;
  EXPECT_NEAR(omni.data().position_H.x(), (kh * target_x + kw * 0.02) / (kh + kw), 2e-6);
  EXPECT_NEAR(omni.data().applied_force_H.x(), -kw * ((kh * target_x + kw * 0.02) / (kh + kw) - 0.02),
              2e-3);

  // The mailbox delivered setpoints in order, newest wins.
  EXPECT_GT(takes, 100u);
  EXPECT_EQ(setpoint_backwards, 0u);

  // The log: a header and one row per tick unless dropped.
  EXPECT_EQ(logger.written() + logger.dropped(), s.ticks);
  std::ifstream f(log_path);
  std::string line, last;
  std::size_t rows = 0;
  std::getline(f, line);
  EXPECT_EQ(line, servo_log_header());
  while (std::getline(f, line)) {
    ++rows;
    last = line;
  }
  EXPECT_EQ(rows, logger.written());
  // Last row: mode 1 (in contact), link fields as set.
  EXPECT_NE(last.find(",1,"), std::string::npos) << last;
  EXPECT_NE(last.find(",2500000,-42"), std::string::npos) << last;
  std::remove(log_path.c_str());
}

// A task that sometimes works longer than a period: overruns are counted and
// the missed deadlines skipped, never run back to back.
class SlowTask final : public ServoTask {
 public:
  void tick(const device::DeviceSample&, const ModelSnapshot&, TickOutput&) noexcept override {
    if (++n % 50 == 0) {
      const auto until = std::chrono::steady_clock::now() + std::chrono::microseconds(2600);
      while (std::chrono::steady_clock::now() < until) {
      }
    }
  }
  std::uint64_t n = 0;
};

TEST(ServoLoop, OverrunsAreCountedAndMissedDeadlinesSkipped) {
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  SlowTask task;
  ModelChannel models;
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  ServoLoop loop(omni, task, models, cfg);
  const auto t0 = std::chrono::steady_clock::now();
  loop.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  loop.stop();
  const double deadlines =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() * 1e3;
  const TimingSummary s = loop.summary();
  std::printf("slow: %s\n", to_string(s).c_str());
  // One slow tick in 50, each 2.6 ms: at least 2 deadlines skipped each time.
  EXPECT_GE(s.overruns, task.n / 50);
  EXPECT_GE(s.skipped_periods, 2 * (task.n / 50));
  EXPECT_GE(s.misses, s.overruns);
  EXPECT_NEAR(static_cast<double>(s.ticks + s.skipped_periods), deadlines, 0.05 * deadlines + 10);
  EXPECT_GE(s.compute.max_us, 2600.0);
}

// The counter must see allocations and frees on the servo thread, or the
// zeros above would prove nothing.
class AllocatingTask final : public ServoTask {
 public:
  void on_servo_start() noexcept override { test::count_allocations_on_this_thread(true); }
  void on_servo_stop() noexcept override { test::count_allocations_on_this_thread(false); }
  void tick(const device::DeviceSample&, const ModelSnapshot&, TickOutput&) noexcept override {
    if (n++ < 10) {
      // Through volatile pointers, so the compiler cannot elide the pairs.
      double_sink = new double(1.0);
      delete double_sink;
      raw_sink = std::malloc(16);
      std::free(raw_sink);
    }
  }
  std::uint64_t n = 0;
  double* volatile double_sink = nullptr;
  void* volatile raw_sink = nullptr;
};

TEST(ServoLoop, AllocationCounterSeesServoThreadAllocationsAndFrees) {
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  AllocatingTask task;
  ModelChannel models;
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  ServoLoop loop(omni, task, models, cfg);
  const std::uint64_t before = test::counted_allocations();
  const std::uint64_t frees_before = test::counted_frees();
  loop.start();
  while (loop.summary().ticks < 20) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  loop.stop();
  // 10 operator new (+ 10 malloc where malloc is hooked), and as many frees.
  EXPECT_EQ(test::counted_allocations() - before, test::malloc_is_hooked() ? 20u : 10u);
  EXPECT_EQ(test::counted_frees() - frees_before, test::malloc_is_hooked() ? 20u : 10u);
}

// Without real-time privileges start() must still run the loop, reporting
// what it could not get. Privileges are dropped from the calling thread only
// (raw capset affects one thread) and the RT priority limit is set to 0, then
// both are restored.
TEST(ServoLoop, FallsBackGracefullyWithoutRealtimePrivileges) {
  __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct saved[2]{}, reduced[2]{};
  ASSERT_EQ(syscall(SYS_capget, &hdr, saved), 0);
  std::memcpy(reduced, saved, sizeof saved);
  for (int cap : {CAP_SYS_NICE, CAP_IPC_LOCK}) reduced[CAP_TO_INDEX(cap)].effective &= ~CAP_TO_MASK(cap);
  rlimit rt_saved{};
  ASSERT_EQ(getrlimit(RLIMIT_RTPRIO, &rt_saved), 0);
  rlimit rt_zero = rt_saved;
  rt_zero.rlim_cur = 0;
  ASSERT_EQ(setrlimit(RLIMIT_RTPRIO, &rt_zero), 0);
  ASSERT_EQ(syscall(SYS_capset, &hdr, reduced), 0);

  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  SlowTask task;
  ModelChannel models;
  ServoConfig cfg;  // asks for SCHED_FIFO and mlockall
  ServoLoop loop(omni, task, models, cfg);
  const RealtimeStatus rt = loop.start();
  hdr = {_LINUX_CAPABILITY_VERSION_3, 0};
  const bool restored = syscall(SYS_capset, &hdr, saved) == 0 && setrlimit(RLIMIT_RTPRIO, &rt_saved) == 0;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  loop.stop();
  ASSERT_TRUE(restored);

  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  EXPECT_FALSE(rt.fifo);
  bool fifo_warned = false, mlock_warned = false;
  for (const auto& w : rt.warnings) {
    fifo_warned |= w.find("SCHED_FIFO refused") != std::string::npos;
    mlock_warned |= w.find("mlockall") != std::string::npos;
  }
  EXPECT_TRUE(fifo_warned);
  // mlockall may still succeed if the memlock limit is unlimited.
  EXPECT_TRUE(rt.memory_locked || mlock_warned);
  EXPECT_GT(loop.summary().ticks, 100u);  // the loop ran anyway
}

TEST(ServoLoop, StartTwiceThrowsAndStopIsIdempotent) {
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  SlowTask task;
  ModelChannel models;
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  cfg.cpu = 100000;  // no such CPU: a warning, not a failure
  ServoLoop loop(omni, task, models, cfg);
  const RealtimeStatus rt = loop.start();
  EXPECT_FALSE(rt.pinned);
  ASSERT_EQ(rt.warnings.size(), 1u);
  EXPECT_NE(rt.warnings[0].find("CPU 100000"), std::string::npos);
  EXPECT_TRUE(loop.running());
  EXPECT_THROW(loop.start(), std::logic_error);
  loop.stop();
  loop.stop();
  EXPECT_FALSE(loop.running());
  cfg.period_ns = 0;
  EXPECT_THROW(ServoLoop(omni, task, models, cfg), std::invalid_argument);
}

}  // namespace
}  // namespace hemm::servo
