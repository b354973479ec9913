// The SIMULATED Omni's hardware in its two modes (operator/device/
// simulated_hardware.h). Lock-step: read()/write() are the engine's step
// (simulated_omni_step with write()'s command checks, as before the threaded
// mode existed), bit for bit. Threaded: samples carry the time they were
// published, the newest wins, the servo side never waits on a stalled
// hardware thread, and the mechanism still settles where the closed form
// puts it (F / k_hand); stop() hands the counters back and returns to
// lock-step. Wall-clock bounds are wide (a shared, loaded machine).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <thread>

#include "common/clock/steady_clock.h"
#include "operator/device/simulated_omni.h"

namespace hemm::device {
namespace {

using Eigen::Vector3d;
using namespace std::chrono_literals;

// Holds the origin; stall = true makes the thread that calls at() (the
// hardware thread, threaded) wait there until it is cleared.
// The times of its last two calls tell which sample is the newest when the
// thread stalls in the last one: the one published after the call before.
class StallingHand final : public HandScript {
 public:
  HandTarget at(double) const noexcept override {
    prev_call_ns.store(last_call_ns.load());
    last_call_ns.store(steady_now_ns());
    calls.fetch_add(1);
    while (stall.load()) {
      waiting.store(true);
      std::this_thread::sleep_for(200us);
    }
    waiting.store(false);
    return HandTarget{};
  }
  // Stalls the calling thread at its next call; returns once it is there.
  void stall_now() const {
    stall.store(true);
    for (int i = 0; i < 2000 && !waiting.load(); ++i) std::this_thread::sleep_for(1ms);
    ASSERT_TRUE(waiting.load());
  }
  mutable std::atomic<bool> stall{false}, waiting{false};
  mutable std::atomic<long> calls{0};
  mutable std::atomic<std::int64_t> prev_call_ns{0}, last_call_ns{0};
};

HardwareStart threaded() {
  HardwareStart h;
  h.mode = HardwareMode::kThreaded;
  return h;
}

TEST(SimulatedHardware, LockStepIsTheEngineStepTickForTick) {
  const SimulatedOmniModel m;
  auto script = std::make_shared<LineScript>(Vector3d(0, 0, 0), Vector3d(0.03, -0.01, 0.02), 0.05, 0.1);
  SimulatedOmni dev(m, script);
  SimulatedOmniData ref;  // the engine alone, as write() did before it had a threaded mode
  ref.position_H = script->at(0.0).position_H;
  DeviceSample s;
  for (int k = 0; k < 3000; ++k) {
    dev.read(s);
    ASSERT_EQ(s.ee[0].position_H, ref.position_H) << "tick " << k;
    ASSERT_EQ(s.ee[0].velocity_H, ref.velocity_H) << "tick " << k;
    EXPECT_EQ(s.measured_ns, 0);
    // A wall at x = 10 mm with 800 N/m, a grip force now and then, a NaN once.
    DeviceCommand c;
    c.ee[0].force_H = Vector3d(s.ee[0].position_H.x() > 0.01 ? -800.0 * (s.ee[0].position_H.x() - 0.01) : 0.0, 0, 0);
    if (k % 500 == 7) c.ee[0].grip_force = 1.0;
    if (k == 1234) c.ee[0].force_H.y() = std::numeric_limits<double>::quiet_NaN();
    dev.write(c);
    Vector3d f = c.ee[0].force_H;
    if (!f.allFinite()) {
      f.setZero();
      ++ref.nonfinite_commands;
    } else if (c.ee[0].grip_force != 0.0) {
      ++ref.ignored_grip_commands;
    }
    simulated_omni_step(m, ref, script->at(ref.t_s + m.dt_s), f);
  }
  EXPECT_EQ(dev.data().steps, ref.steps);
  EXPECT_EQ(dev.data().position_H, ref.position_H);
  EXPECT_EQ(dev.data().mean_square_force, ref.mean_square_force);
  EXPECT_EQ(dev.data().nonfinite_commands, 1u);
  EXPECT_EQ(dev.data().ignored_grip_commands, 6u);
  EXPECT_EQ(dev.simulated_hardware(), nullptr);  // never started threaded
  // Starting it in lock-step changes nothing.
  dev.start(HardwareStart{}, nullptr);
  EXPECT_EQ(dev.simulated_hardware(), nullptr);
}

TEST(SimulatedHardware, ThreadedSamplesCarryTheirTimeAndTheNewestWins) {
  auto hand = std::make_shared<StallingHand>();
  SimulatedOmni dev(SimulatedOmniModel{}, hand);
  std::vector<std::string> warnings;
  const std::int64_t t0 = steady_now_ns();
  dev.start(threaded(), &warnings);
  ASSERT_NE(dev.simulated_hardware(), nullptr);
  DeviceSample s;
  dev.read(s);
  EXPECT_GE(s.measured_ns, t0);  // start() published the state it began from
  std::this_thread::sleep_for(100ms);  // ~100 hardware steps (fewer on a loaded machine), no read
  hand->stall_now();                   // the hardware thread waits inside a step's at()
  dev.read(s);
  EXPECT_LE(s.measured_ns, steady_now_ns());
  // The newest sample: published after the step before the stalled one
  // called at(), before the stalled step did; every older one was published
  // before that call.
  EXPECT_GT(s.measured_ns, hand->prev_call_ns.load());
  EXPECT_LT(s.measured_ns, hand->last_call_ns.load());
  const std::int64_t first = s.measured_ns;
  hand->stall.store(false);
  std::this_thread::sleep_for(20ms);
  dev.read(s);
  EXPECT_GT(s.measured_ns, first);
  dev.stop();
  const SimulatedHardwareStats& hw = *dev.simulated_hardware();
  EXPECT_GE(hw.timing.ticks.load(), 10u);
  // Nothing was written: every step held the zero force in effect.
  EXPECT_EQ(hw.commands_new.load(), 0u);
  EXPECT_EQ(hw.commands_held.load(), hw.timing.ticks.load());
  EXPECT_EQ(hw.sample_age.count(), 3u);
  EXPECT_EQ(dev.data().steps, hw.timing.ticks.load());
}

TEST(SimulatedHardware, TheServoSideNeverWaitsOnAStalledHardwareThread) {
  auto hand = std::make_shared<StallingHand>();
  SimulatedOmni dev(SimulatedOmniModel{}, hand);
  dev.start(threaded(), nullptr);
  std::this_thread::sleep_for(20ms);
  hand->stall_now();
  DeviceSample s;
  dev.read(s);
  const std::int64_t stamp = s.measured_ns;
  DeviceCommand c;
  c.ee[0].force_H = Vector3d(0.1, 0, 0);
  const std::int64_t t0 = steady_now_ns();
  for (int k = 0; k < 10'000; ++k) {
    dev.read(s);
    dev.write(c);
  }
  const double ms = static_cast<double>(steady_now_ns() - t0) * 1e-6;
  std::printf("10000 read+write pairs with the hardware thread stalled: %.2f ms\n", ms);
  EXPECT_LT(ms, 200.0);                 // ~1 ms unloaded; a wait on the hardware would be seconds
  EXPECT_EQ(s.measured_ns, stamp);      // no new sample came meanwhile
  hand->stall.store(false);
  std::this_thread::sleep_for(20ms);
  dev.read(s);
  EXPECT_GT(s.measured_ns, stamp);
  dev.stop();
  EXPECT_GE(dev.simulated_hardware()->commands_new.load(), 1u);
}

TEST(SimulatedHardware, ThreadedTheHandSettlesWhereTheClosedFormPutsIt) {
  // A constant 0.5 N (below the 0.88 N continuous limit) on the hand's
  // 200 N/m spring: x = F / k = 2.5 mm at rest, whichever thread steps it.
  const SimulatedOmniModel m;
  SimulatedOmni dev(m, std::make_shared<HoldScript>(Vector3d::Zero()));
  dev.start(threaded(), nullptr);
  DeviceCommand c;
  c.ee[0].force_H = Vector3d(0.5, 0, 0);
  DeviceSample s;
  for (int k = 0; k < 1500; ++k) {  // ~1.5 s of 1 kHz writes
    dev.read(s);
    dev.write(c);
    std::this_thread::sleep_for(1ms);
  }
  dev.read(s);
  dev.stop();
  EXPECT_NEAR(s.ee[0].position_H.x(), 0.5 / m.hand_stiffness, 2e-5);
  EXPECT_NEAR(s.ee[0].position_H.y(), 0.0, 1e-12);
  EXPECT_GT(dev.simulated_hardware()->commands_new.load(), 500u);
}

TEST(SimulatedHardware, StopHandsBackTheCountersAndReturnsToLockStep) {
  SimulatedOmni dev(SimulatedOmniModel{}, std::make_shared<HoldScript>(Vector3d::Zero()));
  dev.start(threaded(), nullptr);
  DeviceCommand bad;
  bad.ee[0].force_H.x() = std::numeric_limits<double>::infinity();
  DeviceCommand grip;
  grip.ee[0].grip_force = 2.0;
  for (int k = 0; k < 5; ++k) dev.write(bad);
  for (int k = 0; k < 3; ++k) dev.write(grip);
  dev.stop();
  dev.stop();  // idempotent
  EXPECT_EQ(dev.data().nonfinite_commands, 5u);
  EXPECT_EQ(dev.data().ignored_grip_commands, 3u);
  // Lock-step again: each write is one step.
  const std::uint64_t steps = dev.data().steps;
  dev.write(DeviceCommand{});
  dev.write(DeviceCommand{});
  EXPECT_EQ(dev.data().steps, steps + 2);
  DeviceSample s;
  dev.read(s);
  EXPECT_EQ(s.measured_ns, 0);
  EXPECT_EQ(s.ee[0].position_H, dev.data().position_H);
}

}  // namespace
}  // namespace hemm::device
