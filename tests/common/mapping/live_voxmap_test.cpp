// The live voxmap from SIMULATED depth clouds of a closed-form scene (floor,
// a table box, optionally a block on it), sent through the wire encoding:
// the VPS force of a sphere tool against the snapshot is checked against the
// exact force of the true plane (K times the volume of the sphere's cap below
// it, since the integral of p n over the cap is the cap's volume), free space
// clears a block that was taken away, and the region of interest bounds what
// is stored.
#include "common/mapping/live_voxmap.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/pointshell.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_stream.h"
#include "common/mesh/primitives.h"
#include "robot_side/sim/depth_camera.h"
#include "tests/common/mapping/depth_scene.h"

namespace hm = hemm::mapping;
namespace vps = hemm::vps;

namespace {

using hemm::test::kTableTop;
using hemm::test::TableScene;

hm::LiveVoxmapParams table_params() {
  hm::LiveVoxmapParams p;
  p.voxel_size = 0.01;
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(0.5, -0.6, 0.55), Eigen::Vector3d(1.5, 0.6, 0.95));
  return p;
}

// The region the tool explores (keeps the tests lean under the sanitizers).
hm::LiveVoxmapParams tool_params(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  hm::LiveVoxmapParams p = table_params();
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(lo.x(), lo.y(), 0.6), Eigen::Vector3d(hi.x(), hi.y(), 0.85));
  return p;
}

struct Tool {
  vps::PointShell ps;
  double R = 0.05;
  Tool() {
    vps::PointShellParams pp;
    pp.voxel_size = 0.003;
    EXPECT_FALSE(vps::build_pointshell(hemm::mesh::make_icosphere(R, 4), pp, Eigen::Vector3d::Zero(), &ps));
  }
  vps::PairResult at(const vps::Voxmap& vm, const Eigen::Vector3d& centre) const {
    vps::PairResult r;
    const Eigen::Isometry3d T_W_P{Eigen::Translation3d(centre)};
    vps::evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T_W_P, vps::ContactParams{},
                       nullptr, &r);
    return r;
  }
};

int surface_voxels_in(const vps::Voxmap& vm, const Eigen::AlignedBox3d& box) {
  int n = 0;
  for (int z = 0; z < vm.dims().z(); ++z) {
    for (int y = 0; y < vm.dims().y(); ++y) {
      for (int x = 0; x < vm.dims().x(); ++x) {
        const Eigen::Vector3i v(x, y, z);
        if (box.contains(vps::voxel_centre(vm, v)) && vps::sample_voxel(vm, v).layer == 0) ++n;
      }
    }
  }
  return n;
}

}  // namespace

TEST(LiveVoxmap, SphereForceOnTheSeenTableMatchesTheExactPlane) {
  hm::LiveVoxmap map(tool_params({0.7, -0.35}, {1.3, 0.35}));
  std::mt19937_64 rng(2024);
  ASSERT_TRUE(hemm::test::observe_table(TableScene{}, 9, rng, &map));
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  EXPECT_TRUE(vm.signed_field);
  const Tool tool;
  const double K = vps::ContactParams{}.stiffness;
  // Places on the top the camera saw from all three viewpoints, and depths
  // from light touch to the 2 cm the device's stiffness allows.
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(1.0, 0.0), Eigen::Vector2d(0.83, 0.21), Eigen::Vector2d(1.17, -0.26)}) {
    for (const double d : {0.004, 0.01, 0.02}) {
      const Eigen::Vector3d c(xy.x(), xy.y(), kTableTop + tool.R - d);
      const vps::PairResult r = tool.at(vm, c);
      const Eigen::Vector3d F = r.on_shell.force;
      std::printf("xy %5.2f %5.2f d %5.3f  F %8.2f ref %8.2f  err %+6.2f %%  angle %.2f deg\n", xy.x(), xy.y(), d, F.z(),
                  hemm::test::cap_force(K, tool.R, d), 100 * (F.z() / hemm::test::cap_force(K, tool.R, d) - 1),
                  std::acos(std::clamp(F.normalized().z(), -1.0, 1.0)) * 180 / std::numbers::pi);
      // The map's geometric error, stated as an equivalent depth error: the
      // force lies between the exact forces 1.5 mm shallower and deeper.
      const double tol = 0.0015;
      EXPECT_GT(F.z(), hemm::test::cap_force(K, tool.R, d - tol)) << xy.transpose() << " d " << d;
      EXPECT_LT(F.z(), hemm::test::cap_force(K, tool.R, d + tol)) << xy.transpose() << " d " << d;
      EXPECT_LT(std::acos(std::clamp(F.normalized().z(), -1.0, 1.0)), 3.0 * std::numbers::pi / 180.0) << xy.transpose();
      EXPECT_LT(r.on_shell.torque.norm(), 0.03 * tool.R * F.norm());  // through the centre
    }
    // 5 mm above the table: free.
    EXPECT_EQ(tool.at(vm, {xy.x(), xy.y(), kTableTop + tool.R + 0.005}).contacts, 0);
  }
}

TEST(LiveVoxmap, FreeSpaceClearsABlockThatWasTakenAway) {
  hm::LiveVoxmap map(tool_params({0.8, -0.2}, {1.2, 0.2}));
  std::mt19937_64 rng(7);
  TableScene scene;
  scene.block = true;
  ASSERT_TRUE(hemm::test::observe_table(scene, 6, rng, &map));
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  const Tool tool;
  const Eigen::Vector3d on_block(1.0, 0.0, kTableTop + 0.1 + tool.R - 0.005);
  EXPECT_GT(tool.at(vm, on_block).on_shell.force.z(), 0.5 * hemm::test::cap_force(1e7, tool.R, 0.005));
  // The block's volume above the table's noise band.
  const Eigen::AlignedBox3d block(Eigen::Vector3d(0.93, -0.07, kTableTop + 0.02), Eigen::Vector3d(1.07, 0.07, 0.82));
  EXPECT_GT(surface_voxels_in(vm, block), 100);
  scene.block = false;
  ASSERT_TRUE(hemm::test::observe_table(scene, 12, rng, &map));
  ASSERT_FALSE(map.snapshot(&vm));
  EXPECT_EQ(tool.at(vm, on_block).contacts, 0);
  EXPECT_GT(map.stats().cells_forgotten, 0u);
  EXPECT_EQ(surface_voxels_in(vm, block), 0);
  // Where the block stood, the table top is felt again.
  const Eigen::Vector3d on_table(1.0, 0.0, kTableTop + tool.R - 0.01);
  EXPECT_NEAR(tool.at(vm, on_table).on_shell.force.z(), hemm::test::cap_force(1e7, tool.R, 0.01), 0.3 * hemm::test::cap_force(1e7, tool.R, 0.01));
}

TEST(LiveVoxmap, RegionOfInterestBoundsWhatIsStored) {
  auto p = table_params();
  hm::LiveVoxmap map(p);
  std::mt19937_64 rng(3);
  ASSERT_TRUE(hemm::test::observe_table(TableScene{}, 3, rng, &map));
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  // Nothing outside the ROI: the floor (z = 0) is never stored.
  const Eigen::Vector3d hi = vm.origin + vm.dims().cast<double>() * vm.voxel_size;
  const double margin = (p.layers + 2 + 8) * p.voxel_size;
  EXPECT_GT(vm.origin.z(), p.roi.min().z() - margin);
  EXPECT_LT(hi.z(), p.roi.max().z() + margin);
  // The table top inside the ROI is 1 m x 1 m: at most ~1 cell per cm^2 and a
  // few rows more for noise.
  const std::size_t cells = map.cells();
  EXPECT_GT(cells, 3000u);
  EXPECT_LT(cells, 2 * 10000u);
  // Shrinking the ROI drops cells outside it.
  map.set_roi(Eigen::AlignedBox3d(Eigen::Vector3d(0.9, -0.1, 0.6), Eigen::Vector3d(1.1, 0.1, 0.8)));
  EXPECT_LT(map.cells(), 600u);
  EXPECT_GT(map.cells(), 200u);
}

TEST(LiveVoxmap, ParamsAreCheckedAndAnEmptyMapHasNoSnapshot) {
  EXPECT_FALSE(hm::LiveVoxmap::check(table_params()));
  auto p = table_params();
  p.voxel_size = 0;
  EXPECT_TRUE(hm::LiveVoxmap::check(p));
  p = table_params();
  p.roi = Eigen::AlignedBox3d();
  EXPECT_TRUE(hm::LiveVoxmap::check(p));
  p = table_params();
  p.log_odds_miss = 0.3f;
  EXPECT_TRUE(hm::LiveVoxmap::check(p));
  p = table_params();
  p.roi.max().x() = 1e9;
  EXPECT_TRUE(hm::LiveVoxmap::check(p));
  hm::LiveVoxmap map(table_params());
  vps::Voxmap vm;
  vm.voxel_size = 42;
  EXPECT_TRUE(map.snapshot(&vm));
  EXPECT_EQ(vm.voxel_size, 42);
}

namespace {

// Where the field along a -> b first changes sign (linear between 1 mm
// samples), or NaN if it does not.
double zero_crossing(const vps::Voxmap& vm, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const int n = static_cast<int>(std::ceil((b - a).norm() / 0.001));
  double prev = vps::sdf_trilinear(vm, a);
  for (int i = 1; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    const double cur = vps::sdf_trilinear(vm, a + t * (b - a));
    if ((prev < 0) != (cur < 0)) return (static_cast<double>(i) - cur / (cur - prev)) / n;
    prev = cur;
  }
  return std::nan("");
}

}  // namespace

// A convex edge whose top the camera sees at a grazing angle (11 degrees,
// its rows 6-7 cm apart on the top, as the mast camera sees table tops): the nearest patch of a point just above
// the top near the front edge is often a front-face patch, whose plane puts
// the point behind it. The rays that passed through the point on their way
// to the top beyond show it is free, so it must be outside; points truly
// behind the front face and below the top stay inside, and the surfaces keep
// their zero crossing.
TEST(LiveVoxmap, SpaceARayPassedThroughAboveAConvexEdgeIsOutside) {
  hm::LiveVoxmapParams p = table_params();
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(0.8, -0.2, 0.6), Eigen::Vector3d(1.2, 0.2, 0.9));
  p.normal_radius = 0.05;  // the operator's probe_3d setting, for sparse rows
  hm::LiveVoxmap map(p);
  std::mt19937_64 rng(5);
  TableScene scene;
  scene.block = true;  // x 0.95-1.05, y -0.05-0.05, z 0.7-0.8
  const Eigen::Vector3d target(1.0, 0.0, kTableTop + 0.08);
  for (std::uint32_t f = 0; f < 6; ++f) {
    const double y = -0.02 + 0.02 * (f % 3);
    ASSERT_TRUE(hemm::test::observe(scene, hemm::test::look_at({-0.05, y, 1.0}, target), f, rng, &map));
  }
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  const double top = kTableTop + 0.1, front = 0.95;
  int above = 0, above_inside = 0;
  for (const double y : {-0.03, -0.01, 0.01, 0.03}) {
    for (const double dx : {0.005, 0.015, 0.025}) {
      for (const double dz : {0.01, 0.015, 0.02}) {
        const double sd = vps::sdf_trilinear(vm, {front + dx, y, top + dz});
        ++above;
        if (sd < 0) {
          ++above_inside;
          std::printf("above the top at x %+.3f y %+.2f z %+.3f: sdf %+.4f\n", front + dx, y, top + dz, sd);
        }
      }
    }
  }
  EXPECT_EQ(above_inside, 0) << "of " << above;
  // Behind the front face and below the top, within the layers: inside.
  for (const double y : {-0.03, 0.0, 0.03}) {
    for (const Eigen::Vector2d& xz : {Eigen::Vector2d(front + 0.015, top - 0.015), Eigen::Vector2d(front + 0.02, top - 0.03),
                                      Eigen::Vector2d(front + 0.01, kTableTop + 0.05)}) {
      EXPECT_LT(vps::sdf_trilinear(vm, {xz.x(), y, xz.y()}), 0.0) << "x " << xz.x() << " y " << y << " z " << xz.y();
    }
  }
  // The surfaces' zero crossings: the top, the front face, the table before it.
  for (const double y : {-0.03, 0.0, 0.03}) {
    // The top is seen too edge-on to be rendered (rows 6-7 cm apart): near
    // the edge its zero crossing is where the cleared space meets the space
    // behind the front face.
    for (const double x : {front + 0.015, front + 0.025}) {
      const double t_top = zero_crossing(vm, {x, y, top + 0.03}, {x, y, top - 0.03});
      EXPECT_NEAR(top + 0.03 - 0.06 * t_top, top, 0.004) << "top x " << x << " y " << y;
    }
    const double t_front = zero_crossing(vm, {front - 0.03, y, kTableTop + 0.05}, {front + 0.03, y, kTableTop + 0.05});
    EXPECT_NEAR(front - 0.03 + 0.06 * t_front, front, 0.004) << "front y " << y;
    const double t_table = zero_crossing(vm, {0.88, y, kTableTop + 0.03}, {0.88, y, kTableTop - 0.03});
    EXPECT_NEAR(kTableTop + 0.03 - 0.06 * t_table, kTableTop, 0.004) << "table y " << y;
  }
}

namespace {

// The closed-form scene as the SIMULATED depth camera's ray caster, so the
// frames have the camera's own failure modes (its edge dropping too).
struct SceneCaster final : hemm::robot::RayCaster {
  TableScene scene;
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const override { return scene.cast(o, d); }
};

}  // namespace

// The home scene's mug as the mast sees it (issue 13's explore3d demo): its
// 8 cm top 0.25 m below the camera and 1.1 m ahead, 13 degrees below the
// horizontal, so the top is about one image row, and the camera's edge
// dropping (a pixel whose range jumps against a 4-neighbour's) drops that row
// and the first row past the mug. No top cell is rendered; the front face's
// patches put everything behind their plane inside, within their layers.
// The rays past the silhouette show the space over the top is free: it must
// be outside, while the mug's inside behind the seen front face stays inside.
TEST(LiveVoxmap, SpaceOverASmallTopSeenAtAGrazingAngleIsOutside) {
  hm::LiveVoxmapParams p = table_params();
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(0.95, -0.25, 0.6), Eigen::Vector3d(1.4, 0.25, 0.95));
  p.normal_radius = 0.05;  // the operator's probe_3d setting
  hm::LiveVoxmap map(p);
  SceneCaster caster;
  caster.scene.mug = true;
  const Eigen::Vector2d axis = TableScene::mug_axis();
  const double top = kTableTop + TableScene::kMugHeight, R = TableScene::kMugRadius;
  // The mast (1.10 m high, pitched 35 degrees down) 1.1 m before the mug and 0.1 m aside.
  const Eigen::Vector3d eye(axis.x() - 1.1, axis.y() - 0.1, top + 0.25);
  const double pitch = 35.0 * std::numbers::pi / 180.0;
  const Eigen::Isometry3d T_W_S = hemm::test::look_at(eye, eye + Eigen::Vector3d(std::cos(pitch), 0.0, -std::sin(pitch)));
  const hemm::robot::SimDepthCameraParams cam;  // 80 x 60, 60 degrees, edge dropping on
  std::mt19937_64 rng(11);
  for (std::uint32_t f = 0; f < 6; ++f) {
    hm::DepthImage img = hemm::robot::simulate_depth_image(cam, caster, T_W_S, rng);
    img.cloud_id = f;
    img.T_W_S = img.T_W_S_truth = T_W_S;
    std::vector<hemm::wire::DepthChunk> chunks;
    ASSERT_FALSE(hm::encode_depth_chunks(img, "depth", {}, &chunks));
    for (const auto& c : chunks) {
      hm::DepthChunkData d;
      ASSERT_FALSE(hm::decode_depth_chunk(c, 0, &d));
      map.integrate(d);
    }
  }
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  if (std::getenv("LIVE_VOXMAP_DEBUG")) {
    for (double z = top + 0.05; z > top - 0.06; z -= 0.005) {
      std::printf("z %+.3f:", z - top);
      for (double x = axis.x() - R - 0.03; x < axis.x() + R + 0.03; x += 0.005) std::printf(" %+4.0f", 1000 * vps::sdf_trilinear(vm, {x, axis.y(), z}));
      std::printf("\n");
    }
  }
  // Over the top, 1-3 cm above it, within 3 cm of the axis: outside.
  int above = 0, above_inside = 0;
  for (const double dx : {-0.03, -0.015, 0.0, 0.015, 0.03}) {
    for (const double dy : {-0.02, 0.0, 0.02}) {
      for (const double dz : {0.01, 0.015, 0.02, 0.025, 0.03}) {
        const Eigen::Vector3d x(axis.x() + dx, axis.y() + dy, top + dz);
        const double sd = vps::sdf_trilinear(vm, x);
        ++above;
        if (sd <= 0) {
          ++above_inside;
          std::printf("over the top at dx %+.3f dy %+.3f dz %+.3f: sdf %+.4f\n", dx, dy, dz, sd);
        }
      }
    }
  }
  EXPECT_EQ(above_inside, 0) << "of " << above;
  // Over the front half of the top (the back half lies beyond the front
  // face's layers, where nothing is modelled) the field's zero crossing is
  // the top, within a voxel (within 4 mm but at the front rim, 9 mm): the
  // tool rests on it.
  for (const double dx : {-0.03, -0.02, -0.01}) {
    for (const double dy : {-0.015, 0.0, 0.015}) {
      const Eigen::Vector3d a(axis.x() + dx, axis.y() + dy, top + 0.03);
      const double t = zero_crossing(vm, a, a - Eigen::Vector3d(0, 0, 0.06));
      std::printf("top's zero crossing at dx %+.3f dy %+.3f: %+.4f m\n", dx, dy, top + 0.03 - 0.06 * t - top);
      EXPECT_NEAR(top + 0.03 - 0.06 * t, top, p.voxel_size) << "top dx " << dx << " dy " << dy;
    }
  }
  // Behind the seen front face, below the top: inside.
  for (const double dy : {-0.02, 0.0, 0.02}) {
    const double front = axis.x() - std::sqrt(R * R - dy * dy);
    for (const Eigen::Vector2d& xz : {Eigen::Vector2d(front + 0.015, top - 0.015), Eigen::Vector2d(front + 0.02, top - 0.03),
                                      Eigen::Vector2d(front + 0.01, kTableTop + 0.05)}) {
      EXPECT_LT(vps::sdf_trilinear(vm, {xz.x(), axis.y() + dy, xz.y()}), 0.0)
          << "x " << xz.x() << " dy " << dy << " z " << xz.y();
    }
    // The front face's zero crossing at mid-height.
    const double t = zero_crossing(vm, {front - 0.03, axis.y() + dy, kTableTop + 0.05}, {front + 0.03, axis.y() + dy, kTableTop + 0.05});
    // (the voxelised curve: 6 mm, 4 mm on the planes above)
    EXPECT_NEAR(front - 0.03 + 0.06 * t, front, 0.006) << "front dy " << dy;
  }
}
