// Proxy compute time per servo tick against the number of map segments in
// reach, and map update time (scan -> segments -> window -> snapshot) against
// the number of scan points. All inputs are SIMULATED, generated analytically.
#include <benchmark/benchmark.h>
#include <numbers>

#include <algorithm>
#include <cmath>
#include <random>

#include "common/haptics/proxy/reference_scene.h"
#include "common/haptics/proxy/virtual_proxy.h"
#include "common/mapping/local_map.h"

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using namespace hemm;

// A wall at x = 1 broken into n short segments (a dense noisy scan of it), all
// within reach of a probe that slides along it while pushing in.
mapping::MapSnapshot wall_map(int n, double span) {
  mapping::LocalMap map;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.002);
  Vector2d prev(1.0 + noise(rng), -0.5 * span);
  for (int i = 1; i <= n; ++i) {
    const Vector2d q(1.0 + noise(rng), -0.5 * span + span * i / n);
    mapping::Segment2 s;
    s.a = prev;
    s.b = q;
    s.normal = Vector2d(-1, 0);
    map.segments.push_back(s);
    prev = q;
  }
  mapping::MapParams p;
  p.cell_size = 0.25;
  return mapping::build_snapshot(p, map);
}

void BM_ProxyTick(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  // All n segments lie on 0.4 m of wall: with the device 5 cm behind it and
  // the probe sliding, the query disc covers all of them.
  const mapping::MapSnapshot map = wall_map(n, 0.4);
  haptics::ProxyModel m;
  haptics::ProxyData d = haptics::make_proxy_data(m);
  haptics::proxy_tick(m, map, d, Vector3d(0.8, 0, 0), 10.0);
  std::size_t k = 0;
  std::size_t contacts = 0;
  for (auto _ : state) {
    const double t = static_cast<double>(k++) * 1e-3;
    const Vector3d dev(1.05, 0.15 * std::sin(2.0 * t), 0.0);
    haptics::proxy_tick(m, map, d, dev, 10.0);
    contacts += static_cast<std::size_t>(d.contact_count);
    benchmark::DoNotOptimize(d.force_W);
  }
  std::uint32_t buf[8192];
  state.counters["in_reach"] =
      static_cast<double>(mapping::query_segments(map, Vector2d(1.05, 0.0), 0.05 + 0.4, buf, 8192));
  state.counters["contacts"] = static_cast<double>(contacts) / static_cast<double>(k);
}
BENCHMARK(BM_ProxyTick)->Arg(10)->Arg(100)->Arg(400)->Arg(1000)->Arg(4000)->Unit(benchmark::kMicrosecond);

// Free motion in a cluttered room (the common case): how cheap is "no contact"?
void BM_ProxyTickFreeSpace(benchmark::State& state) {
  haptics::ExactScene scene;
  haptics::add_box(scene, {-3, -3}, {3, 3});
  mapping::LocalMap lm;
  for (const auto& e : scene.segments) {
    mapping::Segment2 s;
    s.a = e.a;
    s.b = e.b;
    lm.segments.push_back(s);
  }
  const mapping::MapSnapshot map = mapping::build_snapshot(mapping::MapParams{}, lm);
  haptics::ProxyModel m;
  haptics::ProxyData d = haptics::make_proxy_data(m);
  std::size_t k = 0;
  for (auto _ : state) {
    const double t = static_cast<double>(k++) * 1e-3;
    haptics::proxy_tick(m, map, d, Vector3d(std::cos(t), std::sin(t), 0), 10.0);
    benchmark::DoNotOptimize(d.force_W);
  }
}
BENCHMARK(BM_ProxyTickFreeSpace)->Unit(benchmark::kMicrosecond);

// A room scan with `points` beams over 360 deg: walls, a box and two posts.
mapping::RangeScan2D room_scan(int points, std::int64_t stamp, double yaw) {
  haptics::ExactScene world;
  haptics::add_box(world, {-4, -3}, {5, 3});
  haptics::add_box(world, {1.5, 0.5}, {2.2, 1.4});
  world.circles.push_back({{2.5, -1.0}, 0.25});
  world.circles.push_back({{-1.5, 1.5}, 0.15});
  mapping::RangeScan2D s;
  s.stamp_ns = stamp;
  s.T_W_R = {0.1, 0.0, yaw};
  s.kind = mapping::SensorKind::kLaser;
  s.angle_step = 2.0 * std::numbers::pi / points;
  s.angle_min = -std::numbers::pi;
  s.range_min = 0.05;
  s.range_max = 10.0;
  std::mt19937 rng(static_cast<std::uint32_t>(points));
  std::normal_distribution<double> noise(0.0, 0.01);
  const math::Pose2 T_W_S = math::compose(s.T_W_R, s.T_R_S);
  for (int i = 0; i < points; ++i) {
    const double a = s.angle_min + i * s.angle_step;
    const auto r = haptics::raycast(world, math::translation(T_W_S),
                                    math::rotate(T_W_S, Vector2d(std::cos(a), std::sin(a))), s.range_max);
    s.ranges.push_back(r ? static_cast<float>(*r + noise(rng)) : 0.0f);
    s.valid.push_back(r ? 1 : 0);
  }
  return s;
}

void map_update(benchmark::State& state, double min_spacing) {
  const int points = static_cast<int>(state.range(0));
  const mapping::RangeScan2D scan = room_scan(points, 0, 0.0);
  mapping::MapParams p;
  p.min_point_spacing = min_spacing;
  p.window_age_s = 1.0;
  mapping::LocalMap map;
  std::int64_t t = 0;
  std::size_t segs = 0, pieces = 0;
  for (auto _ : state) {
    mapping::RangeScan2D s = scan;  // (copy excluded from nothing: it is part of receiving a scan)
    s.stamp_ns = t;
    mapping::add_scan(p, map, s);
    mapping::slide_window(p, map, t, Vector2d(0.1, 0.0));
    const mapping::MapSnapshot snap = mapping::build_snapshot(p, map);
    segs = map.segments.size();
    pieces = snap.segments.size();
    benchmark::DoNotOptimize(snap.items.data());
    t += 100'000'000;  // 10 Hz: the window holds 10 scans
  }
  state.counters["map_segments"] = static_cast<double>(segs);
  state.counters["snapshot_pieces"] = static_cast<double>(pieces);
  state.counters["points"] = points;
}

void BM_MapUpdate(benchmark::State& state) { map_update(state, 0.0); }
void BM_MapUpdateDownsampled5cm(benchmark::State& state) { map_update(state, 0.05); }
BENCHMARK(BM_MapUpdate)->Arg(181)->Arg(1000)->Arg(5000)->Arg(10000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MapUpdateDownsampled5cm)->Arg(181)->Arg(1000)->Arg(5000)->Arg(10000)->Unit(benchmark::kMicrosecond);

// The operator's steady state: a 181-beam laser (180 deg) at 30 Hz, window
// 3 s, robot standing in the room with a new noise draw per scan. Arg 1: ray
// clearing on (the newest scan supersedes what it re-observes), 0: off (every
// scan kept until it ages out). Time per add_scan alone, and the map size.
void BM_AddScan30Hz(benchmark::State& state) {
  const bool clear = state.range(0) != 0;
  std::vector<mapping::RangeScan2D> scans;
  for (int k = 0; k < 16; ++k) {
    mapping::RangeScan2D s = room_scan(360, 0, 0.0);  // 1 cm noise, the same draw each time
    std::mt19937 rng(static_cast<std::uint32_t>(k + 1));
    std::normal_distribution<double> noise(0.0, 0.01);
    mapping::RangeScan2D f = s;  // keep the front 181 beams (-90 .. +90 deg)
    f.angle_min = -0.5 * std::numbers::pi;
    f.angle_step = std::numbers::pi / 180.0;
    f.ranges.assign(s.ranges.begin() + 90, s.ranges.begin() + 271);
    f.valid.assign(s.valid.begin() + 90, s.valid.begin() + 271);
    for (float& r : f.ranges) r += static_cast<float>(noise(rng));  // plus a fresh draw: ~1.4 cm in all
    scans.push_back(f);
  }
  mapping::MapParams p;
  p.clear_reobserved = clear;
  p.window_age_s = 3.0;
  mapping::LocalMap map;
  const std::int64_t period = 33'333'333;
  std::int64_t t = 0;
  std::size_t k = 0;
  // Warm up to the steady state: a full window.
  for (; t < 4'000'000'000; t += period) {
    mapping::RangeScan2D s = scans[k++ % scans.size()];
    s.stamp_ns = t;
    mapping::add_scan(p, map, s);
    mapping::slide_window(p, map, t, Vector2d(0.1, 0.0));
  }
  double segs = 0;
  std::size_t n = 0;
  for (auto _ : state) {
    state.PauseTiming();
    mapping::RangeScan2D s = scans[k++ % scans.size()];
    s.stamp_ns = t;
    state.ResumeTiming();
    mapping::add_scan(p, map, s);
    state.PauseTiming();
    mapping::slide_window(p, map, t, Vector2d(0.1, 0.0));
    segs += static_cast<double>(map.segments.size());
    ++n;
    t += period;
    state.ResumeTiming();
  }
  state.counters["map_segments"] = segs / static_cast<double>(n);
  state.counters["newest_scan_segments"] = static_cast<double>(std::count_if(
      map.segments.begin(), map.segments.end(), [&](const mapping::Segment2& g) { return g.stamp_ns == t - period; }));
}
BENCHMARK(BM_AddScan30Hz)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Radius query alone (what the servo thread does each tick before the sweep).
void BM_MapQuery(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  mapping::LocalMap map;
  mapping::MapParams p;
  mapping::add_scan(p, map, room_scan(points, 0, 0.0));
  const mapping::MapSnapshot snap = mapping::build_snapshot(p, map);
  std::uint32_t out[4096];
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-4, 5), uy(-3, 3);
  std::vector<Vector2d> q(1024);
  for (auto& v : q) v = Vector2d(ux(rng), uy(rng));
  std::size_t k = 0, found = 0;
  for (auto _ : state) {
    found += mapping::query_segments(snap, q[k++ & 1023], 0.2, out, 4096);
    benchmark::DoNotOptimize(out[0]);
  }
  state.counters["found_per_query"] = static_cast<double>(found) / static_cast<double>(k);
  state.counters["snapshot_pieces"] = static_cast<double>(snap.segments.size());
}
BENCHMARK(BM_MapQuery)->Arg(181)->Arg(10000)->Unit(benchmark::kNanosecond);

}  // namespace

BENCHMARK_MAIN();
