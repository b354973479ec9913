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
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include <linux/capability.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "common/clock/steady_clock.h"
#include "operator/device/simulated_omni.h"
#include "operator/servo/servo_loop.h"
#include "report.pb.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/operator/servo/two_hand_device.h"
#include "tests/csv_fields.h"
#include "tests/temp_dir.h"

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
    // The loop resets what ran and sets the next deadline: after the wake,
    // at most a period on (a wake later than a whole period aside).
    if (*out.renderer != '\0' || out.work != 0) ++not_reset;
    if (out.deadline_ns <= in.t_ns || out.deadline_ns - in.t_ns > 1'000'000) ++odd_deadlines;
    out.renderer = "wall";
    out.work = static_cast<std::int64_t>(ticks);
    if (model.version == 0) return;  // no model yet: no force
    if (model.version < last_version) ++versions_backwards;
    last_version = model.version;
    const auto& wall = static_cast<const WallSnapshot&>(model);
    const Vector3d& p = in.ee[0].position_H;
    const double pen = p.x() - wall.wall_x;
    out.points[0].proxy_position_H = p;
    if (pen > 0.0) {
      out.command.ee[0].force_H = Vector3d(-wall.stiffness * pen, 0, 0);
      out.points[0].proxy_position_H.x() = wall.wall_x;
      out.mode = 1;
    }
    out.points[0].interaction_point_H = out.points[0].proxy_position_H;
  }
  std::uint64_t ticks = 0, last_version = 0, versions_backwards = 0, not_reset = 0, odd_deadlines = 0;
};

std::unique_ptr<const ModelSnapshot> make_wall(std::uint64_t version) {
  auto w = std::make_unique<WallSnapshot>();
  w->version = version;
  w->stamp_ns = hemm::steady_now_ns();
  w->wall_x = 0.02;
  w->stiffness = 500.0;
  return w;
}

TEST(ServoLoop, RunsTwoSecondsAtOneKilohertzWithoutAllocating) {
  const std::string log_path = hemm::test::make_temp_dir() + "/servo_loop_test_log.csv";
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
  // Deadlines are counted from here to the stop: start() (mlockall, the
  // device, the checks) and stop() take tens of ms on a loaded machine that
  // are no deadlines of the loop.
  const auto deadlines_since = [&loop] {
    return std::make_pair(std::chrono::steady_clock::now(),
                          loop.stats().ticks.load() + loop.stats().skipped_periods.load());
  };
  const auto running_from = deadlines_since();
  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  std::printf("realtime: fifo=%d mlock=%d\n", rt.fifo, rt.memory_locked);
  loop.set_link_stats(2'500'000, -42);
  // The model thread: a new snapshot every 5 ms for 2 s.
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    models.publish(make_wall(++published));
  }
  const auto running_to = deadlines_since();
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
  const double running_deadlines =
      static_cast<double>(
          std::chrono::duration_cast<std::chrono::nanoseconds>(running_to.first - running_from.first).count()) / static_cast<double>(cfg.period_ns);
  EXPECT_NEAR(static_cast<double>(running_to.second - running_from.second), running_deadlines,
              0.05 * running_deadlines + 10);
  EXPECT_LE(static_cast<double>(s.ticks + s.skipped_periods), deadlines + 1);
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

  // What ran is reset each tick and named in the worst ticks; the deadline
  // handed to the task is the next one.
  EXPECT_EQ(task.not_reset, 0u);
  EXPECT_LE(task.odd_deadlines, s.misses);
  ASSERT_EQ(s.worst.size(), 10u);
  for (const WorstTick& w : s.worst) {
    EXPECT_STREQ(w.what, "wall");
    EXPECT_EQ(w.work, static_cast<std::int64_t>(w.tick) + 1);  // the task's count after this tick
  }
  EXPECT_GE(s.worst.front().response_ns(), s.worst.back().response_ns());
  EXPECT_FALSE(s.hardware);  // lock-step: no hardware thread
  EXPECT_EQ(s.period_target_us, 1000.0);
  EXPECT_EQ(s.late_wake_threshold_us, 500.0);
  EXPECT_EQ(s.fifo, rt.fifo);

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
  // The loop ran anyway: ~190 ticks in the 200 ms unloaded; without SCHED_FIFO
  // on a loaded 2-core VM as few as 98 were seen, so only a fifth is asked.
  EXPECT_GT(loop.summary().ticks, 40u);
}

TEST(ServoLoop, StartTwiceThrowsAndStopIsIdempotent) {
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  SlowTask task;
  ModelChannel models;
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  ServoLoop loop(omni, task, models, cfg);
  const RealtimeStatus rt = loop.start();
  EXPECT_FALSE(rt.pinned);
  EXPECT_TRUE(loop.running());
  EXPECT_THROW(loop.start(), std::logic_error);
  loop.stop();
  loop.stop();
  EXPECT_FALSE(loop.running());
  cfg.period_ns = 0;
  EXPECT_THROW(ServoLoop(omni, task, models, cfg), std::invalid_argument);
}

// Renders on both end-effectors of the two-hand test double: a spring to each
// centre, a rotational damper on end-effector 0 asking more torque than the
// device's peak, a grip force on end-effector 1, and every 50th tick a NaN
// torque on end-effector 1 (a broken renderer the device must survive).
class TwoHandTask final : public ServoTask {
 public:
  static constexpr double kK = 200.0;        // N/m
  static constexpr double kDamping = 0.6;    // N m s/rad: 0.6 * 2 pi > 3 N m peak
  static constexpr double kGripGain = 100.0;  // N/m
  void on_servo_start() noexcept override { test::count_allocations_on_this_thread(true); }
  void on_servo_stop() noexcept override { test::count_allocations_on_this_thread(false); }
  void tick(const device::DeviceSample& in, const ModelSnapshot&, TickOutput& out) noexcept override {
    if (in.end_effectors != 2) ++wrong_count;
    const device::EndEffectorSample &a = in.ee[0], &b = in.ee[1];
    out.command.ee[0].force_H = -kK * (a.position_H - test::TwoHandDevice::c0());
    out.command.ee[0].torque_H = -kDamping * a.angular_velocity_H;
    out.command.ee[1].force_H = -kK * (b.position_H - test::TwoHandDevice::c1());
    out.command.ee[1].grip_force = kGripGain * b.handle.grip_position;
    if (n % 50 == 49) {
      out.command.ee[1].torque_H.y() = std::numeric_limits<double>::quiet_NaN();
      ++nan_ticks;
    }
    out.points[0].proxy_position_H = test::TwoHandDevice::c0();
    out.points[1].proxy_position_H = test::TwoHandDevice::c1();
    out.mode = 3;
    ++n;
  }
  std::uint64_t n = 0, nan_ticks = 0, wrong_count = 0;
};

TEST(ServoLoop, TwoEndEffectorsBothWrenchesReachTheDeviceAndTheLog) {
  using test::TwoHandDevice;
  const std::string log_path = hemm::test::make_temp_dir() + "/servo_loop_two_hands.csv";
  TwoHandDevice dev(20000);
  TwoHandTask task;
  ModelChannel models;
  auto logger = make_servo_logger(8192, 2);
  ASSERT_FALSE(logger.start(log_path));
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  ServoLoop loop(dev, task, models, cfg, &logger);
  const std::uint64_t allocs_before = test::counted_allocations();
  const std::uint64_t frees_before = test::counted_frees();
  loop.start();
  const auto t0 = std::chrono::steady_clock::now();
  while (loop.summary().ticks < 700 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10))
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  loop.stop();
  logger.stop();
  const std::uint64_t ticks = loop.summary().ticks;
  ASSERT_GE(ticks, 700u);
  ASSERT_LE(ticks, 20000u);

  EXPECT_EQ(test::counted_allocations() - allocs_before, 0u);
  EXPECT_EQ(test::counted_frees() - frees_before, 0u);
  EXPECT_EQ(task.wrong_count, 0u);
  ASSERT_EQ(dev.writes(), ticks);
  // Each NaN command zeroed end-effector 1's wrench and was counted.
  EXPECT_EQ(dev.nonfinite(), task.nan_ticks);
  EXPECT_GE(task.nan_ticks, 14u);

  // What the device applied, against the closed-form state of each tick.
  const double w = TwoHandDevice::kW;
  for (std::uint64_t i = 0; i < ticks; ++i) {
    const double t = static_cast<double>(i) * 0.001;
    const device::DeviceCommand& c = dev.applied(i);
    // End-effector 0: the spring force of the circle's radius, the damper's
    // torque cut to the 3 N m peak.
    const Vector3d f0 = -TwoHandTask::kK * TwoHandDevice::kRadius * Vector3d(std::cos(w * t), std::sin(w * t), 0);
    ASSERT_LT((c.ee[0].force_H - f0).norm(), 1e-9) << i;
    ASSERT_NEAR(c.ee[0].torque_H.z(), -3.0, 1e-12) << i;
    const bool disabled = i >= TwoHandDevice::kDisabledFrom && i < TwoHandDevice::kDisabledTo;
    const bool nan_tick = i % 50 == 49;
    if (disabled || nan_tick) {
      ASSERT_EQ(c.ee[1].force_H, Vector3d::Zero()) << i;
      ASSERT_EQ(c.ee[1].torque_H, Vector3d::Zero()) << i;
      ASSERT_EQ(c.ee[1].grip_force, 0.0) << i;
    } else {
      const double fz = -TwoHandTask::kK * TwoHandDevice::kBob * std::sin(w * t);
      ASSERT_NEAR(c.ee[1].force_H.z(), fz, 1e-9) << i;
      ASSERT_NEAR(c.ee[1].grip_force, TwoHandTask::kGripGain * 0.01 * (1.0 + std::sin(w * t)), 1e-9) << i;
    }
  }

  // The log: both end-effectors, every tick, under their names.
  EXPECT_EQ(logger.dropped(), 0u);
  std::ifstream f(log_path);
  std::string line;
  std::getline(f, line);
  ASSERT_EQ(line, servo_log_header(2));
  const auto h = hemm::test::csv_fields(line);
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < h.size(); ++i) col[h[i]] = i;
  std::uint64_t rows = 0;
  while (std::getline(f, line)) {
    const auto v = hemm::test::csv_fields(line);
    ASSERT_EQ(v.size(), h.size());
    auto num = [&](const char* name) { return std::stod(v.at(col.at(name))); };
    const auto i = static_cast<std::uint64_t>(num("tick"));
    ASSERT_EQ(i, rows);
    ++rows;
    const device::DeviceSample want = dev.expected(i);
    const device::EndEffectorSample &a = want.ee[0], &b = want.ee[1];
    // Shortest round-trip text: the logged numbers are the sampled doubles.
    EXPECT_EQ(num("dev_x"), a.position_H.x());
    EXPECT_EQ(num("dev_vy"), a.velocity_H.y());
    EXPECT_EQ(num("dev_qz"), a.orientation_H.z());
    EXPECT_EQ(num("dev_wz"), w);
    EXPECT_EQ(num("joy_x"), a.handle.joystick.x());
    EXPECT_EQ(num("inputs"), device::kHasDeadman | device::kHasJoystick);
    EXPECT_EQ(num("buttons"), a.handle.buttons);
    EXPECT_EQ(num("proxy_x"), TwoHandDevice::c0().x());
    EXPECT_EQ(num("ee1_dev_z"), b.position_H.z());
    EXPECT_EQ(num("ee1_dev_vz"), b.velocity_H.z());
    EXPECT_EQ(num("ee1_grip"), b.handle.grip_position);
    EXPECT_EQ(num("ee1_inputs"), device::kHasGrip | device::kHasClutch);
    EXPECT_EQ(num("ee1_enabled"), b.enabled ? 1 : 0);
    EXPECT_EQ(num("ee1_proxy_x"), TwoHandDevice::c1().x());
    EXPECT_EQ(num("mode"), 3);
    // The log shows what the task commanded; the device applied less.
    EXPECT_NEAR(num("tz"), -TwoHandTask::kDamping * w, 1e-12);
    EXPECT_NEAR(num("fx"), -TwoHandTask::kK * (a.position_H.x() - TwoHandDevice::c0().x()), 1e-12);
    EXPECT_NEAR(num("ee1_fz"), -TwoHandTask::kK * (b.position_H.z() - TwoHandDevice::c1().z()), 1e-12);
    EXPECT_NEAR(num("ee1_grip_force"), TwoHandTask::kGripGain * b.handle.grip_position, 1e-12);
    EXPECT_EQ(std::isnan(num("ee1_ty")), i % 50 == 49);
  }
  EXPECT_EQ(rows, ticks);
  std::remove(log_path.c_str());
}

TEST(ServoLoop, RejectsALogForAnotherEndEffectorCountAndBadDeviceLimits) {
  test::TwoHandDevice two(1);
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  SlowTask task;
  ModelChannel models;
  ServoConfig cfg;
  auto one_log = make_servo_logger(8, 1);
  auto two_log = make_servo_logger(8, 2);
  EXPECT_THROW(ServoLoop(two, task, models, cfg, &one_log), std::invalid_argument);
  EXPECT_THROW(ServoLoop(omni, task, models, cfg, &two_log), std::invalid_argument);
  EXPECT_NO_THROW(ServoLoop(two, task, models, cfg, &two_log));
  EXPECT_NO_THROW(ServoLoop(omni, task, models, cfg, &one_log));

  // A device whose limits make no sense is refused before any tick.
  class BadDevice final : public device::HapticDevice {
   public:
    BadDevice() { lim.end_effectors = device::kMaxEndEffectors + 1; }
    void read(device::DeviceSample&) noexcept override {}
    void write(const device::DeviceCommand&) noexcept override {}
    const device::DeviceLimits& limits() const noexcept override { return lim; }
    std::string_view name() const noexcept override { return "bad"; }
    device::DeviceLimits lim = device::phantom_omni_limits();
  } bad;
  EXPECT_THROW(ServoLoop(bad, task, models, cfg), std::invalid_argument);
  bad.lim = device::phantom_omni_limits();
  bad.lim.ee[0].peak_force = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ServoLoop(bad, task, models, cfg), std::invalid_argument);
}

}  // namespace
}  // namespace hemm::servo

namespace hemm::servo {
namespace {

int allowed_cpu(bool first) {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return -1;
  int found = -1;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &set)) {
      found = c;
      if (first) break;
    }
  return found;
}

// The servo thread pinned to a CPU this process may use: pinned, and the
// summary says which; a CPU it may not use is refused by the constructor
// with the reason, before anything (the device, memory locking) is touched.
TEST(ServoLoop, PinningToAnAllowedCpuIsAcceptedAndABadOneRefused) {
  auto script = std::make_shared<device::HoldScript>(Vector3d::Zero());
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  WallTask task;
  ModelChannel models;
  ServoConfig cfg;
  cfg.realtime = false;
  cfg.lock_memory = false;
  cfg.simulated_hardware = device::HardwareMode::kThreaded;
  for (int bad : {-2, 100000, CPU_SETSIZE}) {
    cfg.cpu = bad;
    try {
      ServoLoop loop(omni, task, models, cfg);
      ADD_FAILURE() << "cpu " << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("cpu: CPU " + std::to_string(bad)), std::string::npos) << e.what();
    }
    EXPECT_EQ(omni.simulated_hardware(), nullptr);  // the device was not started
  }
  const int cpu = allowed_cpu(false);
  ASSERT_GE(cpu, 0);
  cfg.cpu = cpu;
  ServoLoop loop(omni, task, models, cfg);
  const RealtimeStatus rt = loop.start();
  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  loop.stop();
  EXPECT_TRUE(rt.pinned);
  EXPECT_EQ(rt.cpu, cpu);
  const TimingSummary s = loop.summary();
  EXPECT_EQ(s.cpu, cpu);
  EXPECT_GT(s.ticks, 20u);
}

// The SIMULATED Omni's hardware on its own thread beside the servo: the servo
// thread still allocates nothing (read/write copy through mailboxes), the
// hardware's own timing is reported beside the servo's, and the hand still
// comes to rest where the closed form puts it against the wall.
TEST(ServoLoop, ThreadedSimulatedHardwareRunsBesideTheServoWithoutAllocating) {
  const double target_x = 0.021;
  auto script = std::make_shared<device::LineScript>(Vector3d::Zero(), Vector3d(target_x, 0, 0), 0.1);
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  WallTask task;
  ModelChannel models;
  models.publish(make_wall(1));
  ServoConfig cfg;
  cfg.simulated_hardware = device::HardwareMode::kThreaded;
  ServoLoop loop(omni, task, models, cfg);
  const std::uint64_t allocs_before = test::counted_allocations();
  const std::uint64_t frees_before = test::counted_frees();
  const RealtimeStatus rt = loop.start();
  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  loop.stop();
  const TimingSummary s = loop.summary();
  std::printf("servo: %s\n", to_string(s).c_str());
  EXPECT_EQ(test::counted_allocations() - allocs_before, 0u);
  EXPECT_EQ(test::counted_frees() - frees_before, 0u);
  ASSERT_TRUE(s.hardware);
  EXPECT_EQ(s.hardware->mode, "threaded");
  EXPECT_EQ(s.hardware->device, "simulated-phantom-omni");
  EXPECT_GT(s.hardware->timing.ticks, 500u);
  EXPECT_GT(s.hardware->commands_new, 500u);
  EXPECT_EQ(s.hardware->sample_age.count, s.ticks);  // one read per tick
  EXPECT_EQ(omni.data().steps, s.hardware->timing.ticks);
  EXPECT_NEAR(s.hardware->timing.period.median_us, 1000.0, 50.0);
  const double kh = omni.model().hand_stiffness, kw = 500.0;
  EXPECT_NEAR(omni.data().position_H.x(), (kh * target_x + kw * 0.02) / (kh + kw), 2e-5);
  // And in the report: the hardware's own ServoTiming beside the servo's.
  report::ServoTiming r;
  fill(&r, s);
  EXPECT_EQ(r.simulated_hardware().mode(), "threaded");
  EXPECT_EQ(r.simulated_hardware().timing().ticks(), s.hardware->timing.ticks);
  EXPECT_GT(r.simulated_hardware().timing().period_us().bin_count_size(), 0);
}

}  // namespace
}  // namespace hemm::servo
