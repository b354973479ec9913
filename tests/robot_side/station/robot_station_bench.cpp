// What the robot station adds per message on its simulation thread: a
// RobotState to the wire, a laser scan (181 beams) split into datagram-sized
// chunks, and their serialization (the network thread's share before sealing).
#include <benchmark/benchmark.h>
#include <numbers>

#include <cmath>

#include "robot_side/sim/wire_convert.h"

namespace hr = hemm::robot;

namespace {

hr::RangeScanData laser_scan(int beams) {
  hr::RangeScanData s;
  s.stamp_ns = 123456789;
  s.sensor_name = "laser";
  s.angle_min = -std::numbers::pi / 2;
  s.angle_step = std::numbers::pi / (beams - 1);
  s.range_min = 0.05;
  s.range_max = 10.0;
  for (int i = 0; i < beams; ++i) {
    s.ranges.push_back(1.0f + 0.01f * static_cast<float>(i));
    s.valid.push_back(i % 50 != 0);
  }
  return s;
}

void BM_StateToWire(benchmark::State& state) {
  hr::RobotStateSim st;
  st.stamp_ns = 1;
  std::string buf;
  for (auto _ : state) {
    hemm::wire::StreamMessage m;
    hr::to_wire(st, m.mutable_robot_state());
    m.SerializeToString(&buf);
    benchmark::DoNotOptimize(buf.data());
  }
  state.counters["bytes"] = static_cast<double>(buf.size());
}
BENCHMARK(BM_StateToWire);

void BM_ScanToWireChunks(benchmark::State& state) {
  const hr::RangeScanData s = laser_scan(static_cast<int>(state.range(0)));
  size_t chunks = 0, bytes = 0;
  std::string buf;
  for (auto _ : state) {
    chunks = bytes = 0;
    for (auto& c : hr::to_wire_chunks(s)) {
      hemm::wire::StreamMessage m;
      *m.mutable_range_scan() = std::move(c);
      m.SerializeToString(&buf);
      bytes += buf.size();
      ++chunks;
    }
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["chunks"] = static_cast<double>(chunks);
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_ScanToWireChunks)->Arg(16)->Arg(181)->Arg(721);

}  // namespace

BENCHMARK_MAIN();
