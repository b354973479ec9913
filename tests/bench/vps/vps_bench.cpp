// VPS speed with its error beside it: one pair against pointshell and voxel
// size, the three-pair cycle (full and time-critical at several budgets)
// against exact closed forms, voxmap build time and memory against triangle
// count. Prints numbers (no assertions); `hemm-vps report` is the full table.
#include <benchmark/benchmark.h>

#include <cmath>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"

namespace {

using namespace hemm;

constexpr double kK = 1e7;

Eigen::Isometry3d at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  return T;
}

// Tool sphere (R 40 mm) resting 2 mm deep on a scene sphere (R 100 mm):
// args = {scene voxel um, tool pointshell voxel um}. Counter err: relative
// force error against the closed form.
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
  cp.stiffness = kK;
  vps::PairResult r;
  const double D = 0.14 - 0.002;
  const Eigen::Isometry3d T = at(Eigen::Vector3d(0.01, 0.02, 1.0).normalized() * D);
  for (auto _ : state) {
    vps::evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T, cp, nullptr, &r);
    benchmark::DoNotOptimize(r);
  }
  const double ref = vps::sphere_sphere_force(kK, 0.04, 0.1, D);
  state.counters["err_pct"] = 100 * std::abs(r.on_shell.force.norm() - ref) / ref;
  state.counters["points"] = static_cast<double>(ps.size());
  state.counters["tested"] = r.points_tested;
  state.counters["contacts"] = r.contacts;
  state.counters["voxmap_MB"] = vm.memory_bytes() / 1e6;
}
BENCHMARK(BM_PairCycle)
    ->Args({4000, 4000})
    ->Args({4000, 2000})
    ->Args({2000, 2000})
    ->Args({1000, 2000})
    ->Args({1000, 1000})
    ->Unit(benchmark::kMicrosecond);

// The three-pair cycle: two tool spheres (R 40 and 30 mm, 2.5 mm pointshells)
// on a scene sphere (R 100 mm, 3 mm voxels), 2 and 1.5 mm deep, 7 mm apart
// (the tool-tool pair is evaluated and culled). arg = work budget (0: the
// full cycle). Counters: err_pct (worse
// of the two scene pairs against the closed forms), levels, work.
void BM_BimanualCycle(benchmark::State& state) {
  static vps::Voxmap scene, left_vm;
  static vps::PointShell right, left;
  if (scene.top.empty()) {
    vps::VoxmapParams vp;
    vp.voxel_size = 0.003;
    vps::PointShellParams pp;
    pp.voxel_size = 0.0025;
    vps::VoxmapParams lp;
    lp.voxel_size = 0.0025;
    if (vps::build_voxmap(mesh::make_icosphere(0.1, 6), vp, &scene, nullptr) ||
        vps::build_pointshell(mesh::make_icosphere(0.04, 5), pp, Eigen::Vector3d::Zero(), &right) ||
        vps::build_pointshell(mesh::make_icosphere(0.03, 5), pp, Eigen::Vector3d::Zero(), &left) ||
        vps::build_voxmap(mesh::make_icosphere(0.03, 5), lp, &left_vm, nullptr)) {
      state.SkipWithError("build");
      return;
    }
  }
  vps::BimanualModel model;
  model.scene = &scene;
  model.right = {nullptr, &right};
  model.left = {&left_vm, &left};
  model.params.stiffness = kK;
  const double Dr = 0.14 - 0.002, Dl = 0.13 - 0.0015;
  const Eigen::Vector3d ur = Eigen::Vector3d(0.3, 0.0, 1.0).normalized(), ul = Eigen::Vector3d(-0.3, 0.0, 1.0).normalized();
  const Eigen::Isometry3d T_R = at(Dr * ur), T_L = at(Dl * ul);
  vps::BimanualState st;
  vps::init_bimanual_state(model, &st);
  vps::BimanualData d;
  const std::int64_t budget = state.range(0) > 0 ? state.range(0) : vps::kUnlimitedWork;
  for (auto _ : state) {
    if (budget == vps::kUnlimitedWork) {
      vps::evaluate_bimanual(model, Eigen::Isometry3d::Identity(), T_R, T_L, &st, &d);
    } else {
      vps::evaluate_bimanual_budgeted(model, Eigen::Isometry3d::Identity(), T_R, T_L, budget, &st, &d);
    }
    benchmark::DoNotOptimize(d);
  }
  const double ref_r = vps::sphere_sphere_force(kK, 0.04, 0.1, Dr), ref_l = vps::sphere_sphere_force(kK, 0.03, 0.1, Dl);
  state.counters["err_pct"] = 100 * std::max(std::abs(d.right_scene.on_shell.force.norm() - ref_r) / ref_r,
                                             std::abs(d.left_scene.on_shell.force.norm() - ref_l) / ref_l);
  state.counters["levels"] = d.levels_completed;
  state.counters["work"] = static_cast<double>(d.work);
}
BENCHMARK(BM_BimanualCycle)->Arg(0)->Arg(250)->Arg(500)->Arg(1000)->Arg(2000)->Arg(4000)->Unit(benchmark::kMicrosecond);

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
