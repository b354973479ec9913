// 3D shape completion of the live voxmap (shape_completion3d.h) from
// SIMULATED depth frames of closed-form scenes: a table top with one object
// on it (a turned box, a cylinder standing or lying, a sphere), seen by a
// camera from one side only, sent through the wire encoding into a
// LiveVoxmap. The fitted primitive is checked against the object's true
// geometry (its unseen faces included), the voxmap's flags against what was
// seen, and a lone plane must stay a plane. Sizes and poses here were not
// used to choose the parameters (those come from the sensor's noise and
// sampling, see shape_completion3d.h).
#include "common/mapping/shape_completion3d.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/live_voxmap.h"
#include "tests/common/mapping/depth_scene.h"

namespace hm = hemm::mapping;
namespace vps = hemm::vps;

namespace {

constexpr double kTop = 0.70;  // table top

// A table top (x 0.4-1.6, y -0.6-0.6) and at most one object on or above it.
struct ObjectScene {
  enum class Kind { kNone, kBox, kCylinder, kSphere } kind = Kind::kNone;
  Eigen::Isometry3d T_W_O = Eigen::Isometry3d::Identity();  // object frame: box centre / cylinder centre, z axis
  Eigen::Vector3d half = Eigen::Vector3d::Zero();           // box half extents; cylinder (r, r, half height); sphere r
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = hemm::test::ray_box(o, d, {0.4, -0.6, 0.0}, {1.6, 0.6, kTop});
    auto take = [&](double t) {
      if (t > 0 && (best < 0 || t < best)) best = t;
    };
    const Eigen::Vector3d oo = T_W_O.inverse() * o, dd = T_W_O.linear().transpose() * d;
    switch (kind) {
      case Kind::kBox:
        take(hemm::test::ray_box(oo, dd, -half, half));
        break;
      case Kind::kCylinder:
        take(hemm::test::ray_upright_cylinder(oo, dd, {0.0, 0.0}, half.x(), -half.z(), half.z()));
        break;
      case Kind::kSphere: {
        const double b = oo.dot(dd), c = oo.squaredNorm() - half.x() * half.x();
        if (b * b - c >= 0) take(-b - std::sqrt(b * b - c));
        break;
      }
      case Kind::kNone:
        break;
    }
    return best;
  }
};

hm::LiveVoxmapParams params() {
  hm::LiveVoxmapParams p;
  p.voxel_size = 0.01;
  p.normal_radius = 0.05;  // as the operator's probe_3d config
  p.roi = Eigen::AlignedBox3d(Eigen::Vector3d(0.6, -0.35, 0.6), Eigen::Vector3d(1.4, 0.35, 1.0));
  p.shape_completion = true;
  p.unknown_solid = true;
  return p;
}

// Frames from one side only (-x, above), as the robot's mast sees a table:
// three positions 12 cm apart, looking at the object.
void observe_from_one_side(const ObjectScene& scene, const Eigen::Vector3d& target, hm::LiveVoxmap* map) {
  std::mt19937_64 rng(99);
  for (int f = 0; f < 9; ++f) {
    const double y = -0.12 + 0.12 * (f % 3);
    ASSERT_TRUE(hemm::test::observe(scene, hemm::test::look_at({0.35, y, 1.15}, target), static_cast<std::uint32_t>(f),
                                    rng, map));
  }
}

const hm::Primitive3* only(const hm::Shape3dModel& m, hm::PrimitiveKind k) {
  const hm::Primitive3* found = nullptr;
  int n = 0;
  for (const auto& q : m.primitives) {
    if (q.kind != k) continue;
    found = &q;
    ++n;
  }
  EXPECT_EQ(m.primitives.size(), 1u);
  return n == 1 ? found : nullptr;
}

Eigen::Isometry3d pose(double x, double y, double z, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() << x, y, z;
  return T;
}

double angle_between_axes(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized()))));
}

}  // namespace

TEST(ShapeCompletion3d, ABoxSeenOnTwoFacesIsCompletedToItsTrueUnseenFaces) {
  // 11 x 8 x 9 cm, turned 17 degrees about z: the camera sees its top and
  // its -x face; its +x (back) face and its -y side are never seen.
  ObjectScene scene;
  scene.kind = ObjectScene::Kind::kBox;
  scene.half = Eigen::Vector3d(0.055, 0.04, 0.045);
  scene.T_W_O = pose(1.02, 0.03, kTop + 0.045, Eigen::AngleAxisd(0.30, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  hm::LiveVoxmap map(params());
  observe_from_one_side(scene, scene.T_W_O.translation(), &map);
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm, hemm::steady_now_ns));
  const hm::Primitive3* q = only(map.shapes(), hm::PrimitiveKind::kBox);
  ASSERT_NE(q, nullptr);
  std::printf("box: centre %.4f %.4f %.4f half %.4f %.4f %.4f faces %d rms %.4f, completion %.2f ms, unknown space %.2f ms, snapshot %.2f ms\n",
              q->T_W_P.translation().x(), q->T_W_P.translation().y(), q->T_W_P.translation().z(), q->half.x(), q->half.y(),
              q->half.z(), q->faces, q->rms, 1e-6 * map.snapshot_report().completion_ns, 1e-6 * map.snapshot_report().unknown_ns,
              1e-6 * map.snapshot_report().snapshot_ns);
  EXPECT_GE(q->faces, 2);
  // Every true face, seen or not, lies within the tolerance of the fitted
  // box's surface: points on each face's centre and near its corners. The
  // tolerance: 1.2 cm on faces whose extent comes from the last sample on an
  // edge (one image pixel on the top seen at ~35 degrees is ~1.5 cm).
  const double tol = 0.012;
  for (int a = 0; a < 3; ++a)
    for (const double sgn : {-1.0, 1.0})
      for (const double u : {0.0, -0.7, 0.7})
        for (const double v : {0.0, -0.7, 0.7}) {
          Eigen::Vector3d l = Eigen::Vector3d::Zero();
          l[a] = sgn * scene.half[a];
          l[(a + 1) % 3] = u * scene.half[(a + 1) % 3];
          l[(a + 2) % 3] = v * scene.half[(a + 2) % 3];
          const Eigen::Vector3d x = scene.T_W_O * l;
          Eigen::Vector3d g;
          bool kink = false;
          const double d = hm::primitive_sdf(*q, x, &g, &kink, 0.0);
          EXPECT_LT(std::abs(d), tol) << "face axis " << a << " sign " << sgn << " at " << x.transpose();
        }
  // Its axes are the true ones (within 4 degrees).
  for (int a = 0; a < 3; ++a) {
    double best = 10.0;
    for (int b = 0; b < 3; ++b) best = std::min(best, angle_between_axes(q->T_W_P.linear().col(a), scene.T_W_O.linear().col(b)));
    EXPECT_LT(best, 4.0 * std::numbers::pi / 180.0) << "axis " << a;
  }
  // The voxmap: the seen top is not inferred, the unseen back face is.
  auto flags_at = [&](const Eigen::Vector3d& x) { return vps::sample_voxel(vm, vps::voxel_of(vm, x)).flags; };
  const Eigen::Vector3d top = scene.T_W_O * Eigen::Vector3d(-0.01, 0.0, scene.half.z() + 0.002);
  const Eigen::Vector3d back = scene.T_W_O * Eigen::Vector3d(scene.half.x() + 0.002, 0.0, 0.0);
  EXPECT_EQ(flags_at(top) & vps::kFlagInferred, 0) << top.transpose();
  EXPECT_NE(flags_at(back) & vps::kFlagInferred, 0) << back.transpose();
  // The back is solid where it truly is: inside 1 cm behind the back face, outside 2 cm beyond it.
  EXPECT_LT(vps::sample_voxel(vm, vps::voxel_of(vm, scene.T_W_O * Eigen::Vector3d(scene.half.x() - 0.01, 0, 0))).sdf, 0.0f);
  EXPECT_GT(vps::sample_voxel(vm, vps::voxel_of(vm, scene.T_W_O * Eigen::Vector3d(scene.half.x() + 0.02, 0, 0))).sdf, 0.0f);
}

TEST(ShapeCompletion3d, CylindersStandingAndLyingGetTheirRadiusAndAxis) {
  struct Case {
    const char* name;
    Eigen::Isometry3d T;
    double r, hh;
  };
  const Eigen::Matrix3d lying =
      (Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Case cases[] = {
      {"standing r 3.5 cm", pose(1.05, -0.04, kTop + 0.065, Eigen::Matrix3d::Identity()), 0.035, 0.065},
      {"standing r 6 cm", pose(0.98, 0.05, kTop + 0.05, Eigen::Matrix3d::Identity()), 0.06, 0.05},
      {"lying r 4.5 cm", pose(1.0, 0.0, kTop + 0.045, lying), 0.045, 0.09},
  };
  for (const Case& c : cases) {
    ObjectScene scene;
    scene.kind = ObjectScene::Kind::kCylinder;
    scene.T_W_O = c.T;
    scene.half = Eigen::Vector3d(c.r, c.r, c.hh);
    hm::LiveVoxmap map(params());
    observe_from_one_side(scene, c.T.translation(), &map);
    vps::Voxmap vm;
    ASSERT_FALSE(map.snapshot(&vm, hemm::steady_now_ns));
    const hm::Primitive3* q = only(map.shapes(), hm::PrimitiveKind::kCylinder);
    ASSERT_NE(q, nullptr) << c.name;
    const double axis_err = angle_between_axes(q->T_W_P.linear().col(2), c.T.linear().col(2));
    // Distance between the axes (lines), at the true centre.
    const Eigen::Vector3d a = q->T_W_P.linear().col(2);
    const Eigen::Vector3d off = c.T.translation() - q->T_W_P.translation();
    const double axis_dist = (off - off.dot(a) * a).norm();
    std::printf("%s: r %.4f (true %.4f) axis %.2f deg, axis offset %.4f, half height %.4f (true %.4f), arc %.0f deg, "
                "completion %.2f ms\n",
                c.name, q->half.x(), c.r, axis_err * 180 / std::numbers::pi, axis_dist, q->half.z(), c.hh,
                q->arc * 180 / std::numbers::pi, 1e-6 * map.snapshot_report().completion_ns);
    EXPECT_NEAR(q->half.x(), c.r, 0.005) << c.name;
    EXPECT_LT(axis_err, 5.0 * std::numbers::pi / 180.0) << c.name;
    EXPECT_LT(axis_dist, 0.006) << c.name;
    // The unseen back of the side: within 1 cm of the fitted surface.
    const Eigen::Vector3d back = c.T * Eigen::Vector3d(0.0, 0.0, 0.0) + c.r * Eigen::Vector3d(1, 0, 0);
    Eigen::Vector3d g;
    bool kink = false;
    EXPECT_LT(std::abs(hm::primitive_sdf(*q, back, &g, &kink, 0.0)), 0.01) << c.name;
  }
}

TEST(ShapeCompletion3d, ASphereGetsItsCentreAndRadius) {
  for (const double r : {0.05, 0.08}) {
    ObjectScene scene;
    scene.kind = ObjectScene::Kind::kSphere;
    scene.half = Eigen::Vector3d::Constant(r);
    scene.T_W_O = pose(1.03, -0.02, kTop + r, Eigen::Matrix3d::Identity());
    hm::LiveVoxmap map(params());
    observe_from_one_side(scene, scene.T_W_O.translation(), &map);
    vps::Voxmap vm;
    ASSERT_FALSE(map.snapshot(&vm, hemm::steady_now_ns));
    const hm::Primitive3* q = only(map.shapes(), hm::PrimitiveKind::kSphere);
    ASSERT_NE(q, nullptr) << r;
    const double centre_err = (q->T_W_P.translation() - scene.T_W_O.translation()).norm();
    std::printf("sphere r %.3f: fitted %.4f, centre off %.4f, completion %.2f ms\n", r, q->half.x(), centre_err,
                1e-6 * map.snapshot_report().completion_ns);
    EXPECT_NEAR(q->half.x(), r, 0.005);
    EXPECT_LT(centre_err, 0.006);
    // Its unseen back (+x) is solid where it truly is, and inferred.
    const Eigen::Vector3d back = scene.T_W_O.translation() + Eigen::Vector3d(r - 0.01, 0, 0);
    const vps::Voxel vx = vps::sample_voxel(vm, vps::voxel_of(vm, back));
    EXPECT_LT(vx.sdf, 0.0f);
    EXPECT_NE(vx.flags & vps::kFlagInferred, 0);
  }
}

TEST(ShapeCompletion3d, APlaneAloneIsNotABoxAndStaysSeen) {
  // The bare table, and a thin 1 cm board lying on it (a plane above the
  // support by less than a box's minimum height is not a box).
  ObjectScene bare;
  hm::LiveVoxmap map(params());
  observe_from_one_side(bare, {1.0, 0.0, kTop}, &map);
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  EXPECT_TRUE(map.shapes().primitives.empty());
  EXPECT_TRUE(map.shapes().have_support);
  EXPECT_NEAR(-map.shapes().support[3] / map.shapes().support[2], kTop, 0.004);
  // The seen table is not inferred; 2 cm below it (unseen, solid) is.
  const vps::Voxel on = vps::sample_voxel(vm, vps::voxel_of(vm, {1.0, 0.0, kTop + 0.004}));
  EXPECT_EQ(on.flags & vps::kFlagInferred, 0);
  EXPECT_LT(vps::sample_voxel(vm, vps::voxel_of(vm, {1.0, 0.0, kTop - 0.02})).sdf, 0.0f);
  // A wall-like vertical board 30 x 20 cm (one vertical face: not a box on the table).
  ObjectScene wall;
  wall.kind = ObjectScene::Kind::kBox;
  wall.half = Eigen::Vector3d(0.004, 0.15, 0.1);
  wall.T_W_O = pose(1.1, 0.0, kTop + 0.1, Eigen::Matrix3d::Identity());
  hm::LiveVoxmap map2(params());
  observe_from_one_side(wall, {1.1, 0.0, kTop + 0.1}, &map2);
  vps::Voxmap vm2;
  ASSERT_FALSE(map2.snapshot(&vm2));
  for (const auto& q : map2.shapes().primitives) {
    // Whatever is fitted must not close space behind the board (+x) that the
    // camera saw over it: nothing reaches 3 cm behind it.
    Eigen::Vector3d g;
    bool kink = false;
    EXPECT_GT(hm::primitive_sdf(q, {1.1 + 0.03, 0.0, kTop + 0.1}, &g, &kink, 0.0), 0.0);
  }
}

TEST(ShapeCompletion3d, PrimitivesAreKeptWhileTheirCellsStayOnThemAndOneMapGivesOneModel) {
  ObjectScene scene;
  scene.kind = ObjectScene::Kind::kCylinder;
  scene.half = Eigen::Vector3d(0.045, 0.045, 0.06);
  scene.T_W_O = pose(1.0, 0.02, kTop + 0.06, Eigen::Matrix3d::Identity());
  hm::LiveVoxmap map(params());
  observe_from_one_side(scene, scene.T_W_O.translation(), &map);
  vps::Voxmap a, b;
  ASSERT_FALSE(map.snapshot(&a));
  ASSERT_EQ(map.shapes().primitives.size(), 1u);
  const hm::Primitive3 first = map.shapes().primitives[0];
  // The same map twice: the same model (seeded RANSAC), voxel for voxel.
  hm::LiveVoxmap again(params());
  observe_from_one_side(scene, scene.T_W_O.translation(), &again);
  ASSERT_FALSE(again.snapshot(&b));
  ASSERT_EQ(a.blocks.size(), b.blocks.size());
  for (std::size_t i = 0; i < a.blocks.size(); ++i)
    for (int k = 0; k < vps::kBlockVoxels; ++k) ASSERT_EQ(a.blocks[i].v[static_cast<std::size_t>(k)].sdf, b.blocks[i].v[static_cast<std::size_t>(k)].sdf);
  (void)first;
}

TEST(ShapeCompletion3d, APrimitiveIsKeptWhileItsCellsStayOnItAndGoesWhenTheyMove) {
  // Cell samples straight on a table plane and the seen half of an upright
  // cylinder (r 5 cm), with 1.5 mm noise.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.0015);
  auto cells_with_cylinder_at = [&](const Eigen::Vector2d& axis) {
    std::vector<hm::CellSample3> cells;
    const Eigen::Vector3d view = Eigen::Vector3d(-1, 0, 0.6).normalized();
    for (double x = 0.7; x <= 1.3; x += 0.01)
      for (double y = -0.25; y <= 0.25; y += 0.01) {
        if ((Eigen::Vector2d(x, y) - axis).norm() < 0.06) continue;
        cells.push_back({Eigen::Vector3d(x, y, kTop + noise(rng)), Eigen::Vector3d::UnitZ(), view});
      }
    for (double a = 0.5 * std::numbers::pi + 0.1; a < 1.5 * std::numbers::pi - 0.1; a += 0.2)
      for (double z = kTop + 0.005; z < kTop + 0.1; z += 0.01) {
        const Eigen::Vector3d n(std::cos(a), std::sin(a), 0.0);
        cells.push_back({Eigen::Vector3d(axis.x(), axis.y(), z) + (0.05 + noise(rng)) * n, n, view});
      }
    return cells;
  };
  hm::Shape3dParams p;
  hm::Shape3dModel m;
  const auto cells = cells_with_cylinder_at({1.0, 0.0});
  hm::complete_shapes_3d(p, cells, {}, m);
  ASSERT_EQ(m.primitives.size(), 1u);
  EXPECT_EQ(m.primitives[0].kind, hm::PrimitiveKind::kCylinder);
  EXPECT_NEAR(m.primitives[0].half.x(), 0.05, 0.004);
  // A fit this map alone fails (an RMS nothing meets): the cylinder is kept.
  hm::Shape3dParams strict = p;
  strict.max_rms = 1e-5;
  hm::complete_shapes_3d(strict, cells, {}, m);
  ASSERT_EQ(m.primitives.size(), 1u);
  EXPECT_TRUE(m.primitives[0].kept);
  EXPECT_EQ(m.kept, 1u);
  // The object moved 6 cm: its cells are no longer on the kept cylinder.
  hm::complete_shapes_3d(strict, cells_with_cylinder_at({1.0, 0.06}), {}, m);
  EXPECT_TRUE(m.primitives.empty());
  // A space the camera saw free inside the fitted cylinder refuses it.
  hm::Shape3dModel fresh;
  hm::complete_shapes_3d(p, cells, [](const Eigen::Vector3d& x) { return x.x() > 1.0; }, fresh);
  EXPECT_TRUE(fresh.primitives.empty());
  EXPECT_EQ(fresh.refused_free, 1u);
}

TEST(LiveVoxmapUnknownSolid, UnseenSpaceIsSolidAndInferredWhileSeenSurfacesStayWhereTheyAre) {
  // A 9 cm cube (axis-aligned) seen from -x only, completion off: behind it
  // no ray has passed. Its +x half is solid and inferred with unknown_solid,
  // and outside without; the seen top stays at its height either way.
  ObjectScene scene;
  scene.kind = ObjectScene::Kind::kBox;
  scene.half = Eigen::Vector3d::Constant(0.045);
  scene.T_W_O = pose(1.0, 0.0, kTop + 0.045, Eigen::Matrix3d::Identity());
  hm::LiveVoxmapParams p = params();
  p.shape_completion = false;
  double crossing[2] = {NAN, NAN};
  for (const bool unknown_solid : {true, false}) {
    p.unknown_solid = unknown_solid;
    hm::LiveVoxmap map(p);
    observe_from_one_side(scene, scene.T_W_O.translation(), &map);
    vps::Voxmap vm;
    ASSERT_FALSE(map.snapshot(&vm, hemm::steady_now_ns));
    std::printf("unknown_solid %d: %zu voxels from unknown space, %zu inferred, record %zu bytes, %.2f ms of %.2f ms\n",
                unknown_solid, map.snapshot_report().voxels_unknown, map.snapshot_report().voxels_inferred, map.free_space_bytes(),
                1e-6 * map.snapshot_report().unknown_ns, 1e-6 * map.snapshot_report().snapshot_ns);
    // 3 cm inside the cube's unseen +x half, at mid height: beyond the top's
    // and the front's layers' reach as measured surfaces.
    const Eigen::Vector3d hidden = scene.T_W_O * Eigen::Vector3d(0.03, 0.0, -0.01);
    const vps::Voxel h = vps::sample_voxel(vm, vps::voxel_of(vm, hidden));
    // 4 cm above the top: rays passed there.
    const Eigen::Vector3d above = scene.T_W_O * Eigen::Vector3d(0.0, 0.0, 0.045 + 0.04);
    EXPECT_TRUE(map.recorded_free(above) || !unknown_solid);
    EXPECT_GT(vps::sample_voxel(vm, vps::voxel_of(vm, above)).sdf, 0.0f);
    if (unknown_solid) {
      EXPECT_LT(h.sdf, 0.0f);
      EXPECT_NE(h.flags & vps::kFlagInferred, 0);
      EXPECT_FALSE(map.recorded_free(hidden));
    } else {
      EXPECT_EQ(map.snapshot_report().voxels_unknown, 0u);
      EXPECT_EQ(map.free_space_bytes(), 0u);
    }
    // The seen top: the field's zero crossing (as the contact interpolates
    // it) the same with and without (below), within 5 mm of the true top
    // (the raw model's own error), not inferred.
    const Eigen::Vector3d c = scene.T_W_O.translation();
    double z0 = NAN;
    for (double z = c.z() + 0.02; z < c.z() + 0.08 && std::isnan(z0); z += 0.0005)
      if (vps::sdf_hermite(vm, {c.x() - 0.015, c.y(), z}) > 0.0) z0 = z;
    EXPECT_NEAR(z0, kTop + 0.09, 0.005) << unknown_solid;
    crossing[unknown_solid ? 0 : 1] = z0;
    EXPECT_EQ(vps::sample_voxel(vm, vps::voxel_of(vm, {c.x() - 0.015, c.y(), kTop + 0.093})).flags & vps::kFlagInferred,
              0);
  }
  EXPECT_NEAR(crossing[0], crossing[1], 0.0006);  // unknown space never moves a seen surface
}

TEST(ShapeCompletion3dLog, CellsRoundTripAndBadBytesAreRefusedWithoutChange) {
  std::vector<hm::CellSample3> cells = {
      {Eigen::Vector3d(1.25, -0.5, 0.75), Eigen::Vector3d(0, 0.6, 0.8), Eigen::Vector3d(-0.8, 0, 0.6), 0.0125},
      {Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(), 0.0}};
  const std::string bytes = hm::cells_to_bytes(cells);
  EXPECT_EQ(bytes.size(), cells.size() * 40u);
  std::vector<hm::CellSample3> back;
  ASSERT_EQ(hm::cells_from_bytes(bytes, &back), "");
  ASSERT_EQ(back.size(), cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) {
    EXPECT_LT((back[i].p - cells[i].p).norm(), 1e-6);  // float32
    EXPECT_LT((back[i].n - cells[i].n).norm(), 1e-6);
    EXPECT_LT((back[i].view - cells[i].view).norm(), 1e-6);
    EXPECT_NEAR(back[i].range_pitch, cells[i].range_pitch, 1e-7);
  }
  // A torn record, a NaN, a normal that is not a unit vector: an error, *out untouched.
  const std::vector<hm::CellSample3> kept = back;
  EXPECT_NE(hm::cells_from_bytes(bytes.substr(0, 39), &back), "");
  std::string nan = bytes;
  const float q = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data() + 4, &q, 4);
  EXPECT_NE(hm::cells_from_bytes(nan, &back), "");
  std::string longn = bytes;
  const float two = 2.0f;
  std::memcpy(longn.data() + 12, &two, 4);
  EXPECT_NE(hm::cells_from_bytes(longn, &back), "");
  ASSERT_EQ(back.size(), kept.size());
  EXPECT_EQ(back[0].p, kept[0].p);
  // The CSV row has the header's columns.
  hm::Primitive3 b;
  b.half = Eigen::Vector3d(0.05, 0.04, 0.03);
  const auto count = [](const std::string& s) { return std::count(s.begin(), s.end(), ','); };
  EXPECT_EQ(count(hm::primitive_csv_row(b)), count(hm::primitive_csv_header()));
  EXPECT_EQ(hm::primitive_csv_row(b).rfind("box,0.00000,0.00000,0.00000,0.0000,0.0000,1.0000,1.0000,0.0000,0.0000,0.05000", 0), 0u);
}

// The failure the shape log showed on the home table (the book, 3 cm high,
// seen at ~25 degrees from the mast): the low front side's 5 cm normals are
// blended with the top's, so no face is fitted to it, and the top's front
// edge was moved out by half the top's sample spacing: the box stood 6-19
// mm proud of the seen front (book front 10.5 N RMS of a 7.7 N peak). Here
// another slab (24 x 13 x 2.6 cm, turned -20 degrees, elsewhere on the
// table) through the SIMULATED camera: its seen front and top are where
// they truly are, and a primitive proud of the seen front is refused even
// when held from an earlier completion.
TEST(ShapeCompletion3d, ALowSlabsSeenFrontPinsItsEdgeAndAPrimitiveProudOfSeenCellsIsRefused) {
  ObjectScene scene;
  scene.kind = ObjectScene::Kind::kBox;
  scene.half = Eigen::Vector3d(0.065, 0.12, 0.013);
  scene.T_W_O = pose(0.99, 0.06, kTop + 0.013, Eigen::AngleAxisd(-0.35, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  hm::LiveVoxmap map(params());
  observe_from_one_side(scene, scene.T_W_O.translation(), &map);
  vps::Voxmap vm;
  ASSERT_FALSE(map.snapshot(&vm));
  const hm::Primitive3* q = only(map.shapes(), hm::PrimitiveKind::kBox);
  ASSERT_NE(q, nullptr);
  auto sdf = [](const hm::Primitive3& b, const Eigen::Vector3d& x) {
    Eigen::Vector3d g;
    bool kink = false;
    return hm::primitive_sdf(b, x, &g, &kink, 0.0);
  };
  // The seen front (-x in the slab's frame, toward the camera) and the top,
  // at points away from the edges: within 4 mm (the camera's 2.5 mm noise
  // and the cells' 1 cm grid; 6 mm was the smallest error of the bad fit).
  for (const double v : {-0.6, 0.0, 0.6}) {
    const Eigen::Vector3d front = scene.T_W_O * Eigen::Vector3d(-scene.half.x(), v * scene.half.y(), 0.0);
    EXPECT_LT(std::abs(sdf(*q, front)), 0.004) << "front at " << front.transpose();
    for (const double u : {-0.5, 0.0, 0.5}) {
      const Eigen::Vector3d top = scene.T_W_O * Eigen::Vector3d(u * scene.half.x(), v * scene.half.y(), scene.half.z());
      EXPECT_LT(std::abs(sdf(*q, top)), 0.004) << "top at " << top.transpose();
    }
  }
  // The fitted slab with its front 1.5 cm out toward the camera (the bad
  // fit), as the previous completion: the top's cells all still lie on it,
  // but the seen front's cells are inside it. A fit this map alone fails
  // (an RMS nothing meets), so only the held one could stand; it is refused.
  const std::vector<hm::CellSample3>& cells = map.shape_samples();
  ASSERT_FALSE(cells.empty());
  hm::Primitive3 proud = *q;
  const Eigen::Vector3d toward = -scene.T_W_O.linear().col(0);  // the front's outward normal
  int a_front = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(q->T_W_P.linear().col(a).dot(toward)) > std::abs(q->T_W_P.linear().col(a_front).dot(toward))) a_front = a;
  proud.half[a_front] += 0.0075;
  proud.T_W_P.translation() += 0.0075 * toward;
  hm::Shape3dParams strict = map.params().shapes;
  strict.max_rms = 1e-5;
  hm::Shape3dModel held;
  held.primitives = {proud};
  hm::complete_shapes_3d(strict, cells, {}, held);
  EXPECT_TRUE(held.primitives.empty());
  // The good one, held the same way, stays.
  hm::Shape3dModel good;
  good.primitives = {*q};
  hm::complete_shapes_3d(strict, cells, {}, good);
  ASSERT_EQ(good.primitives.size(), 1u);
  EXPECT_TRUE(good.primitives[0].kept);
}
