#include "common/haptics/proxy/passivity.h"

#include <cstdio>
#include <deque>
#include <numbers>

#include <gtest/gtest.h>

#include "common/haptics/proxy/virtual_proxy.h"
#include "tests/common/haptics/proxy/proxy_test_util.h"

namespace hemm::haptics {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

TEST(Passivity, ClosedFormSpringAndDamper) {
  // An ideal spring loaded and unloaded along the same path: net 0 (trapezoid
  // forces, exact); a damper: sum of b v^2 dt > 0; a negative damper: < 0.
  const double k = 100.0, dt = 1e-3;
  std::vector<Vector3d> F, x, v;
  for (int i = 0; i <= 200; ++i) {
    const double xi = 0.01 * std::sin(std::numbers::pi * i / 200.0);
    x.push_back({xi, 0, 0});
  }
  // Spring with the force evaluated at the midpoint of each step (exact work).
  for (std::size_t i = 0; i + 1 < x.size(); ++i) F.push_back(-k * 0.5 * (x[i] + x[i + 1]));
  F.push_back(Vector3d::Zero());
  PassivityReport r = passivity_observer(F, x, 1e-12);
  EXPECT_NEAR(r.energy_final, 0.0, 1e-12);
  EXPECT_TRUE(r.valid);
  EXPECT_GE(r.energy_min, -1e-12);
  // Damper from velocities.
  F.clear();
  for (int i = 0; i < 100; ++i) {
    v.push_back({0.1, -0.05, 0.0});
    F.push_back(-2.0 * v.back());
  }
  r = passivity_observer_velocity(F, v, dt, 0.0);
  EXPECT_NEAR(r.energy_final, 2.0 * (0.01 + 0.0025) * dt * 100, 1e-12);
  EXPECT_TRUE(r.passive);
  for (auto& f : F) f = -f;  // negative damping generates energy
  r = passivity_observer_velocity(F, v, dt, 1e-6);
  EXPECT_FALSE(r.passive);
  EXPECT_NEAR(r.generated, 2.0 * 0.0125 * dt * 100, 1e-12);
  EXPECT_EQ(r.episodes, 1u);
  // Hostile input.
  x.pop_back();
  EXPECT_FALSE(passivity_observer(F, x, 0.0).valid);
  F[3].x() = std::nan("");
  EXPECT_FALSE(passivity_observer_velocity(F, v, dt, 0.0).valid);
}

struct HandRun {
  std::vector<Vector3d> F, x;
};

// SIMULATED hand pushing the stylus into a wall and pulling back, five times.
// delay > 0 renders the force from a stale device position: a classic active
// (energy generating) wall, the control case for the observer.
HandRun run_wall(const ProxyModel& m, int delay) {
  ExactScene scene;
  scene.segments.push_back({{1, -1}, {1, 1}});
  const auto map = test::snapshot_of(scene, {0, 0});
  ProxyData d = make_proxy_data(m);
  const double scale = 10.0;
  test::SimHand hand;
  hand.x = Vector2d(0.09, 0.0);
  std::deque<Vector3d> stale;
  HandRun run;
  for (int k = 0; k < 5000; ++k) {
    const double t = k * 1e-3;
    const Vector2d target(0.097 + 0.006 * std::sin(2 * std::numbers::pi * t), 0.002 * std::cos(5 * t));
    stale.push_back(Vector3d(scale * hand.x.x(), scale * hand.x.y(), 0));
    const Vector3d dev = stale.front();
    if (static_cast<int>(stale.size()) > delay) stale.pop_front();
    proxy_tick(m, map, d, dev, scale);
    run.F.push_back(d.force_W);
    run.x.push_back(Vector3d(hand.x.x(), hand.x.y(), 0));
    hand.step(target, d.force_W.head<2>(), m.period);
  }
  return run;
}

TEST(Passivity, ProxyWallWithSimulatedHandGeneratesNoEnergy) {
  const ProxyModel m;  // k = 300 N/m, B = 0.3 N s/m > k T / 2
  const HandRun run = run_wall(m, 0);
  const PassivityReport r = passivity_observer(run.F, run.x, 1e-7);
  std::printf("wall, k=%.0f B=%.2f: %zu episodes, energy in %.4g J, min %.3g J, worst episode %.3g J\n",
              m.stiffness, m.damping, r.episodes, r.energy_final, r.energy_min, r.worst_episode_energy);
  EXPECT_GE(r.episodes, 5u);  // five pushes (a push may bounce once)
  EXPECT_TRUE(r.passive);
  EXPECT_GT(r.energy_final, 0.0);
  // Control: the same wall rendered 20 ms late is active, and the observer says so.
  const HandRun late = run_wall(m, 20);
  const PassivityReport rl = passivity_observer(late.F, late.x, 1e-7);
  std::printf("wall, 20 ms stale: energy %.4g J, generated %.3g J\n", rl.energy_final, rl.generated);
  EXPECT_FALSE(rl.passive);
  EXPECT_GT(rl.generated, 1e-5);
}

TEST(Passivity, UndampedDiscreteSpringLeaksColgateEnergy) {
  // Without virtual damping the sampled spring returns k T / 2 per unit
  // squared velocity more than it took: the reason for B > k T / 2.
  ProxyModel m;
  m.damping = 0.0;
  const HandRun run = run_wall(m, 0);
  const PassivityReport r = passivity_observer(run.F, run.x, 0.0);
  std::printf("wall, undamped: energy %.4g J, worst episode %.3g J\n", r.energy_final, r.worst_episode_energy);
  EXPECT_LT(r.worst_episode_energy, 0.0);
}

}  // namespace
}  // namespace hemm::haptics
