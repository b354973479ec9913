// Per-tick cost of the held object (issue 25): the two-hand object (the 2 kg
// box held at both ends, hands moving) and one hand, plus the model thread's
// per-ArmsState work: one grasp-estimate sample, one contact observation. Prints ns per call; nothing
// is asserted (docs/telemanipulation_model.md has the figures).
#include <benchmark/benchmark.h>

#include <cmath>

#include "common/haptics/held_object.h"
#include "common/mapping/contact_correction.h"
#include "common/mapping/grasp_estimate.h"
#include "common/mesh/primitives.h"

namespace {

using namespace hemm;

haptics::HeldObjectModel bench_box() {
  haptics::HeldObjectModel m;
  m.body.mass = 2.0;
  m.body.centre_of_mass = Eigen::Vector3d(0.01, 0.0, 0.0);
  m.body.inertia_com = haptics::solid_box_inertia(2.0, {0.3, 0.2, 0.15});
  m.gains.k_lin = 2000;
  m.gains.b_lin = 40;
  m.gains.k_rot = 20;
  m.gains.b_rot = 0.5;
  return m;
}

Eigen::Isometry3d bench_at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  return T;
}

void BM_HeldObjectTick(benchmark::State& state) {
  const int n_hands = static_cast<int>(state.range(0));
  const haptics::HeldObjectModel m = bench_box();
  haptics::HeldObjectData d;
  std::array<haptics::HeldHandInput, 2> hands;
  hands[0].T_A_G = bench_at({0.35, 0, 1});
  hands[1].T_A_G = bench_at({0.65, 0, 1});
  haptics::grasp(m, &d, 0, hands[0], bench_at({-0.15, 0, 0}));
  if (n_hands == 2) haptics::grasp(m, &d, 1, hands[1], bench_at({0.15, 0, 0}));
  haptics::HeldObjectOutput out;
  std::int64_t i = 0;
  for (auto _ : state) {
    const double t = 1e-3 * static_cast<double>(i++);
    hands[0].T_A_G.translation().z() = 1.0 + 0.05 * std::sin(3.0 * t);
    hands[0].v_A.z() = 0.15 * std::cos(3.0 * t);
    hands[1].T_A_G.translation().x() = 0.65 + 0.01 * std::sin(5.0 * t);
    hands[1].v_A.x() = 0.05 * std::cos(5.0 * t);
    benchmark::DoNotOptimize(haptics::step_held_object(m, &d, hands, nullptr, &out));
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_HeldObjectTick)->Arg(1)->Arg(2);

void BM_GraspEstimateSample(benchmark::State& state) {
  const mapping::GraspEstimateParams p;
  mapping::GraspEstimator e = mapping::make_grasp_estimator(p);
  mapping::GraspSample s;
  s.T_A_G = bench_at({0.5, 0, 1});
  s.force_A = Eigen::Vector3d(0.1, 0.2, -19.6);
  s.torque_A = Eigen::Vector3d(0.0, 0.3, 0.0);
  std::int64_t stamp = 0;
  for (auto _ : state) {
    stamp += 4'000'000;
    s.stamp_ns = stamp;
    s.force_A.z() = -19.6 + 0.01 * static_cast<double>(stamp % 7);
    benchmark::DoNotOptimize(mapping::add_grasp_sample(p, &e, s));
  }
}
BENCHMARK(BM_GraspEstimateSample);

// One contact observation (model thread, per ArmsState) with a fingertip
// pointshell of ~1000 points pressing on a plane: arg 1 the robot touches
// (line of action), 0 the robot is free and the model is searched for its
// deepest point.
void BM_ContactObservation(benchmark::State& state) {
  vps::VoxmapParams vp;
  vp.voxel_size = 0.004;
  vps::Voxmap vm;
  if (vps::build_voxmap(mesh::make_box({0.2, 0.2, 0.03}, 4), vp, &vm, nullptr)) {
    state.SkipWithError("voxmap");
    return;
  }
  mesh::TriangleMesh tip;
  mesh::append_mesh(&tip, mesh::make_icosphere(0.015, 4), bench_at({0, 0, -0.1}));
  vps::PointShellParams pp;
  pp.voxel_size = 0.002;
  vps::PointShell ps;
  if (vps::build_pointshell(tip, pp, Eigen::Vector3d::Zero(), &ps)) {
    state.SkipWithError("pointshell");
    return;
  }
  const mapping::ContactCorrectionParams p;
  mapping::ContactCorrection c = mapping::make_contact_correction(p);
  const mapping::CorrectedVoxmap model{&vm, bench_at({0, 0, -0.035})};  // plane at z = -0.005
  const bool touching = state.range(0) == 1;
  mapping::ContactSample s;
  s.T_A_G = bench_at({0, 0, 0.115});
  s.force_A = Eigen::Vector3d(0, 0, touching ? 8.0 : 0.0);
  std::int64_t stamp = 0;
  for (auto _ : state) {
    stamp += 4'000'000;
    s.stamp_ns = stamp;
    benchmark::DoNotOptimize(mapping::observe_contact(p, model, ps, s, &c));
  }
  state.counters["points"] = static_cast<double>(ps.size());
}
BENCHMARK(BM_ContactObservation)->Arg(1)->Arg(0);

}  // namespace

BENCHMARK_MAIN();
