// Voxmap, pointshell, cache and geometry kernels against exact references.
#include <gtest/gtest.h>
#include <numbers>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <random>

#include "common/haptics/vps/cache.h"
#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/geometry.h"
#include "common/mesh/primitives.h"

namespace hemm::vps {
namespace {

TEST(VpsGeometry, ClosestPointMatchesDenseSampling) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const Eigen::Vector3d p = 2 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const double d = std::sqrt(point_triangle_distance_sq(p, a, b, c));
    double best = 1e9;
    const int n = 200;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Eigen::Vector3d q = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
        best = std::min(best, (q - p).norm());
      }
    EXPECT_LE(d, best + 1e-12);
    EXPECT_NEAR(d, best, 0.02);  // grid spacing bound
  }
}

TEST(VpsGeometry, SatAgreesWithClippingAndSeparatesEdgeCases) {
  // Far away and clearly crossing.
  EXPECT_FALSE(triangle_box_overlap({0, 0, 0}, 0.5, {2, 2, 2}, {3, 2, 2}, {2, 3, 2}));
  EXPECT_TRUE(triangle_box_overlap({0, 0, 0}, 0.5, {-2, -2, 0}, {2, -2, 0}, {0, 2, 0}));
  // A triangle cutting past a box corner diagonally: the box-axis and normal
  // tests pass, only an edge-cross axis separates it.
  EXPECT_FALSE(triangle_box_overlap({0, 0, 0}, 0.5, {0.9, 0.9, -5}, {0.9, 0.9, 5}, {1.5, 0.2, 0}));
  // Random cases against dense point sampling of the triangle (sampling can
  // only find overlaps, so: sampled overlap implies SAT overlap).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    bool sampled = false;
    const int n = 60;
    for (int i = 0; i <= n && !sampled; ++i)
      for (int j = 0; i + j <= n && !sampled; ++j) {
        const Eigen::Vector3d q = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
        sampled = q.cwiseAbs().maxCoeff() <= 0.5;
      }
    if (sampled) { EXPECT_TRUE(triangle_box_overlap({0, 0, 0}, 0.5, a, b, c)); }
    // SAT overlap implies the triangle comes within the box's circumradius.
    if (triangle_box_overlap({0, 0, 0}, 0.5, a, b, c)) {
      EXPECT_LE(std::sqrt(point_triangle_distance_sq({0, 0, 0}, a, b, c)), std::sqrt(3.0) * 0.5 + 1e-12);
    }
  }
}

TEST(Voxmap, SphereSignedDistanceLayersAndSparsity) {
  const double R = 0.1, s = 0.005;
  const auto sphere = mesh::make_icosphere(R, 5);
  VoxmapParams p;
  p.voxel_size = s;
  p.layers_in = 3;
  p.layers_out = 3;
  Voxmap vm;
  VoxmapBuildInfo info;
  ASSERT_FALSE(build_voxmap(sphere, p, &vm, &info));
  EXPECT_TRUE(vm.signed_field);
  EXPECT_EQ(info.components, 2u);  // outside and inside
  EXPECT_GT(info.uniform_inside_blocks, 0u);
  EXPECT_LT(vm.blocks.size(), vm.top.size());  // sparse
  // Polyhedral approximation of the sphere: faces are inside by < sagitta.
  const double sagitta = 0.0005;
  std::size_t checked = 0;
  const Eigen::Vector3i d = vm.dims();
  for (int z = 0; z < d.z(); ++z)
    for (int y = 0; y < d.y(); ++y)
      for (int x = 0; x < d.x(); ++x) {
        const Eigen::Vector3i v(x, y, z);
        const Voxel vs = sample_voxel(vm, v);
        const double exact = voxel_centre(vm, v).norm() - R;
        if (vs.layer == kLayerFarOutside) {
          EXPECT_GT(exact, 3 * s - sagitta);
          continue;
        }
        if (vs.layer == kLayerFarInside) {
          EXPECT_LT(exact, -3 * s + sagitta);
          continue;
        }
        ++checked;
        EXPECT_NEAR(vs.sdf, exact, sagitta + 1e-6) << x << " " << y << " " << z;
        // Layer = Chebyshev voxel distance to the surface band: |sdf| bounds.
        if (vs.layer == 0) { EXPECT_LE(std::abs(exact), std::sqrt(3.0) * s / 2 + sagitta); }
        if (vs.layer > 0) { EXPECT_GT(exact, (vs.layer - 1) * s - sagitta); }
        if (vs.layer < 0) { EXPECT_LT(exact, (vs.layer + 1) * s + sagitta); }
        if (vs.layer != 0) { EXPECT_LE(std::abs(exact), std::sqrt(3.0) * (std::abs(vs.layer) + 0.5) * s + sagitta); }
        // Culling bound never exceeds the true layer.
        EXPECT_LE(clearance_voxels(vm, v), std::max<int>(0, vs.layer));
      }
  EXPECT_GT(checked, 1000u);
  // Trilinear field between centres.
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 300; ++i) {
    Eigen::Vector3d dir(u(rng), u(rng), u(rng));
    dir.normalize();
    const double r = R + 0.8 * s * u(rng);
    EXPECT_NEAR(sdf_trilinear(vm, r * dir), r - R, 0.15 * s);
  }
}

TEST(Voxmap, QueriesAreTotalForNonFiniteAndHugeCoordinates) {
  // NaN, infinities and coordinates far beyond int range must give "outside"
  // without casting them to int (run under UBSan: float-cast-overflow).
  VoxmapParams p;
  p.voxel_size = 0.005;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap(mesh::make_icosphere(0.05, 3), p, &vm, nullptr));
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  const std::vector<Eigen::Vector3d> bad = {
      {nan, 0, 0},        {0, nan, 0},      {0, 0, nan},        {inf, 0, 0},         {-inf, 0, 0},
      {0, 0, inf},        {1e30, 0, 0},     {0, -1e30, 0},      {0, 0, 3e9 * 0.005}, {-1.2e7, 1.2e7, 0},
      {nan, inf, -inf},   {1e300, 1e300, 1e300}};
  for (const Eigen::Vector3d& x : bad) {
    const Eigen::Vector3i v = voxel_of(vm, x);
    EXPECT_FALSE(in_grid(vm, v)) << x.transpose();
    EXPECT_EQ(sample_voxel(vm, v).layer, kLayerFarOutside);
    EXPECT_GT(clearance_voxels(vm, v), vm.layers_out);
    EXPECT_EQ(sdf_trilinear(vm, x), vm.far_outside_sdf()) << x.transpose();
    EXPECT_TRUE(sdf_gradient(vm, x).allFinite());
  }
  // The same through a pair evaluation: a non-finite or absurd pose touches nothing.
  PointShellParams pp;
  pp.voxel_size = 0.005;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.02, 3), pp, Eigen::Vector3d::Zero(), &ps));
  ContactParams cp;
  for (const Eigen::Vector3d& x : bad) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = x;
    PairResult r;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T, cp, nullptr, &r);
    EXPECT_EQ(r.contacts, 0);
    EXPECT_TRUE(r.on_shell.force.isZero());
  }
  // A sphere node with an absurd radius (as a hostile cache could carry) is
  // merely not culled.
  PointShell huge = ps;
  huge.nodes[0].radius = 1e300;
  Eigen::Isometry3d away = Eigen::Isometry3d::Identity();
  away.translation() = Eigen::Vector3d(1.0, 0, 0);
  PairResult r;
  evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), huge, away, cp, nullptr, &r);
  EXPECT_EQ(r.contacts, 0);
  EXPECT_GT(r.nodes_visited, 1);  // the root was not culled, its children were
}

TEST(Voxmap, OpenAndNonManifoldMeshesFallBackToUnsigned) {
  Voxmap vm;
  VoxmapBuildInfo info;
  VoxmapParams p;
  p.voxel_size = 0.01;
  ASSERT_FALSE(build_voxmap(mesh::make_open_sheet(0.2, 10), p, &vm, &info));
  EXPECT_FALSE(vm.signed_field);
  EXPECT_FALSE(info.mesh_report.closed);
  EXPECT_GT(info.mesh_report.boundary_edges, 0u);
  // Every surface voxel is a thin shell; nothing is inside.
  for (const auto& v : info.surface_index) {
    const Voxel vs = sample_voxel(vm, v);
    EXPECT_EQ(vs.layer, 0);
    EXPECT_TRUE(vs.flags & kFlagThin);
    EXPECT_GE(vs.sdf, 0.0f);
  }
  // Non-manifold: a closed box plus a fin sharing one of its edges.
  auto box = mesh::make_box({0.1, 0.1, 0.1}, 1);
  std::uint32_t a = 0, b = 0;
  for (std::uint32_t i = 0; i < box.vertices.size(); ++i) {
    if ((box.vertices[i] - Eigen::Vector3d(0.1, 0.1, 0.1)).norm() < 1e-12) a = i;
    if ((box.vertices[i] - Eigen::Vector3d(0.1, 0.1, -0.1)).norm() < 1e-12) b = i;
  }
  box.vertices.push_back({0.3, 0.3, 0.0});
  box.triangles.push_back({a, b, static_cast<std::uint32_t>(box.vertices.size() - 1)});
  ASSERT_FALSE(build_voxmap(box, p, &vm, &info));
  EXPECT_GT(info.mesh_report.nonmanifold_edges, 0u);
  EXPECT_FALSE(vm.signed_field);
}

TEST(Voxmap, RejectsBadInputAndLeavesOutputAlone) {
  Voxmap vm;
  vm.voxel_size = 123.0;
  VoxmapParams p;
  p.voxel_size = -1;
  EXPECT_TRUE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), p, &vm, nullptr));
  p.voxel_size = 1e-7;  // too many voxels
  EXPECT_TRUE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), p, &vm, nullptr));
  p.voxel_size = 0.01;
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6));
  EXPECT_TRUE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), p, &vm, nullptr));
  p.roi.reset();
  mesh::TriangleMesh nan = mesh::make_box({0.1, 0.1, 0.1});
  nan.vertices[0].x() = std::nan("");
  EXPECT_TRUE(build_voxmap(nan, p, &vm, nullptr));
  EXPECT_TRUE(build_voxmap_from_points({}, p, &vm));
  // Too much voxelization work (40 stacked 30 m sheets at 5 mm): refused up front.
  mesh::TriangleMesh stack;
  for (int i = 0; i < 40; ++i) mesh::append_mesh(&stack, mesh::make_open_sheet(15.0, 1));
  p.voxel_size = 0.005;
  const auto e = build_voxmap(stack, p, &vm, nullptr);
  ASSERT_TRUE(e);
  EXPECT_NE(e->message.find("limit"), std::string::npos);
  EXPECT_EQ(vm.voxel_size, 123.0);
}

TEST(Voxmap, RegionOfInterestKeepsSignsOfCutObjects) {
  // Only the upper half of a sphere is voxelized: the cut must not leak the
  // inside to the outside.
  const double R = 0.1;
  VoxmapParams p;
  p.voxel_size = 0.005;
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0.0), Eigen::Vector3d(1, 1, 1));
  Voxmap full, cut;
  ASSERT_FALSE(build_voxmap(mesh::make_icosphere(R, 4), p, &cut, nullptr));
  p.roi.reset();
  ASSERT_FALSE(build_voxmap(mesh::make_icosphere(R, 4), p, &full, nullptr));
  EXPECT_LT(cut.memory_bytes(), full.memory_bytes());
  EXPECT_LT(sdf_trilinear(cut, {0, 0, 0.05}), -0.019);
  EXPECT_NEAR(sdf_trilinear(cut, {0, 0, 0.095}), -0.005, 0.001);
  EXPECT_GT(sdf_trilinear(cut, {0, 0, 0.11}), 0.0);
}

TEST(Voxmap, PointCloudGivesUnsignedSurface) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 100; ++j) pts.push_back({i * 0.002, j * 0.002, 0.0});
  VoxmapParams p;
  p.voxel_size = 0.005;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap_from_points(pts, p, &vm));
  EXPECT_FALSE(vm.signed_field);
  EXPECT_EQ(sample_voxel(vm, voxel_of(vm, {0.1, 0.1, 0.0})).layer, 0);
  EXPECT_EQ(sample_voxel(vm, voxel_of(vm, {0.1, 0.1, 0.012})).layer, 2);
  EXPECT_NEAR(sample_voxel(vm, voxel_of(vm, {0.1, 0.1, 0.012})).sdf, (voxel_of(vm, {0.1, 0.1, 0.012}).z() + 0.5) * 0.005 + vm.origin.z(), 0.0011);
}

TEST(PointShell, PointsOnSurfaceInwardNormalsAreaAndTree) {
  const double R = 0.05;
  const auto sphere = mesh::make_icosphere(R, 5);
  PointShellParams p;
  p.voxel_size = 0.003;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(sphere, p, Eigen::Vector3d::Zero(), &ps));
  const double area = mesh::mesh_area(sphere);
  EXPECT_NEAR(ps.total_weight, area, 1e-9 * area);
  for (std::size_t i = 0; i < ps.size(); ++i) {
    EXPECT_NEAR(ps.point(i).norm(), R, 0.0005);
    EXPECT_GT(ps.normal(i).dot(-ps.point(i).normalized()), std::cos(3.0 * std::numbers::pi / 180));
    EXPECT_NEAR(ps.normal(i).norm(), 1.0, 1e-6);
  }
  // Each node's sphere holds its points; children split the parent's range;
  // every point is in exactly one leaf of its level's tree.
  std::vector<int> seen(ps.size(), 0);
  for (std::size_t k = 0; k < ps.nodes.size(); ++k) {
    const SphereNode& n = ps.nodes[k];
    for (int i = n.first; i < n.first + n.count; ++i)
      EXPECT_LE((ps.point(static_cast<std::size_t>(i)) - Eigen::Vector3d(n.cx, n.cy, n.cz)).norm(), n.radius);
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i) ++seen[static_cast<std::size_t>(i)];
    } else {
      const SphereNode& l = ps.nodes[static_cast<std::size_t>(n.left)];
      const SphereNode& r = ps.nodes[static_cast<std::size_t>(n.right)];
      EXPECT_EQ(l.first, n.first);
      EXPECT_EQ(r.first, l.first + l.count);
      EXPECT_EQ(l.count + r.count, n.count);
      EXPECT_EQ(ps.parent[static_cast<std::size_t>(n.left)], static_cast<int>(k));
    }
  }
  for (int c : seen) EXPECT_EQ(c, 1);
}

TEST(VpsCache, RoundTripAndCorruptionIsDetected) {
  VoxmapParams vp;
  vp.voxel_size = 0.01;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap(mesh::make_icosphere(0.1, 3), vp, &vm, nullptr));
  PointShellParams pp;
  pp.voxel_size = 0.01;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.1, 3), pp, Eigen::Vector3d(0.001, 0, 0), &ps));
  const auto bytes = serialize_vps(vm, ps);
  Voxmap vm2;
  PointShell ps2;
  ASSERT_FALSE(deserialize_vps(bytes.data(), bytes.size(), &vm2, &ps2));
  EXPECT_EQ(vm2.top, vm.top);
  EXPECT_EQ(vm2.blocks.size(), vm.blocks.size());
  EXPECT_EQ(std::memcmp(vm2.blocks[3].v.data(), vm.blocks[3].v.data(), sizeof(VoxelBlock)), 0);
  EXPECT_EQ(ps2.px, ps.px);
  EXPECT_EQ(ps2.level_weight, ps.level_weight);
  EXPECT_EQ(ps2.reference_point, ps.reference_point);
  EXPECT_EQ(ps2.nodes.size(), ps.nodes.size());
  // Truncated at every 997th length, one flipped byte, bad magic, bad version.
  for (std::size_t n = 0; n < bytes.size(); n += 997) {
    Voxmap v3;
    v3.voxel_size = 7;
    PointShell p3;
    EXPECT_TRUE(deserialize_vps(bytes.data(), n, &v3, &p3));
    EXPECT_EQ(v3.voxel_size, 7);
  }
  auto bad = bytes;
  bad[bad.size() / 2] ^= 0x40;
  const auto e = deserialize_vps(bad.data(), bad.size(), &vm2, &ps2);
  ASSERT_TRUE(e);
  EXPECT_NE(e->message.find("checksum"), std::string::npos);
  bad = bytes;
  bad[0] = 'X';
  EXPECT_TRUE(deserialize_vps(bad.data(), bad.size(), &vm2, &ps2));
  bad = bytes;
  bad[8] = 99;
  EXPECT_TRUE(deserialize_vps(bad.data(), bad.size(), &vm2, &ps2));
}

}  // namespace
}  // namespace hemm::vps
