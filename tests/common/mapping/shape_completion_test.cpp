#include "common/mapping/shape_completion.h"

#include <cmath>
#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include "common/math/geometry2.h"
#include "tests/common/mapping/scan_synth.h"

namespace hemm::mapping {
namespace {

using Eigen::Vector2d;
using math::Pose2;

constexpr std::int64_t kScanPeriodNs = 33'333'333;  // 30 Hz

// A SIMULATED 0.5 deg laser over the half plane ahead, reporting "nothing
// up to range" apart from dropouts.
test::SynthScanSpec half_degree_laser(double sigma) {
  test::SynthScanSpec spec;
  spec.beams = 361;
  spec.angle_step = std::numbers::pi / 360;
  spec.sigma = sigma;
  spec.no_return_valid = true;
  return spec;
}

// A SIMULATED laser (0.5 deg, 1 cm noise) scanning `world` from poses along a
// short line, as a robot creeping forward would: n scans into one map.
LocalMap scan_world(const test::Shapes2D& world, int n, double sigma = 0.01, double step = 0.01) {
  MapParams p;
  LocalMap map;
  test::SynthScanSpec spec = half_degree_laser(sigma);
  for (int k = 0; k < n; ++k) {
    spec.seed = 7 + k;
    const Pose2 T_W_R{step * k, 0.0, 0.0};
    EXPECT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), T_W_R, Pose2{}, k * kScanPeriodNs, spec)), "");
  }
  return map;
}

// Distance from q to the nearest fitted piece.
double to_fitted(const ShapeModel& m, const Vector2d& q) {
  double d = 1e300;
  for (const Segment2& s : m.segments)
    if (s.fitted) d = std::min(d, math::distance_to_segment(s.a, s.b, q));
  return d;
}

// Radii the parameters were not tuned on (the scenes use 0.07-0.30 m): the
// circle is found, its centre and radius match the truth, the unseen back is
// drawn where the true back is, and the raw front and the shadow edges that
// closed the back are gone.
TEST(ShapeCompletion, CircleFittedToTheSeenArcClosesTheUnseenBackAtSeveralRadii) {
  for (double r : {0.09, 0.13, 0.18, 0.27, 0.45}) {
    SCOPED_TRACE(r);
    test::Shapes2D world;
    const Vector2d c(1.5, 0.35);
    world.circles.push_back({c, r});
    const LocalMap map = scan_world(world, 10);
    std::size_t shadows_before = 0;
    for (const Segment2& s : map.segments) shadows_before += s.shadow;
    ASSERT_GT(shadows_before, 0u);
    ShapeModel m;
    complete_shapes(ShapeParams{}, MapParams{}, map, m);
    ASSERT_EQ(m.circles.size(), 1u);
    const FittedCircle& f = m.circles[0];
    EXPECT_LT((f.centre - c).norm(), 0.012);
    EXPECT_NEAR(f.radius, r, 0.008);
    EXPECT_LT(f.rms, 0.008);
    // The near half less the grazing edges the windowing cuts (seen edge-on).
    EXPECT_GT(f.arc, 0.5 * std::numbers::pi);
    // The far side, never seen, is now surface, within the fit's error (the
    // smallest, 7 points at 2 cm spacing, is the least certain: 1.6 cm).
    const Vector2d away = (c - Vector2d(0.05, 0.0)).normalized();
    for (double off : {-0.6, 0.0, 0.6}) {
      const Vector2d dir = Eigen::Rotation2Dd(off) * away;
      EXPECT_LT(to_fitted(m, c + r * dir), 0.02) << "back at " << off << " rad";
    }
    // Nothing of the raw object or its shadow is left.
    for (const Segment2& s : m.segments) {
      if (s.fitted) continue;
      EXPECT_FALSE(s.shadow && std::abs((s.a - c).norm() - r) < 0.03) << "shadow edge of the circle kept";
      EXPECT_GT(std::abs((0.5 * (s.a + s.b) - c).norm() - r), 0.02) << "raw piece of the circle kept";
    }
    EXPECT_GT(m.raw_replaced, 5u);
  }
}

// A straight wall (also a short piece of one, which a big circle could
// explain within the noise) is a line, never a circle; a box corner seen
// from the side is two lines and no circle.
TEST(ShapeCompletion, WallsAndBoxCornersAreLinesNotCircles) {
  {
    test::Shapes2D world;
    world.segs.push_back({{2.0, -3.0}, {2.0, 3.0}});
    world.segs.push_back({{1.2, 0.8}, {1.2, 1.0}});  // a 20 cm board face-on
    ShapeModel m;
    complete_shapes(ShapeParams{}, MapParams{}, scan_world(world, 5), m);
    EXPECT_TRUE(m.circles.empty());
    ASSERT_GE(m.lines.size(), 1u);
    const FittedLine& wall = m.lines[0];
    EXPECT_NEAR(wall.a.x(), 2.0, 0.01);
    EXPECT_NEAR(wall.b.x(), 2.0, 0.01);
    EXPECT_GT(wall.normal.dot(Vector2d(-1, 0)), 0.99);  // toward the sensor
    EXPECT_LT(wall.rms, 0.012);
  }
  {
    test::Shapes2D world;
    // A 0.5 m square box turned 35 deg: two faces seen.
    const Vector2d c(2.0, 0.2);
    const Eigen::Rotation2Dd R(35.0 * std::numbers::pi / 180.0);
    const Vector2d v[4] = {c + R * Vector2d(-0.25, -0.25), c + R * Vector2d(0.25, -0.25),
                           c + R * Vector2d(0.25, 0.25), c + R * Vector2d(-0.25, 0.25)};
    for (int k = 0; k < 4; ++k) world.segs.push_back({v[k], v[(k + 1) % 4]});
    ShapeModel m;
    complete_shapes(ShapeParams{}, MapParams{}, scan_world(world, 5), m);
    EXPECT_TRUE(m.circles.empty());
    EXPECT_GE(m.lines.size(), 2u);
    // Its two seen faces are drawn on their lines, on the true faces.
    int on_faces = 0;
    for (const Segment2& sg : m.segments) {
      if (!sg.fitted) continue;
      ++on_faces;
      EXPECT_LT(world.distance(sg.a), 0.01);
      EXPECT_LT(world.distance(sg.b), 0.01);
    }
    EXPECT_GE(on_faces, 2);
  }
}

// A wall seen with 1 cm noise: raw, its 2 cm segments kink by tens of
// degrees (felt as sideways force); drawn on its fitted line, every piece
// faces the true way. A 1.5 cm board seen from both sides keeps both faces.
TEST(ShapeCompletion, WallsAreDrawnStraightAndAThinBoardKeepsBothFaces) {
  {
    test::Shapes2D world;
    world.segs.push_back({{1.0, -3.0}, {1.0, 3.0}});
    const LocalMap map = scan_world(world, 3);
    // The surface's direction: each piece against the true wall (along y).
    auto kink = [](const Segment2& sg) {
      const Vector2d d = (sg.b - sg.a).normalized();
      return std::acos(std::min(1.0, std::abs(d.y())));
    };
    double raw_worst = 0.0, fit_worst = 0.0, fit_len = 0.0;
    for (const Segment2& sg : map.segments)
      if (!sg.shadow && std::abs(sg.a.y()) < 1.0) raw_worst = std::max(raw_worst, kink(sg));
    ShapeModel m;
    complete_shapes(ShapeParams{}, MapParams{}, map, m);
    for (const Segment2& sg : m.segments) {
      if (!sg.fitted) continue;
      fit_worst = std::max(fit_worst, kink(sg));
      fit_len += (sg.b - sg.a).norm();
      EXPECT_NEAR(sg.a.x(), 1.0, 0.004);
      EXPECT_NEAR(sg.b.x(), 1.0, 0.004);
    }
    std::printf("wall pieces, worst direction error: raw %.1f deg, fitted %.2f deg over %.2f m\n",
                raw_worst * 180 / std::numbers::pi, fit_worst * 180 / std::numbers::pi, fit_len);
    EXPECT_GT(fit_len, 3.0);     // the wall seen within +-60 deg at 1 m: 3.4 m
    EXPECT_GT(raw_worst, 0.3);   // the kinks are there ...
    EXPECT_LT(fit_worst, 0.01);  // ... and gone
  }
  {
    test::Shapes2D world;  // a board 1.5 cm thick along x at y = 0, seen from below and from above
    world.segs = {{{1.0, -0.0075}, {1.6, -0.0075}}, {{1.6, -0.0075}, {1.6, 0.0075}},
                  {{1.6, 0.0075}, {1.0, 0.0075}}, {{1.0, 0.0075}, {1.0, -0.0075}}};
    MapParams mp;
    LocalMap map;
    test::SynthScanSpec spec = half_degree_laser(0.003);
    const Pose2 below{1.3, -0.8, std::numbers::pi / 2}, above{1.3, 0.8, -std::numbers::pi / 2};
    ASSERT_EQ(add_scan(mp, map, test::synth_scan(world.rayfn(), below, Pose2{}, 1, spec)), "");
    ASSERT_EQ(add_scan(mp, map, test::synth_scan(world.rayfn(), above, Pose2{}, 2, spec)), "");
    ShapeModel m;
    complete_shapes(ShapeParams{}, mp, map, m);
    bool faces_down = false, faces_up = false;
    for (const Segment2& sg : m.segments) {
      if (sg.shadow || std::abs(0.5 * (sg.a.y() + sg.b.y())) > 0.02) continue;
      faces_down = faces_down || sg.normal.y() < -0.9;
      faces_up = faces_up || sg.normal.y() > 0.9;
    }
    EXPECT_TRUE(faces_down);
    EXPECT_TRUE(faces_up);
  }
}

// A wall with a run of dropouts (no information) continues through them; the
// same gap seen as free space (a real opening, nothing up to the laser's
// range behind it) stays open.
TEST(ShapeCompletion, AWallContinuesThroughDropoutsButNotThroughAnOpeningSeenFree) {
  MapParams mp;
  test::SynthScanSpec spec = half_degree_laser(0.005);
  auto gap_covered = [](const ShapeModel& m) {
    // Points inside the gap (y in [-0.04, 0.04] on x = 2) on a fitted piece.
    int on = 0;
    for (double y : {-0.03, 0.0, 0.03}) on += to_fitted(m, Vector2d(2.0, y)) < 0.01;
    return on;
  };
  {
    test::Shapes2D world;
    world.segs.push_back({{2.0, -3.0}, {2.0, 3.0}});
    LocalMap map;
    RangeScan2D s = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec);
    for (int i = 178; i <= 183; ++i) s.valid[static_cast<std::size_t>(i)] = 0;  // 6 dropouts, ~10 cm of wall
    ASSERT_EQ(add_scan(mp, map, s), "");
    // Without completion the polyline is broken at the dropouts.
    bool raw_hole = true;
    for (const Segment2& seg : map.segments)
      if (!seg.shadow && math::distance_to_segment(seg.a, seg.b, Vector2d(2.0, 0.0)) < 0.01) raw_hole = false;
    ASSERT_TRUE(raw_hole);
    ShapeModel m;
    complete_shapes(ShapeParams{}, mp, map, m);
    EXPECT_GE(m.bridges, 1u);
    EXPECT_EQ(gap_covered(m), 3);
  }
  {
    test::Shapes2D world;  // the same wall with a real 10 cm opening
    world.segs.push_back({{2.0, -3.0}, {2.0, -0.05}});
    world.segs.push_back({{2.0, 0.05}, {2.0, 3.0}});
    LocalMap map;
    ASSERT_EQ(add_scan(mp, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec)), "");
    ShapeModel m;
    complete_shapes(ShapeParams{}, mp, map, m);
    EXPECT_EQ(gap_covered(m), 0);
  }
}

// Temporal coherence: an accepted circle stays while the object's few
// remaining points still lie on it (a scan chunk lost on the link leaves too
// few to fit), and goes when they do not (the object moved).
TEST(ShapeCompletion, AnAcceptedCircleStaysWhileItsPointsStayOnItAndGoesWhenTheyMove) {
  test::Shapes2D world;
  world.circles.push_back({{1.6, 0.2}, 0.15});
  ShapeModel m;
  complete_shapes(ShapeParams{}, MapParams{}, scan_world(world, 5), m);
  ASSERT_EQ(m.circles.size(), 1u);
  // The same object seen through a narrow gap: 4 points, too few to fit.
  LocalMap sparse = scan_world(world, 1, 0.002);
  std::vector<Segment2> kept_raw;
  for (const Segment2& s : sparse.segments)
    if (!s.shadow && std::abs(0.5 * (s.a.y() + s.b.y()) - 0.2) < 0.03) kept_raw.push_back(s);
  ASSERT_GE(kept_raw.size(), 2u);
  ASSERT_LE(kept_raw.size(), 4u);
  sparse.segments = kept_raw;
  ShapeModel fresh;
  complete_shapes(ShapeParams{}, MapParams{}, sparse, fresh);
  EXPECT_TRUE(fresh.circles.empty());  // alone, the few points do not make a circle ...
  complete_shapes(ShapeParams{}, MapParams{}, sparse, m);
  ASSERT_EQ(m.circles.size(), 1u);     // ... but they keep the one accepted before
  EXPECT_EQ(m.kept, 1u);
  // The object moved 10 cm: its points are off the old circle, which goes.
  for (Segment2& s : sparse.segments) {
    s.a.x() += 0.10;
    s.b.x() += 0.10;
  }
  complete_shapes(ShapeParams{}, MapParams{}, sparse, m);
  EXPECT_TRUE(m.circles.empty());
}

TEST(ShapeCompletion, DisabledOrInvalidParametersLeaveTheMapAsItIs) {
  test::Shapes2D world;
  world.circles.push_back({{1.9, 0.0}, 0.15});
  const LocalMap map = scan_world(world, 3);
  ShapeParams off;
  off.enabled = false;
  ShapeModel m;
  complete_shapes(off, MapParams{}, map, m);
  EXPECT_EQ(m.segments.size(), map.segments.size());
  EXPECT_TRUE(m.circles.empty());
  ShapeParams bad;
  bad.min_radius = 1.0;
  bad.max_radius = 0.5;
  EXPECT_NE(validate(bad), "");
  complete_shapes(bad, MapParams{}, map, m);
  EXPECT_EQ(m.segments.size(), map.segments.size());
  bad = ShapeParams{};
  bad.inlier_distance = std::nan("");
  EXPECT_NE(validate(bad), "");
  EXPECT_EQ(validate(ShapeParams{}), "");
}

// Same map, same model: the fits are repeatable (seeded sample consensus),
// so the rendered outline does not jitter between snapshots of one map.
TEST(ShapeCompletion, RepeatableOnTheSameMap) {
  test::Shapes2D world;
  world.circles.push_back({{1.7, -0.3}, 0.2});
  world.segs.push_back({{2.6, -3.0}, {2.6, 3.0}});
  const LocalMap map = scan_world(world, 6);
  ShapeModel a, b;
  complete_shapes(ShapeParams{}, MapParams{}, map, a);
  complete_shapes(ShapeParams{}, MapParams{}, map, b);
  ASSERT_EQ(a.circles.size(), 1u);
  ASSERT_EQ(b.circles.size(), 1u);
  EXPECT_EQ(a.circles[0].centre, b.circles[0].centre);
  EXPECT_EQ(a.circles[0].radius, b.circles[0].radius);
  EXPECT_EQ(a.segments.size(), b.segments.size());
}

}  // namespace
}  // namespace hemm::mapping
