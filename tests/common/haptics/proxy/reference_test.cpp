#include "common/haptics/proxy/reference_scene.h"

#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include "common/mapping/local_map.h"
#include "tests/common/haptics/proxy/proxy_test_util.h"
#include "tests/common/mapping/scan_synth.h"

namespace hemm::haptics {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using math::Pose2;

TEST(Reference, RaycastAndDistanceClosedForm) {
  ExactScene s;
  add_box(s, {1, -1}, {2, 1});
  s.circles.push_back({{0, 3}, 0.5});
  EXPECT_NEAR(*raycast(s, {0, 0}, {1, 0}, 10), 1.0, 1e-12);
  EXPECT_NEAR(*raycast(s, {0, 0}, {0, 2}, 10), 2.5, 1e-12);  // dir need not be unit
  EXPECT_NEAR(*raycast(s, {0, 0}, {1, 1}, 10), std::sqrt(2.0), 1e-12);  // box corner
  EXPECT_FALSE(raycast(s, {0, 0}, {-1, 0}, 10).has_value());
  EXPECT_FALSE(raycast(s, {0, 0}, {1, 0}, 0.5).has_value());  // beyond max range
  EXPECT_NEAR(distance_to_scene(s, {0, 0}), 1.0, 1e-12);
  EXPECT_NEAR(distance_to_scene(s, {0, 2.2}), 0.3, 1e-12);
}

TEST(Reference, ExactCylinderProxyClosedForm) {
  // Against a solid circle the god-object rests at R + rho along the ray to the device.
  ExactScene s;
  s.circles.push_back({{2, 0}, 0.5});
  ProxyModel m;
  m.damping = 0.0;
  ProxyData d = make_proxy_data(m);
  reference_tick(m, s, d, {0, 0, 0}, 100.0);
  for (int k = 0; k < 3; ++k) reference_tick(m, s, d, {2.0, 0.0, 0.0}, 100.0);  // into the centre
  EXPECT_NEAR((d.proxy_W - Vector2d(2 - 0.5 - m.probe_radius, 0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(d.force_W.x(), -m.stiffness * (0.5 + m.probe_radius) / 100.0, 1e-9);
  // Sliding around it: always exactly outside R + rho.
  for (int k = 0; k < 2000; ++k) {
    const double a = k * 0.002;
    reference_tick(m, s, d, {2 - 0.3 * std::cos(a), 0.3 * std::sin(a), 0}, 10.0);
    ASSERT_GE((d.proxy_W - Vector2d(2, 0)).norm(), 0.5 + m.probe_radius - 1e-9);
  }
}

// Figure 9 of the paper: the user cross-sections a cylinder (and a box) with
// the proxy while the robot stands still. Force from the scan-built local
// model against force from the exact scene along the same device path.
ForceError local_vs_exact(double sigma, double* peak_out) {
  ExactScene world;
  world.circles.push_back({{2.0, 0.0}, 0.3});
  add_box(world, {1.5, 1.0}, {2.5, 1.6});
  test::SynthScanSpec spec;
  spec.sigma = sigma;
  spec.beams = 361;
  spec.angle_step = std::numbers::pi / 360;
  auto ray = [&](const Vector2d& o, const Vector2d& u, double r) { return raycast(world, o, u, r); };
  mapping::MapParams mp;
  mapping::LocalMap lm;
  EXPECT_EQ(mapping::add_scan(mp, lm, test::synth_scan(ray, Pose2{}, Pose2{}, 0, spec)), "");
  const mapping::MapSnapshot map = mapping::build_snapshot(mp, lm);

  ProxyModel m;
  const double scale = 10.0;
  ProxyData local = make_proxy_data(m), truth = make_proxy_data(m);
  std::vector<Vector3d> F_local, F_truth;
  // Cross-sectioning sweeps (constant x, y increasing) at several depths:
  // through the cylinder (front at x = 1.7) and into the box (front at x = 1.5,
  // entered through its lower face y = 1, which the laser also sees).
  for (int pass = 0; pass < 4; ++pass) {
    const double x = 1.72 + 0.04 * pass;
    for (int k = 0; k <= 3000; ++k) {
      const Vector3d dev(x, -0.6 + 2.4 * k / 3000.0, 0.0);
      proxy_tick(m, map, local, dev, scale);
      reference_tick(m, world, truth, dev, scale);
      F_local.push_back(local.force_W);
      F_truth.push_back(truth.force_W);
    }
  }
  const ForceError err = force_error(F_local, F_truth);
  *peak_out = 0.0;
  for (const Vector3d& f : F_truth) *peak_out = std::max(*peak_out, f.norm());
  std::printf("local model (scan sigma %.3f m) vs exact: rms %.4f N, max %.4f N, peak true force %.3f N, %zu ticks\n",
              sigma, err.rms, err.max, *peak_out, err.count);
  EXPECT_FALSE(force_error(F_local, std::vector<Vector3d>(3)).valid);
  return err;
}

TEST(Reference, LocalModelForceMatchesExactSceneForce) {
  // A surface error e in W is a force error k e / scale at the device
  // (300 / 10 = 30 N/m): the noise-free scan leaves only the polyline's chords
  // and silhouette ends; with sigma = 5 mm the RMS error is about k sigma / scale.
  double peak = 0.0;
  const ForceError exact_scan = local_vs_exact(0.0, &peak);
  ASSERT_TRUE(exact_scan.valid);
  EXPECT_GT(peak, 0.5);
  const ForceError noisy = local_vs_exact(0.005, &peak);
  ASSERT_TRUE(noisy.valid);
  EXPECT_LT(exact_scan.rms, 0.05);
  EXPECT_LT(noisy.rms, 2.0 * 30.0 * 0.005);
  EXPECT_LT(noisy.max, 0.5 * 3.3 * 2);
  EXPECT_GT(noisy.rms, exact_scan.rms);  // the comparison sees the noise
}

}  // namespace
}  // namespace hemm::haptics
