// The coverage metric of the live voxmap (voxmap_coverage.h) on closed-form
// cases: a camera 1 m above a plane looking straight down sees exactly a
// 1.1547 m x 0.8660 m patch of it (60 degree hfov, 80 x 60 pixels); a cube on
// the plane hides its shadow and shows its top; an exact voxmap of the
// plane covers every visible sample; a live voxmap built from the chunks of the
// first half of a frame's rows covers half of the patch.
#include "robot_side/truth/voxmap_coverage.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_stream.h"
#include "common/mapping/live_voxmap.h"
#include "common/mesh/primitives.h"

namespace hm = hemm::mapping;
namespace hr = hemm::robot;
namespace vps = hemm::vps;

namespace {

hemm::mesh::TriangleMesh moved(hemm::mesh::TriangleMesh m, const Eigen::Vector3d& by) {
  for (Eigen::Vector3d& v : m.vertices) v += by;
  return m;
}

// 1 m above the origin, looking straight down (x_S = x_W, y_S = -y_W).
Eigen::Isometry3d looking_down() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  T.translation() << 0.0, 0.0, 1.0;
  return T;
}

const hm::DepthIntrinsics kK = hm::intrinsics_from_hfov(80, 60, std::numbers::pi / 3, 0.2, 3.0);
// The patch of the plane z = 0 the camera sees: 2 tan(30 deg) x 0.75 of it.
const double kPatchW = 2.0 * std::tan(std::numbers::pi / 6), kPatchH = 0.75 * kPatchW;

}  // namespace

TEST(VoxmapCoverage, VisibleSamplesOfAPlaneAndACubeMatchTheClosedForm) {
  // The plane: the top of a 4 m slab at z = 0.
  const auto slab = moved(hemm::mesh::make_box({2.0, 2.0, 0.05}), {0, 0, -0.05});
  hr::VisibleSurfaceParams vp;
  vp.density = 40000;
  const auto plane = hr::visible_surface_samples({&slab}, kK, looking_down(), vp);
  const double area = kPatchW * kPatchH;  // 1.0 m^2
  EXPECT_NEAR(static_cast<double>(plane.size()), vp.density * area, 0.02 * vp.density * area);
  for (const Eigen::Vector3d& x : plane) {
    EXPECT_NEAR(x.z(), 0.0, 1e-9);
    EXPECT_LE(std::abs(x.x()), 0.5 * kPatchW + 1e-9);
    EXPECT_LE(std::abs(x.y()), 0.5 * kPatchH + 1e-9);
  }
  // A 0.2 m cube under the camera: its sides are turned away, its top is
  // seen (0.04 m^2) and it hides the plane's square of side 0.2 / (1 - 0.2).
  const auto cube = moved(hemm::mesh::make_box({0.1, 0.1, 0.1}), {0, 0, 0.1});
  const auto both = hr::visible_surface_samples({&slab, &cube}, kK, looking_down(), vp);
  const double shadow = std::pow(0.2 / 0.8, 2);
  const double expected = area - shadow + 0.04;
  EXPECT_NEAR(static_cast<double>(both.size()), vp.density * expected, 0.02 * vp.density * expected);
  std::size_t on_top = 0;
  for (const Eigen::Vector3d& x : both) {
    if (x.z() > 0.1) {
      EXPECT_NEAR(x.z(), 0.2, 1e-9);
      ++on_top;
    } else {
      EXPECT_NEAR(x.z(), 0.0, 1e-9);
      EXPECT_FALSE(std::abs(x.x()) < 0.125 - 1e-6 && std::abs(x.y()) < 0.125 - 1e-6) << x.transpose();  // in the shadow
    }
  }
  EXPECT_NEAR(static_cast<double>(on_top), vp.density * 0.04, 0.1 * vp.density * 0.04);
  // Out of range (range_max below the plane): nothing.
  hm::DepthIntrinsics near = kK;
  near.range_max = 0.9;
  EXPECT_TRUE(hr::visible_surface_samples({&slab}, near, looking_down(), vp).empty());
}

TEST(VoxmapCoverage, ExactPlaneCoversAllAndHalfTheChunksCoverHalf) {
  const auto slab = moved(hemm::mesh::make_box({2.0, 2.0, 0.05}), {0, 0, -0.05});
  hr::VisibleSurfaceParams sp;
  sp.density = 20000;
  const auto samples = hr::visible_surface_samples({&slab}, kK, looking_down(), sp);
  ASSERT_GT(samples.size(), 15000u);
  // The exact voxmap of the plane covers every sample; one of a slab beside
  // the patch covers none.
  vps::VoxmapParams vp;
  vp.voxel_size = 0.01;
  vp.roi = Eigen::AlignedBox3d(Eigen::Vector3d(-0.8, -0.6, -0.1), Eigen::Vector3d(0.8, 0.6, 0.1));
  vps::Voxmap exact;
  ASSERT_FALSE(vps::build_voxmap(slab, vp, &exact, nullptr));
  EXPECT_DOUBLE_EQ(hr::surface_coverage(exact, samples), 1.0);
  vps::Voxmap beside;
  vp.roi = Eigen::AlignedBox3d(Eigen::Vector3d(-0.8, -0.6, 0.3), Eigen::Vector3d(0.8, 0.6, 0.6));
  ASSERT_FALSE(vps::build_voxmap(moved(slab, {0, 0, 0.5}), vp, &beside, nullptr));  // 0.5 m above: no sample near
  EXPECT_DOUBLE_EQ(hr::surface_coverage(beside, samples), 0.0);
  EXPECT_DOUBLE_EQ(hr::surface_coverage(exact, {}), 0.0);

  // A depth frame of the plane (depth = 1 m everywhere), through the wire
  // encoding: 12 chunks of 5 rows.
  hm::DepthImage img;
  img.cloud_id = 1;
  img.K = kK;
  img.T_W_S = img.T_W_S_truth = looking_down();
  img.depth.assign(80 * 60, 1.0f);
  img.status.assign(80 * 60, hm::DepthStatus::kValid);
  std::vector<hemm::wire::DepthChunk> wire;
  ASSERT_FALSE(hm::encode_depth_chunks(img, "depth", {}, &wire));
  ASSERT_GT(wire.size(), 2u);
  hm::LiveVoxmapParams lp;
  lp.voxel_size = 0.01;
  lp.normal_radius = 0.05;
  lp.roi = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -0.2), Eigen::Vector3d(1, 1, 0.3));
  auto coverage_of = [&](bool first_half_only) {
    hm::LiveVoxmap map(lp);
    int rows = 0;
    for (const auto& w : wire) {
      hm::DepthChunkData d;
      EXPECT_FALSE(hm::decode_depth_chunk(w, 0, &d));
      if (first_half_only && d.first_row >= 30) continue;
      map.integrate(d);
      rows += d.row_count;
    }
    EXPECT_EQ(rows, first_half_only ? 30 : 60);  // the chunks cut at row 30
    vps::Voxmap vm;
    EXPECT_FALSE(map.snapshot(&vm));
    return hr::surface_coverage(vm, samples);
  };
  const double full = coverage_of(false), half = coverage_of(true);
  std::printf("coverage: all chunks %.4f, first half of the rows %.4f\n", full, half);
  EXPECT_GT(full, 0.98);
  // Rows are linear in y on a fronto-parallel plane: half the rows see half
  // the patch; reach (one voxel) and the rendered cells' rim add up to two
  // voxels on the cut, 2 cm of the patch's 86.6 cm.
  EXPECT_GT(half, 0.5 - 0.01);
  EXPECT_LT(half, 0.5 + 0.02 / kPatchH + 0.005);
}
