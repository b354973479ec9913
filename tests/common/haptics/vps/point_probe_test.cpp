// The 3-DoF point probe against voxmaps of exact meshes: resting on a box's
// top face the proxy sits at the face + rho and the force is exactly the
// spring's k (penetration along the normal) / scale; it slides along a tilted
// face (force along the exact normal); a device point jumping through a thin
// slab does not tunnel; the tick stays within its work bound and allocates
// nothing.
#include "common/haptics/vps/point_probe.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"

namespace vps = hemm::vps;

namespace {

// A box with its top face at z = 0 (half extents h), voxel s.
vps::Voxmap box_voxmap(const Eigen::Vector3d& h, double s, const Eigen::Isometry3d& T = Eigen::Isometry3d::Identity()) {
  hemm::mesh::TriangleMesh m = hemm::mesh::make_box(h, 4);
  for (auto& v : m.vertices) v = T * (v - Eigen::Vector3d(0, 0, h.z()));
  vps::VoxmapParams p;
  p.voxel_size = s;
  p.layers_in = 4;
  p.layers_out = 4;
  vps::Voxmap vm;
  EXPECT_FALSE(vps::build_voxmap(m, p, &vm, nullptr));
  return vm;
}

vps::PointProbeParams probe_params() {
  vps::PointProbeParams p;
  p.force.probe_radius = 0.01;
  p.force.force_peak = 100.0;  // no clamping in these checks
  p.force.force_continuous = 100.0;
  p.force.damping = 0.0;
  return p;
}

}  // namespace

TEST(PointProbe, RestsOnTheTopFaceWithTheExactSpringForce) {
  const double s = 0.01, scale = 5.0;
  const vps::Voxmap vm = box_voxmap({0.3, 0.3, 0.1}, s);
  const vps::PointProbeParams p = probe_params();
  vps::PointProbeData d;
  vps::point_probe_reset(d, {0.02, -0.03, 0.1});
  // Press down slowly to 3 cm (W) below the top, hold.
  Eigen::Vector3d goal;
  for (int i = 0; i <= 2000; ++i) {
    const double z = 0.1 - 0.13 * std::min(1.0, i / 1500.0);
    goal = {0.02 + 1e-5 * i, -0.03, z};
    vps::point_probe_tick(p, &vm, d, goal, scale);
    EXPECT_LE(d.work, vps::point_probe_max_work(p, s));
  }
  ASSERT_TRUE(d.contact);
  EXPECT_NEAR(d.proxy_W.z(), p.force.probe_radius, 2e-4);  // top face at z = 0
  EXPECT_NEAR(d.proxy_W.x(), goal.x(), 1e-4);               // no sideways drag on a plane
  EXPECT_NEAR(d.proxy_W.y(), goal.y(), 1e-4);
  const double exact = p.force.stiffness * (p.force.probe_radius - goal.z()) / scale;
  EXPECT_NEAR(d.force_W.z(), exact, 0.01 * exact);
  EXPECT_NEAR(d.force_W.head<2>().norm(), 0.0, 0.01 * exact);
  EXPECT_GT(d.normal_W.z(), 0.999);
  // Lifting off: the proxy follows, no force (never pulls).
  for (int i = 0; i < 200; ++i) vps::point_probe_tick(p, &vm, d, {0.04, -0.03, 0.2}, scale);
  EXPECT_FALSE(d.contact);
  EXPECT_EQ(d.force_W.norm(), 0.0);
  EXPECT_NEAR((d.proxy_W - Eigen::Vector3d(0.04, -0.03, 0.2)).norm(), 0.0, 1e-9);
}

TEST(PointProbe, SlidesOnATiltedFaceWithTheForceAlongItsNormal) {
  const double s = 0.01, scale = 4.0, tilt = 0.4;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const vps::Voxmap vm = box_voxmap({0.4, 0.4, 0.15}, s, T);
  const Eigen::Vector3d n = T.linear() * Eigen::Vector3d::UnitZ();
  const vps::PointProbeParams p = probe_params();
  vps::PointProbeData d;
  vps::point_probe_reset(d, Eigen::Vector3d(-0.1, 0, 0) + 0.1 * n);
  double max_dev = 0.0;
  for (int i = 0; i <= 3000; ++i) {
    // 2 cm into the face along -n, sweeping 0.2 m along the face.
    const double depth = 0.02 * std::min(1.0, i / 500.0);
    const Eigen::Vector3d along = T.linear() * Eigen::Vector3d(-0.1 + 0.2 * i / 3000.0, 0, 0);
    const Eigen::Vector3d goal = along + (p.force.probe_radius - depth) * n;
    vps::point_probe_tick(p, &vm, d, goal, scale);
    if (i > 600) {
      ASSERT_TRUE(d.contact) << i;
      max_dev = std::max(max_dev, std::abs(d.proxy_W.dot(n) - p.force.probe_radius));
      const double exact = p.force.stiffness * depth / scale;
      EXPECT_NEAR(d.force_W.dot(n), exact, 0.02 * exact) << i;
      EXPECT_LT((d.force_W - d.force_W.dot(n) * n).norm(), 0.02 * exact) << i;
    }
  }
  EXPECT_LT(max_dev, 5e-4);
}

TEST(PointProbe, AJumpThroughAThinSlabDoesNotTunnel) {
  const double s = 0.005;
  const vps::Voxmap vm = box_voxmap({0.2, 0.2, 0.01}, s);  // 2 cm slab, top at 0
  vps::PointProbeParams p = probe_params();
  p.force.probe_radius = 0.005;
  vps::PointProbeData d;
  vps::point_probe_reset(d, {0, 0, 0.05});
  // The device point lands 5 cm under the slab in one tick (max_step 2 cm:
  // followed over a few ticks).
  for (int i = 0; i < 20; ++i) vps::point_probe_tick(p, &vm, d, {0, 0, -0.07}, 1.0);
  EXPECT_TRUE(d.contact);
  EXPECT_NEAR(d.proxy_W.z(), p.force.probe_radius, 3e-4);
  EXPECT_GT(d.force_W.z(), 0.0);
}

TEST(PointProbe, BadInputKeepsTheProxyAndNoModelMeansNoForce) {
  const vps::Voxmap vm = box_voxmap({0.3, 0.3, 0.1}, 0.01);
  const vps::PointProbeParams p = probe_params();
  vps::PointProbeData d;
  vps::point_probe_reset(d, {0, 0, 0.01});
  vps::point_probe_tick(p, &vm, d, {0, 0, -0.01}, 2.0);
  const Eigen::Vector3d kept = d.proxy_W;
  vps::point_probe_tick(p, &vm, d, {NAN, 0, 0}, 2.0);
  EXPECT_EQ(d.rejected_inputs, 1u);
  EXPECT_EQ(d.force_W.norm(), 0.0);
  EXPECT_EQ(d.proxy_W, kept);
  vps::point_probe_tick(p, nullptr, d, {0, 0, -0.5}, 2.0);
  EXPECT_EQ(d.force_W.norm(), 0.0);
  EXPECT_FALSE(d.contact);
  EXPECT_TRUE(vps::validate(p).empty()) << vps::validate(p);
  vps::PointProbeParams bad = p;
  bad.max_step = 0.0;
  EXPECT_FALSE(vps::validate(bad).empty());
}

TEST(PointProbe, TickAllocatesNothing) {
  const vps::Voxmap vm = box_voxmap({0.3, 0.3, 0.1}, 0.01);
  const vps::PointProbeParams p = probe_params();
  vps::PointProbeData d;
  vps::point_probe_reset(d, {0, 0, 0.05});
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int i = 0; i < 500; ++i) vps::point_probe_tick(p, &vm, d, {0.0001 * i, 0, 0.05 - 0.0002 * i}, 3.0);
  const std::uint64_t after = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_TRUE(d.contact);
}
