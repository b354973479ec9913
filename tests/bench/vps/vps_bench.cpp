// VPS speed: cycle time against pointshell size and voxel size; voxmap build
// time and memory against triangle count. Prints numbers (no assertions).
#include <benchmark/benchmark.h>

#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"

namespace {

using namespace hemm;

Eigen::Isometry3d at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  return T;
}

// Tool sphere (R 40 mm) resting 2 mm deep on a scene sphere (R 100 mm):
// args = {scene voxel um, tool pointshell voxel um}.
void BM_PairCycle(benchmark::State& state) {
  const double sv = state.range(0) * 1e-6, pv = state.range(1) * 1e-6;
  vps::VoxmapParams vp;
  vp.voxel_size = sv;
  vps::Voxmap vm;
  if (vps::build_voxmap(mesh::make_icosphere(0.1, 5), vp, &vm, nullptr)) {
    state.SkipWithError("voxmap");
    return;
  }
  vps::PointShellParams pp;
  pp.voxel_size = pv;
  vps::PointShell ps;
  if (vps::build_pointshell(mesh::make_icosphere(0.04, 5), pp, Eigen::Vector3d::Zero(), &ps)) {
    state.SkipWithError("pointshell");
    return;
  }
  vps::ContactParams cp;
  vps::PairResult r;
  const Eigen::Isometry3d T = at(Eigen::Vector3d(0.01, 0.02, 1.0).normalized() * (0.14 - 0.002));
  for (auto _ : state) {
    vps::evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T, cp, nullptr, &r);
    benchmark::DoNotOptimize(r);
  }
  state.counters["points"] = static_cast<double>(ps.size());
  state.counters["tested"] = r.points_tested;
  state.counters["contacts"] = r.contacts;
  state.counters["voxmap_MB"] = vm.memory_bytes() / 1e6;
}
BENCHMARK(BM_PairCycle)
    ->Args({4000, 4000})
    ->Args({4000, 2000})
    ->Args({4000, 1000})
    ->Args({2000, 2000})
    ->Args({1000, 2000})
    ->Args({1000, 1000})
    ->Unit(benchmark::kMicrosecond);

// Voxmap build against triangles: n x n icospheres (20480 triangles each) at 3 mm.
void BM_VoxmapBuild(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  mesh::TriangleMesh scene;
  const auto ball = mesh::make_icosphere(0.08, 5);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) mesh::append_mesh(&scene, ball, at({i * 0.25, j * 0.25, 0.0}));
  vps::VoxmapParams vp;
  vp.voxel_size = 0.003;
  vps::Voxmap vm;
  for (auto _ : state) {
    if (vps::build_voxmap(scene, vp, &vm, nullptr)) state.SkipWithError("voxmap");
    benchmark::DoNotOptimize(vm.blocks.data());
  }
  state.counters["triangles"] = static_cast<double>(scene.triangles.size());
  state.counters["MB"] = vm.memory_bytes() / 1e6;
  state.counters["blocks"] = static_cast<double>(vm.blocks.size());
}
BENCHMARK(BM_VoxmapBuild)->Arg(1)->Arg(2)->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
