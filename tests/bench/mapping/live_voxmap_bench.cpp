// Model only what the scene needs: memory, integration time per depth frame,
// snapshot time and the force error of a sphere tool against the exact plane,
// for the live voxmap over voxel size and region-of-interest size (SIMULATED
// 80 x 60 frames of the table scene, 9 frames from three viewpoints).
#include <benchmark/benchmark.h>

#include <cmath>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/pointshell.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"
#include "tests/common/mapping/depth_scene.h"

namespace hm = hemm::mapping;
namespace vps = hemm::vps;
namespace ht = hemm::test;

namespace {

// ROI: a box centred on the table top, `half` metres to each side in x and y
// and 0.15 m above and below it.
hm::LiveVoxmapParams params(double voxel, double half) {
  hm::LiveVoxmapParams p;
  p.voxel_size = voxel;
  p.downsample_leaf = 0.5 * voxel;
  p.clear_margin = 1.5 * voxel;
  p.normal_radius = 2.5 * voxel;
  p.layers = std::max(3, static_cast<int>(std::ceil(0.02 / voxel)));
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(1.0 - half, -half, ht::kTableTop - 0.15),
                              Eigen::Vector3d(1.0 + half, half, ht::kTableTop + 0.15));
  return p;
}

void BM_LiveVoxmap(benchmark::State& state) {
  const double voxel = static_cast<double>(state.range(0)) * 1e-3;
  const double half = static_cast<double>(state.range(1)) * 1e-2;
  vps::PointShell ps;
  vps::PointShellParams pp;
  pp.voxel_size = 0.003;
  if (vps::build_pointshell(hemm::mesh::make_icosphere(0.05, 4), pp, Eigen::Vector3d::Zero(), &ps)) {
    state.SkipWithError("pointshell");
    return;
  }
  double integrate_s = 0, snapshot_s = 0, err_sum = 0, err_max = 0, mem = 0, vm_mem = 0;
  int frames = 0, snaps = 0, probes = 0;
  for (auto _ : state) {
    hm::LiveVoxmap map(params(voxel, half));
    std::mt19937_64 rng(11);
    const double t0 = hemm::thread_cpu_s();
    if (!ht::observe_table(ht::TableScene{}, 9, rng, &map)) {
      state.SkipWithError("observe");
      return;
    }
    const double t1 = hemm::thread_cpu_s();
    vps::Voxmap vm;
    if (map.snapshot(&vm)) {
      state.SkipWithError("snapshot");
      return;
    }
    const double t2 = hemm::thread_cpu_s();
    integrate_s += t1 - t0;
    snapshot_s += t2 - t1;
    frames += 9;
    ++snaps;
    mem = static_cast<double>(map.memory_bytes());
    vm_mem = static_cast<double>(vm.memory_bytes());
    // Sphere (R 5 cm) pressed 1 cm into the top at points inside the smallest ROI.
    for (const Eigen::Vector2d& xy : {Eigen::Vector2d(1.0, 0.0), Eigen::Vector2d(0.93, 0.08), Eigen::Vector2d(1.06, -0.09)}) {
      vps::PairResult r;
      const Eigen::Isometry3d T{Eigen::Translation3d(xy.x(), xy.y(), ht::kTableTop + 0.05 - 0.01)};
      vps::evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T, vps::ContactParams{}, nullptr,
                         &r);
      const double ref = ht::cap_force(vps::ContactParams{}.stiffness, 0.05, 0.01);
      const double e = (r.on_shell.force - Eigen::Vector3d(0, 0, ref)).norm() / ref;
      err_sum += e;
      err_max = std::max(err_max, e);
      ++probes;
    }
  }
  state.counters["integrate_cpu_ms_per_frame"] = 1e3 * integrate_s / frames;
  state.counters["snapshot_cpu_ms"] = 1e3 * snapshot_s / snaps;
  state.counters["cells_MB"] = mem / 1e6;
  state.counters["voxmap_MB"] = vm_mem / 1e6;
  state.counters["force_err_mean_pct"] = 100 * err_sum / probes;
  state.counters["force_err_max_pct"] = 100 * err_max;
}

}  // namespace

// voxel (mm) x ROI half-width (cm)
BENCHMARK(BM_LiveVoxmap)
    ->ArgsProduct({{5, 10, 20}, {15, 30, 60}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_MAIN();
