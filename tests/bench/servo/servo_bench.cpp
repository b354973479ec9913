// Servo loop timing on this machine: wake latency (median/p99/max) and
// deadline misses over a 10 s run with and without SCHED_FIFO, the per-tick
// compute time the loop measures itself, and the cost of the pieces of a tick.
// Set HEMM_SERVO_BENCH_SECONDS to change the run length.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <thread>

#include "operator/device/simulated_omni.h"
#include "operator/servo/servo_loop.h"

namespace {

using Eigen::Vector3d;
using namespace hemm;

struct WallSnapshot final : servo::ModelSnapshot {
  double wall_x = 0.02;
  double stiffness = 500.0;
};

class WallTask final : public servo::ServoTask {
 public:
  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
            servo::TickOutput& out) noexcept override {
    if (model.version == 0) return;
    const auto& wall = static_cast<const WallSnapshot&>(model);
    const double pen = in.ee[0].position_H.x() - wall.wall_x;
    if (pen > 0.0) out.command.ee[0].force_H = Vector3d(-wall.stiffness * pen, 0, 0);
  }
};

std::unique_ptr<const servo::ModelSnapshot> make_wall(std::uint64_t v) {
  auto w = std::make_unique<WallSnapshot>();
  w->version = v;
  return w;
}

double run_seconds() {
  const char* e = std::getenv("HEMM_SERVO_BENCH_SECONDS");
  const double s = e != nullptr ? std::atof(e) : 10.0;
  return s > 0.1 ? s : 10.0;
}

void BM_ServoLoopWakeLatency(benchmark::State& state) {
  const bool fifo = state.range(0) != 0;
  servo::TimingSummary s;
  servo::RealtimeStatus rt;
  for (auto _ : state) {
    auto script = std::make_shared<device::LineScript>(Vector3d::Zero(), Vector3d(0.03, 0, 0), 0.05);
    device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
    WallTask task;
    servo::ModelChannel models;
    models.publish(make_wall(1));
    auto logger = servo::make_servo_logger(8192);
    if (logger.start("/dev/null")) state.SkipWithError("cannot open /dev/null");
    servo::ServoConfig cfg;
    cfg.realtime = fifo;
    cfg.lock_memory = fifo;
    servo::ServoLoop loop(omni, task, models, cfg, &logger);
    rt = loop.start();
    const auto t0 = std::chrono::steady_clock::now();
    std::uint64_t v = 1;
    while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() <
           run_seconds()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      models.publish(make_wall(++v));  // model thread at 100 Hz
    }
    loop.stop();
    logger.stop();
    s = loop.summary();
  }
  for (const auto& w : rt.warnings) std::printf("realtime: %s\n", w.c_str());
  std::printf("%s: %s\n", fifo ? "SCHED_FIFO" : "SCHED_OTHER", servo::to_string(s).c_str());
  state.counters["fifo_active"] = rt.fifo;
  state.counters["mlock_active"] = rt.memory_locked;
  state.counters["ticks"] = static_cast<double>(s.ticks);
  state.counters["wake_med_us"] = s.wake_latency.median_us;
  state.counters["wake_p99_us"] = s.wake_latency.p99_us;
  state.counters["wake_max_us"] = s.wake_latency.max_us;
  state.counters["compute_med_us"] = s.compute.median_us;
  state.counters["compute_p99_us"] = s.compute.p99_us;
  state.counters["period_med_us"] = s.period.median_us;
  state.counters["misses"] = static_cast<double>(s.misses);
  state.counters["late_wakes"] = static_cast<double>(s.late_wakes);
  state.counters["overruns"] = static_cast<double>(s.overruns);
  state.counters["skipped"] = static_cast<double>(s.skipped_periods);
}
BENCHMARK(BM_ServoLoopWakeLatency)->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The pieces of one tick, measured alone.
void BM_SimulatedOmniStep(benchmark::State& state) {
  auto script = std::make_shared<device::LineScript>(Vector3d::Zero(), Vector3d(0.03, 0, 0), 0.05);
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, script);
  device::DeviceSample s;
  for (auto _ : state) {
    omni.read(s);
    omni.write(device::force_command(Vector3d(0.1, 0, 0)));
    benchmark::DoNotOptimize(s);
  }
}
BENCHMARK(BM_SimulatedOmniStep);

void BM_SnapshotAcquire(benchmark::State& state) {
  servo::ModelChannel models;
  models.publish(make_wall(1));
  for (auto _ : state) benchmark::DoNotOptimize(models.acquire());
}
BENCHMARK(BM_SnapshotAcquire);

void BM_SnapshotPublishAndAcquire(benchmark::State& state) {
  servo::ModelChannel models;
  std::uint64_t v = 0;
  for (auto _ : state) {
    models.publish(make_wall(++v));  // includes one new + one delete
    benchmark::DoNotOptimize(models.acquire());
  }
}
BENCHMARK(BM_SnapshotPublishAndAcquire);

void BM_SetpointMailboxPutTake(benchmark::State& state) {
  NewestMailbox<servo::ServoSetpoint> m;
  servo::ServoSetpoint sp, out;
  for (auto _ : state) {
    ++sp.tick;
    m.publish(sp);
    benchmark::DoNotOptimize(m.take(out));
  }
}
BENCHMARK(BM_SetpointMailboxPutTake);

void BM_LogRingPushPop(benchmark::State& state) {
  servo::SpscRing<servo::ServoLogRecord> r(1024);
  servo::ServoLogRecord rec, out;
  for (auto _ : state) {
    ++rec.tick;
    r.try_push(rec);
    r.try_pop(out);
    benchmark::DoNotOptimize(out);
  }
}
BENCHMARK(BM_LogRingPushPop);

// Arg: end-effectors in the record (1: the Omni; 2: a bimanual device).
void BM_FormatLogRecord(benchmark::State& state) {
  servo::ServoLogRecord rec;
  rec.end_effectors = static_cast<int>(state.range(0));
  for (auto& e : rec.ee) {
    e.position[0] = 0.0123456789;
    e.force[2] = -0.987654321;
    e.orientation[1] = 0.31415926535;
  }
  char buf[servo::ServoLogger::kLineMax];
  for (auto _ : state) {
    ++rec.tick;
    benchmark::DoNotOptimize(servo::format_servo_log_record(rec, buf, sizeof buf));
  }
}
BENCHMARK(BM_FormatLogRecord)->Arg(1)->Arg(2);

}  // namespace

BENCHMARK_MAIN();
