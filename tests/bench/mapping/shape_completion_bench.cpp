// Shape completion against the raw segments: time of one completion (thread
// CPU, on the model thread in the station), memory of what it replaces
// against the primitives and their outline, and the error of the unseen back
// of each round object against the exact circle, with and without completion
// (SIMULATED room, 0.5 deg laser with 1 cm noise, 30 scans from a creeping
// robot; round objects of radius 0.10-0.25 m).
#include <benchmark/benchmark.h>

#include <time.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "common/mapping/shape_completion.h"
#include "common/math/geometry2.h"
#include "tests/common/mapping/scan_synth.h"

namespace hm = hemm::mapping;
namespace ht = hemm::test;
using Eigen::Vector2d;

namespace {

double cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// A 6 x 6 m room, `round` round objects ahead of the robot at varied radii and
// two boxes; the robot at the west side looking east.
ht::Shapes2D room(int round) {
  ht::Shapes2D w;
  const Vector2d c[4] = {{-1, -3}, {5, -3}, {5, 3}, {-1, 3}};
  for (int k = 0; k < 4; ++k) w.segs.push_back({c[k], c[(k + 1) % 4]});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < round; ++i) {
    // Spread over a fan ahead in two rows (the far row partly hidden by the near one).
    const double ang = -0.9 + 1.8 * (i + 0.5) / round, dist = i % 2 == 0 ? 1.5 : 2.8;
    w.circles.push_back({Vector2d(dist * std::cos(ang), dist * std::sin(ang)), 0.10 + 0.15 * u(rng)});
  }
  for (const Vector2d& b : {Vector2d(4.0, -2.0), Vector2d(4.0, 2.0)}) {
    const Vector2d v[4] = {b + Vector2d(-0.2, -0.2), b + Vector2d(0.2, -0.2), b + Vector2d(0.2, 0.2),
                           b + Vector2d(-0.2, 0.2)};
    for (int k = 0; k < 4; ++k) w.segs.push_back({v[k], v[(k + 1) % 4]});
  }
  return w;
}

void BM_ShapeCompletion(benchmark::State& state) {
  const int round = static_cast<int>(state.range(0));
  const ht::Shapes2D world = room(round);
  hm::MapParams mp;
  hm::LocalMap map;
  ht::SynthScanSpec spec;
  spec.beams = 720;
  spec.angle_min = -std::numbers::pi;
  spec.angle_step = std::numbers::pi / 360;
  spec.sigma = 0.01;
  spec.no_return_valid = true;
  for (int k = 0; k < 30; ++k) {
    spec.seed = 3 + k;
    const std::string e = hm::add_scan(mp, map, ht::synth_scan(world.rayfn(), hemm::math::Pose2{0.005 * k, 0, 0},
                                                               hemm::math::Pose2{}, k * 33'333'333LL, spec));
    if (!e.empty()) {
      state.SkipWithError(e.c_str());
      return;
    }
  }
  hm::ShapeParams sp;
  hm::ShapeModel m;
  double cpu = 0;
  int runs = 0;
  for (auto _ : state) {
    const double t0 = cpu_s();
    hm::complete_shapes(sp, mp, map, m);
    cpu += cpu_s() - t0;
    ++runs;
    benchmark::DoNotOptimize(m.segments.data());
  }
  // The unseen back of each round object: the distance from points of its
  // true far half to the nearest surface the proxy would meet, with the raw
  // map (segments and shadow edges) and with completion.
  auto nearest = [](const std::vector<hm::Segment2>& segs, const Vector2d& q) {
    double d = 1e300;
    for (const hm::Segment2& s : segs) d = std::min(d, hemm::math::distance_to_segment(s.a, s.b, q));
    return d;
  };
  // Only objects the laser saw (some raw segment on the outline): an object
  // never seen has no back to complete.
  double raw_sum = 0, fit_sum = 0, raw_max = 0, fit_max = 0;
  int n = 0, seen = 0;
  for (const auto& [c, r] : world.circles) {
    bool on = false;
    for (const hm::Segment2& sg : map.segments)
      on = on || (!sg.shadow && std::abs((0.5 * (sg.a + sg.b) - c).norm() - r) < 0.02);
    if (!on) continue;
    ++seen;
    const Vector2d away = (c - Vector2d(0.07, 0)).normalized();
    for (int k = -6; k <= 6; ++k) {
      const Vector2d q = c + r * (Eigen::Rotation2Dd(0.2 * k) * away);
      const double dr = nearest(map.segments, q), df = nearest(m.segments, q);
      raw_sum += dr * dr;
      fit_sum += df * df;
      raw_max = std::max(raw_max, dr);
      fit_max = std::max(fit_max, df);
      ++n;
    }
  }
  state.counters["objects"] = round;
  state.counters["seen"] = seen;
  state.counters["circles"] = static_cast<double>(m.circles.size());
  state.counters["lines"] = static_cast<double>(m.lines.size());
  state.counters["bridges"] = static_cast<double>(m.bridges);
  state.counters["fit_cpu_ms"] = 1e3 * cpu / std::max(1, runs);
  state.counters["raw_segments"] = static_cast<double>(map.segments.size());
  state.counters["raw_KB"] = static_cast<double>(map.segments.size() * sizeof(hm::Segment2)) / 1024.0;
  state.counters["model_segments"] = static_cast<double>(m.segments.size());
  state.counters["model_KB"] = static_cast<double>(m.segments.size() * sizeof(hm::Segment2)) / 1024.0;
  state.counters["replaced_KB"] = static_cast<double>(m.raw_replaced * sizeof(hm::Segment2)) / 1024.0;
  state.counters["circle_params_B"] = static_cast<double>(m.circles.size() * 3 * sizeof(double));
  state.counters["outline_KB"] =
      static_cast<double>(m.circles.size() * static_cast<std::size_t>(sp.circle_pieces) * sizeof(hm::Segment2)) / 1024.0;
  state.counters["back_rms_raw_mm"] = 1e3 * std::sqrt(raw_sum / std::max(1, n));
  state.counters["back_max_raw_mm"] = 1e3 * raw_max;
  state.counters["back_rms_fit_mm"] = 1e3 * std::sqrt(fit_sum / std::max(1, n));
  state.counters["back_max_fit_mm"] = 1e3 * fit_max;
}
BENCHMARK(BM_ShapeCompletion)->Arg(2)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
