#include "common/mapping/local_map.h"

#include <algorithm>
#include <cstdio>
#include <numbers>
#include <optional>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "common/math/geometry2.h"
#include "tests/common/mapping/scan_synth.h"

namespace hemm::mapping {
namespace {

using Eigen::Vector2d;
using math::Pose2;

using Shapes = test::Shapes2D;

test::SynthScanSpec laser(double sigma = 0.0, std::uint32_t seed = 1) {
  test::SynthScanSpec s;
  s.sigma = sigma;
  s.seed = seed;
  return s;
}

// Pioneer-like ring of 16 sonars, ascending angles, 15 deg cones.
test::SynthScanSpec sonar_ring(double sigma = 0.0) {
  test::SynthScanSpec s;
  s.kind = SensorKind::kSonar;
  s.beams = 16;
  s.angle_min = -std::numbers::pi + std::numbers::pi / 16;
  s.angle_step = 2 * std::numbers::pi / 16;
  s.range_min = 0.1;
  s.range_max = 5.0;
  s.beam_width = 15.0 * std::numbers::pi / 180.0;
  s.rays_per_cone = 9;
  s.sigma = sigma;
  return s;
}

TEST(LocalMap, WallScanLandsOnTrueWall) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  const double sigma = 0.01;
  MapParams p;
  LocalMap map;
  const RangeScan2D scan = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser(sigma, 3));
  ASSERT_EQ(add_scan(p, map, scan), "");
  // Every beam within +-59 deg hits the wall: one polyline of ~118 segments.
  ASSERT_GT(map.segments.size(), 100u);
  double sum = 0, worst = 0;
  for (const Segment2& s : map.segments) {
    for (const Vector2d& q : {s.a, s.b}) {
      worst = std::max(worst, std::abs(q.x() - 3.0));
      sum += q.x() - 3.0;
    }
    EXPECT_GT(s.normal.dot(Vector2d(-1, 0)), 0.5);  // toward the sensor side
    EXPECT_NEAR(s.normal.norm(), 1.0, 1e-12);
    EXPECT_FALSE(s.interpolated);
  }
  // Error ~ noise: along-beam noise projects onto x by cos(angle) <= 1.
  EXPECT_LT(worst, 5 * sigma);
  EXPECT_LT(std::abs(sum / (2.0 * map.segments.size())), 0.3 * sigma);
}

TEST(LocalMap, BoxAndCylinderOnTrueGeometry) {
  Shapes world;
  // Box 1 m wide at x in [2, 2.6], y in [0.5, 1.5]; cylinder r = 0.3 at (2.5, -1).
  const Vector2d lo(2, 0.5), hi(2.6, 1.5);
  world.segs = {{lo, {hi.x(), lo.y()}}, {{hi.x(), lo.y()}, hi}, {hi, {lo.x(), hi.y()}}, {{lo.x(), hi.y()}, lo}};
  world.circles.push_back({{2.5, -1.0}, 0.3});
  const double sigma = 0.005;
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser(sigma, 5))), "");
  ASSERT_GT(map.segments.size(), 20u);
  for (const Segment2& s : map.segments) {
    EXPECT_LT(world.distance(s.a), 5 * sigma);
    EXPECT_LT(world.distance(s.b), 5 * sigma);
    // The midpoint too: no chord strays from the surface (cylinder sagitta is < 1 mm here).
    EXPECT_LT(world.distance(0.5 * (s.a + s.b)), 5 * sigma + 1e-3);
    // Normal faces the sensor at the origin.
    EXPECT_GT(s.normal.dot(-0.5 * (s.a + s.b)), 0.0);
  }
}

TEST(LocalMap, WindowingNoBridgeBetweenNearObjectAndWall) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  world.circles.push_back({{1.0, 0.0}, 0.15});
  auto bridges = [&](const MapParams& p) {
    LocalMap map;
    EXPECT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser(0.005))), "");
    int n = 0;
    for (const Segment2& s : map.segments) {
      if (s.shadow) {
        // Shadow edges are deliberate: along the grazing beam (radial from
        // the sensor at the origin), from the cylinder's silhouette to at
        // most the wall behind, facing away from the cylinder.
        EXPECT_LT(std::abs(hemm::math::cross2(s.a, s.b - s.a)), 1e-9 * (s.b - s.a).norm() + 1e-12);
        EXPECT_LT(world.distance(s.a), 0.03);
        EXPECT_LT(s.b.x(), 3.0 + 0.03);
        EXPECT_GT(s.normal.dot(s.a - Vector2d(1.0, 0.0)), 0.0);
        continue;
      }
      n += world.distance(0.5 * (s.a + s.b)) > 0.05 ? 1 : 0;
    }
    return n;
  };
  EXPECT_EQ(bridges(MapParams{}), 0);
  // Control: with windowing switched off the same scan does produce false
  // walls between the cylinder's silhouette and the wall behind it.
  MapParams off;
  off.shadow_depth = 0.0;
  off.jump_ratio = 100;
  off.jump_abs = 100;
  off.min_view_angle = 0;
  off.max_segment_length = 100;
  EXPECT_GE(bridges(off), 2);
}

TEST(LocalMap, DropoutsNeverCreateObstacles) {
  MapParams p;
  // An empty world: every beam is a dropout or out of range (hostile ranges: 0, NaN, -1).
  RangeScan2D s = test::synth_scan(Shapes{}.rayfn(), Pose2{}, Pose2{}, 0, laser());
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    s.ranges[i] = i % 3 == 0 ? 0.0f : (i % 3 == 1 ? std::nanf("") : -1.0f);
    s.valid[i] = 0;
  }
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, s), "");
  EXPECT_TRUE(map.segments.empty());
  // valid flag set but range out of [range_min, range_max): still not a return.
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    s.valid[i] = 1;
    s.ranges[i] = i % 2 ? static_cast<float>(s.range_max) : 0.01f;
  }
  ASSERT_EQ(add_scan(p, map, s), "");
  EXPECT_TRUE(map.segments.empty());

  // A wall with 30% dropouts: whatever is built lies on the wall.
  Shapes world;
  world.segs.push_back({{2, -5}, {2, 5}});
  test::SynthScanSpec spec = laser(0.005, 11);
  spec.dropout_probability = 0.3;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec)), "");
  ASSERT_FALSE(map.segments.empty());
  for (const Segment2& seg : map.segments) {
    EXPECT_LT(world.distance(seg.a), 0.03);
    EXPECT_LT(world.distance(seg.b), 0.03);
  }
}

TEST(LocalMap, SingleDropoutBridgedLongerGapsNot) {
  Shapes world;
  world.segs.push_back({{2, -5}, {2, 5}});
  RangeScan2D s = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser());
  s.valid[90] = 0;                 // one isolated dropout straight ahead
  s.valid[100] = s.valid[101] = 0;  // two in a row
  MapParams p;
  p.max_bridged_dropouts = 1;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, s), "");
  auto covered = [&](double y) {
    for (const Segment2& seg : map.segments)
      if (std::min(seg.a.y(), seg.b.y()) <= y && y <= std::max(seg.a.y(), seg.b.y())) return true;
    return false;
  };
  EXPECT_TRUE(covered(0.0));                              // beam 90 bridged
  EXPECT_FALSE(covered(2.0 * std::tan(10.5 * std::numbers::pi / 180)));  // between beams 100 and 101: a hole
}

TEST(LocalMap, SonarInterpolation) {
  Shapes world;
  world.segs.push_back({{1.5, -6}, {1.5, 6}});  // wall ahead, x = 1.5
  MapParams p;
  LocalMap map;
  const test::SynthScanSpec spec = sonar_ring();
  const RangeScan2D s = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec);
  ASSERT_EQ(add_scan(p, map, s), "");
  int arcs = 0, bridges = 0;
  for (const Segment2& seg : map.segments) {
    EXPECT_TRUE(seg.interpolated);
    EXPECT_EQ(seg.kind, SensorKind::kSonar);
    // Conservative: never beyond the wall (nothing is closer inside a cone
    // than the echo), and close to it.
    EXPECT_LE(std::max(seg.a.x(), seg.b.x()), 1.5 + 1e-6);  // ranges are floats
    EXPECT_GT(seg.normal.x(), 0.0 - 1e-12 - 1.0);  // finite
    EXPECT_GT(seg.normal.dot(-0.5 * (seg.a + seg.b)), 0.0);  // faces the robot
    // Arc pieces span beam_width / pieces at one radius; anything else is a bridge.
    const double span = std::acos(std::clamp(seg.a.normalized().dot(seg.b.normalized()), -1.0, 1.0));
    if (std::abs(seg.a.norm() - seg.b.norm()) < 1e-9 && std::abs(span - spec.beam_width / p.sonar_arc_pieces) < 1e-6) {
      ++arcs;
    } else {
      ++bridges;
    }
  }
  // Beams facing the wall: those whose cone sees it within 5 m.
  int returns = 0;
  for (std::size_t i = 0; i < s.ranges.size(); ++i) returns += beam_is_return(s, i) ? 1 : 0;
  EXPECT_EQ(arcs, returns * p.sonar_arc_pieces);
  EXPECT_GE(bridges, 2);  // neighbours at similar range joined
  // The front sonars (axes at +-11.25 deg, cones 3.75 .. 18.75 deg) echo at
  // r = 1.5 / cos(3.75 deg); their arcs then stay within
  // r (1 - cos(18.75 deg)) ~ 8 cm in front of the wall.
  const double r_front = 1.5 / std::cos(3.75 * std::numbers::pi / 180);
  for (const Segment2& seg : map.segments) {
    if (std::abs(seg.a.y()) < 0.45) {
      EXPECT_GT(seg.a.x(), r_front * std::cos(18.75 * std::numbers::pi / 180) - 1e-3);
    }
  }
  // Neighbours whose ranges disagree (a post in front of one sonar) are not bridged.
  world.circles.push_back({{0.6, std::tan(std::numbers::pi / 16) * 0.6}, 0.05});
  LocalMap map2;
  const RangeScan2D s2 = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec);
  ASSERT_EQ(add_scan(p, map2, s2), "");
  for (const Segment2& seg : map2.segments) {
    const double ra = seg.a.norm(), rb = seg.b.norm();
    EXPECT_LT(std::abs(ra - rb), 0.5) << "bridge between the post and the wall";
  }
}

// Where the laser looks, a sonar echo it explains is not drawn (its arc would
// be a false wall in front of the measured surface); echoes from behind the
// laser's field of view, or from an obstacle only the sonar sees (below the
// laser plane), still are; a laser scan too old explains nothing.
TEST(LocalMap, SonarEchoesTheLaserExplainsAreLeftToTheLaser) {
  Shapes laser_world;  // what the laser plane cuts
  laser_world.circles.push_back({{1.9, 0.0}, 0.15});     // a bin ahead
  laser_world.segs.push_back({{-1.5, -6}, {-1.5, 6}});   // a wall behind the robot
  Shapes sonar_world = laser_world;
  sonar_world.circles.push_back({{1.0, 0.3}, 0.04});     // a low post only the sonar sees
  MapParams p;
  const RangeScan2D ls = test::synth_scan(laser_world.rayfn(), Pose2{}, Pose2{}, 0, laser());
  const RangeScan2D ss = test::synth_scan(sonar_world.rayfn(), Pose2{}, Pose2{}, 100'000'000, sonar_ring());

  LocalMap map;
  ASSERT_EQ(add_scan(p, map, ls), "");
  ASSERT_GT(map.laser.returns.size(), 5u);
  const std::size_t n_laser = map.segments.size();
  ASSERT_EQ(add_scan(p, map, ss), "");
  int rear = 0, post = 0;
  for (std::size_t k = n_laser; k < map.segments.size(); ++k) {
    const Segment2& seg = map.segments[k];
    ASSERT_EQ(seg.kind, SensorKind::kSonar);
    const Vector2d mid = 0.5 * (seg.a + seg.b);
    // No arc in front of the bin: the laser measured it.
    EXPECT_GT((mid - Vector2d(1.9, 0.0)).norm(), 0.6) << mid.transpose();
    if (mid.x() < -1.0) ++rear;
    if ((mid - Vector2d(1.0, 0.3)).norm() < 0.3) ++post;
  }
  EXPECT_GE(rear, p.sonar_arc_pieces);  // behind the laser's field of view: drawn
  EXPECT_GE(post, 1);                   // the laser saw past the post: drawn

  // A dense scan travels in chunks (each its own RangeScan2D): the returns of
  // every chunk explain, not just the last chunk's.
  {
    RangeScan2D right = ls, left = ls;
    const std::size_t half_n = ls.ranges.size() / 2;
    right.ranges.resize(half_n);
    right.valid.resize(half_n);
    left.ranges.erase(left.ranges.begin(), left.ranges.begin() + static_cast<std::ptrdiff_t>(half_n));
    left.valid.erase(left.valid.begin(), left.valid.begin() + static_cast<std::ptrdiff_t>(half_n));
    left.angle_min = ls.angle_min + static_cast<double>(half_n) * ls.angle_step;
    LocalMap chunked;
    ASSERT_EQ(add_scan(p, chunked, right), "");
    ASSERT_EQ(add_scan(p, chunked, left), "");
    EXPECT_EQ(chunked.laser.returns.size(), map.laser.returns.size());
    ASSERT_EQ(add_scan(p, chunked, ss), "");
    for (const Segment2& seg : chunked.segments) {
      if (seg.kind == SensorKind::kSonar) {
        EXPECT_GT((0.5 * (seg.a + seg.b) - Vector2d(1.9, 0.0)).norm(), 0.6);
      }
    }
    // Returns older than sonar_laser_max_age_s before the newest laser data go.
    RangeScan2D later = ls;
    later.stamp_ns = 2'000'000'000;
    ASSERT_EQ(add_scan(p, chunked, later), "");
    EXPECT_EQ(chunked.laser.returns.size(), map.laser.returns.size());
  }

  // The same sonar scan 1 s after the laser scan: nothing explained, the
  // front cone's arc is drawn in front of the bin.
  LocalMap stale;
  ASSERT_EQ(add_scan(p, stale, ls), "");
  RangeScan2D late = ss;
  late.stamp_ns = 1'000'000'000;
  ASSERT_EQ(add_scan(p, stale, late), "");
  int front = 0;
  for (const Segment2& seg : stale.segments)
    if (seg.kind == SensorKind::kSonar && (0.5 * (seg.a + seg.b) - Vector2d(1.9, 0.0)).norm() < 0.6) ++front;
  EXPECT_GE(front, p.sonar_arc_pieces);
}

TEST(LocalMap, SlidingWindowDropsOldAndFar) {
  Shapes world;
  world.segs.push_back({{2, -3}, {2, 3}});
  MapParams p;
  p.window_age_s = 3.0;
  p.window_radius = 4.0;
  // The window alone (ray clearing would leave only the newest of these
  // identical scans; see the RayClearing tests).
  p.clear_reobserved = false;
  LocalMap map;
  // One scan per second, t = 0 .. 5 s, robot stationary at the origin.
  std::vector<std::size_t> per_scan;
  for (int t = 0; t <= 5; ++t) {
    const std::size_t before = map.segments.size();
    ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, t * 1'000'000'000LL, laser())), "");
    per_scan.push_back(map.segments.size() - before);
  }
  slide_window(p, map, 5'000'000'000LL, Vector2d::Zero());
  std::size_t expect = 0;
  for (int t = 2; t <= 5; ++t) expect += per_scan[static_cast<std::size_t>(t)];
  EXPECT_EQ(map.segments.size(), expect);
  for (const Segment2& s : map.segments) EXPECT_GE(s.stamp_ns, 2'000'000'000LL);
  // Far: the robot drove 6 m away; the wall is now out of reach.
  slide_window(p, map, 5'000'000'000LL, Vector2d(2, 6.5 + 4.0));
  for (const Segment2& s : map.segments) EXPECT_LE(math::distance_to_segment(s.a, s.b, {2, 10.5}), 4.0);
  slide_window(p, map, 5'000'000'000LL, Vector2d(-10, 0));
  EXPECT_TRUE(map.segments.empty());
  // Size bound: the newest are kept.
  p.max_segments = 50;
  for (int t = 0; t < 3; ++t)
    ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, t, laser())), "");
  slide_window(p, map, 2, Vector2d::Zero());
  ASSERT_EQ(map.segments.size(), 50u);
  for (const Segment2& s : map.segments) EXPECT_EQ(s.stamp_ns, 2);
}

TEST(LocalMap, StampedPosePlacesScanAfterRobotMoved) {
  Shapes world;
  world.segs.push_back({{4, -5}, {4, 5}});
  world.circles.push_back({{3.0, 2.0}, 0.3});
  // Scan taken at pose A with an offset, yawed sensor mount; by the time it
  // arrives the robot is at pose B. Placing by the stamped pose A must put it
  // on the true geometry.
  const Pose2 A{0.5, -0.4, 0.3}, B{1.5, 0.6, -0.6};
  const Pose2 T_R_S{0.18, 0.05, 0.1};
  RangeScan2D s = test::synth_scan(world.rayfn(), A, T_R_S, 0, laser(0.003));
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, s), "");
  ASSERT_GT(map.segments.size(), 50u);
  for (const Segment2& seg : map.segments) EXPECT_LT(world.distance(seg.a), 0.02);
  // Control: the same ranges placed with the current pose B are wrong.
  s.T_W_R = B;
  LocalMap wrong;
  ASSERT_EQ(add_scan(p, wrong, s), "");
  int off = 0;
  for (const Segment2& seg : wrong.segments) off += world.distance(seg.a) > 0.1 ? 1 : 0;
  EXPECT_GT(off, static_cast<int>(wrong.segments.size()) / 2);
}

TEST(LocalMap, HostileScansRejectedMapUnchanged) {
  Shapes world;
  world.segs.push_back({{2, -5}, {2, 5}});
  MapParams p;
  LocalMap map;
  const RangeScan2D good = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser());
  ASSERT_EQ(add_scan(p, map, good), "");
  const std::size_t n = map.segments.size();
  std::vector<RangeScan2D> bad(8, good);
  bad[0].T_W_R.x = std::nan("");
  bad[1].valid.pop_back();
  bad[2].angle_step = -0.01;
  bad[3].range_max = bad[3].range_min;
  bad[4].beam_angles.assign(good.ranges.size(), 0.0f);  // not ascending
  bad[5].kind = SensorKind::kSonar;                      // sonar without a cone
  bad[6].angle_step = 0.1;                               // 181 beams * 0.1 rad > one turn
  bad[7].T_R_S.theta = std::numeric_limits<double>::infinity();
  for (const RangeScan2D& b : bad) {
    EXPECT_NE(add_scan(p, map, b), "");
    EXPECT_EQ(map.segments.size(), n);
  }
  MapParams bad_p;
  bad_p.cell_size = 0;
  EXPECT_NE(add_scan(bad_p, map, good), "");
  EXPECT_EQ(map.segments.size(), n);
}

TEST(LocalMap, DenseScanDownSampledStaysOnWall) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  test::SynthScanSpec spec = laser(0.002);
  spec.beams = 10000;
  spec.angle_step = std::numbers::pi / 9999;
  MapParams p;
  p.min_point_spacing = 0.05;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec)), "");
  // The wall seen within +-59 deg spans ~10 m: about 10 / 0.05 pieces, not ~6500.
  EXPECT_LT(map.segments.size(), 260u);
  EXPECT_GT(map.segments.size(), 150u);
  for (const Segment2& seg : map.segments) EXPECT_LT(world.distance(seg.a), 0.01);
}

TEST(LocalMap, NormalsOnDenseNoisyScanFromPolylineFit) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  test::SynthScanSpec spec = laser(0.01, 9);
  spec.beams = 2000;
  spec.angle_step = std::numbers::pi / 1999;
  auto mean_error_deg = [&](double window) {
    MapParams p;
    p.normal_window = window;
    LocalMap map;
    EXPECT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, spec)), "");
    double err = 0;
    for (const Segment2& s : map.segments) err += std::acos(std::min(1.0, -s.normal.x()));
    return err / static_cast<double>(map.segments.size()) * 180.0 / std::numbers::pi;
  };
  const double fitted = mean_error_deg(0.2), raw = mean_error_deg(0.0);
  std::printf("wall normals, sigma 1 cm, 2000 beams: PCA window 0.2 m %.2f deg, per-segment %.2f deg\n", fitted, raw);
  EXPECT_LT(fitted, 5.0);
  EXPECT_GT(raw, 2.0 * fitted);  // the fit is what makes them usable
}

TEST(LocalMap, SnapshotQueryMatchesBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-8, 8), len(0.0, 1.5), ang(-std::numbers::pi, std::numbers::pi);
  LocalMap map;
  for (int i = 0; i < 3000; ++i) {
    Segment2 s;
    s.a = {u(rng), u(rng)};
    const double a = ang(rng), l = len(rng);
    s.b = s.a + l * Vector2d(std::cos(a), std::sin(a));
    map.segments.push_back(s);
  }
  MapParams p;
  p.cell_size = 0.3;
  const MapSnapshot snap = build_snapshot(p, map);
  ASSERT_GE(snap.segments.size(), map.segments.size());
  for (const Segment2& s : snap.segments) EXPECT_LE((s.b - s.a).norm(), p.cell_size + 1e-12);
  std::vector<std::uint32_t> out(snap.segments.size());
  for (int q = 0; q < 300; ++q) {
    const Vector2d c(u(rng) * 1.3, u(rng) * 1.3);  // some queries off the grid
    const double r = std::abs(u(rng)) * 0.25;
    const std::size_t n = query_segments(snap, c, r, out.data(), out.size());
    std::set<std::uint32_t> got(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n)), want;
    for (std::uint32_t i = 0; i < snap.segments.size(); ++i)
      if (math::distance_to_segment(snap.segments[i].a, snap.segments[i].b, c) <= r) want.insert(i);
    EXPECT_EQ(got.size(), n);  // no duplicates
    EXPECT_EQ(got, want);
    // Truncation reports the full count.
    if (n > 2) {
      EXPECT_EQ(query_segments(snap, c, r, out.data(), 2), std::min<std::size_t>(n, 3));  // stops at cap + 1
    }
  }
  EXPECT_EQ(query_segments(snap, {1e6, 1e6}, 1.0, out.data(), out.size()), 0u);
  EXPECT_EQ(query_segments(snap, {std::nan(""), 0}, 1.0, out.data(), out.size()), 0u);
  EXPECT_EQ(query_segments(MapSnapshot{}, {0, 0}, 1.0, out.data(), out.size()), 0u);
}


// ---- Ray clearing: the newest scan supersedes what it re-observes ----------

constexpr std::int64_t kScanPeriodNs = 33'333'333;  // 30 Hz

// Closed box (axis-aligned) as four thin segments.
void add_box(Shapes& w, const Vector2d& lo, const Vector2d& hi) {
  w.segs.push_back({lo, {hi.x(), lo.y()}});
  w.segs.push_back({{hi.x(), lo.y()}, hi});
  w.segs.push_back({hi, {lo.x(), hi.y()}});
  w.segs.push_back({{lo.x(), hi.y()}, lo});
}

std::size_t count_stamp(const LocalMap& m, std::int64_t stamp) {
  return static_cast<std::size_t>(
      std::count_if(m.segments.begin(), m.segments.end(), [&](const Segment2& s) { return s.stamp_ns == stamp; }));
}

TEST(RayClearing, StaticWallScanned50TimesHoldsOneScan) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  MapParams p;
  LocalMap map;
  std::size_t last = 0;
  std::int64_t t = 0;
  for (int k = 0; k < 50; ++k) {
    t = k * kScanPeriodNs;
    const std::size_t before = map.segments.size();
    const RangeScan2D s = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, t, laser(0.01, 100u + static_cast<std::uint32_t>(k)));
    const std::size_t n = [&] { std::vector<Segment2> tmp; extract_segments(p, s, tmp); return tmp.size(); }();
    ASSERT_EQ(add_scan(p, map, s), "");
    last = n;
    ASSERT_LE(map.segments.size(), before + n);
  }
  ASSERT_GT(last, 100u);
  // Every segment is the newest scan's: one copy of the wall, not 50.
  EXPECT_EQ(map.segments.size(), last);
  EXPECT_EQ(count_stamp(map, t), last);
  // Control: without clearing the map holds every scan.
  MapParams off = p;
  off.clear_reobserved = false;
  LocalMap all;
  for (int k = 0; k < 50; ++k)
    ASSERT_EQ(add_scan(off, all, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, k * kScanPeriodNs,
                                                  laser(0.01, 100u + static_cast<std::uint32_t>(k)))), "");
  EXPECT_GT(all.segments.size(), 45 * last);
  // A late (reordered) scan older than the map's segments clears nothing.
  const std::size_t n = map.segments.size();
  EXPECT_EQ(clear_reobserved_segments(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, t - 1, laser())), 0u);
  EXPECT_EQ(map.segments.size(), n);
}

TEST(RayClearing, RemovedPostVanishesWallBehindIsDrawn) {
  Shapes with, without;
  without.segs.push_back({{3, -5}, {3, 5}});
  with = without;
  const Vector2d post(1.5, 0.2);
  with.circles.push_back({post, 0.1});
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(with.rayfn(), Pose2{}, Pose2{}, 0, laser(0.005, 1))), "");
  auto near_post = [&] {
    int n = 0;
    for (const Segment2& s : map.segments) n += math::distance_to_segment(s.a, s.b, post) < 0.3 ? 1 : 0;
    return n;
  };
  ASSERT_GT(near_post(), 3);
  // The post is taken away; the next scan from a slightly moved robot.
  ASSERT_EQ(add_scan(p, map, test::synth_scan(without.rayfn(), Pose2{0.05, 0.02, 0.03}, Pose2{}, kScanPeriodNs,
                                              laser(0.005, 2))), "");
  EXPECT_EQ(near_post(), 0);
  // The wall behind where the post stood (its shadow was y in ~[0.12, 0.7]) is drawn.
  for (double y = 0.1; y <= 0.7; y += 0.05) {
    bool covered = false;
    for (const Segment2& s : map.segments)
      covered = covered || (std::abs(s.a.x() - 3.0) < 0.03 && std::min(s.a.y(), s.b.y()) <= y && y <= std::max(s.a.y(), s.b.y()));
    EXPECT_TRUE(covered) << y;
  }
  for (const Segment2& s : map.segments) EXPECT_LT(without.distance(s.a), 0.03);
}

TEST(RayClearing, OccludedSurfaceIsKept) {
  Shapes wall, boxed;
  wall.segs.push_back({{3, -5}, {3, 5}});
  boxed = wall;
  add_box(boxed, {1.5, -0.3}, {1.7, 0.3});  // now a box stands in front: shadow |y| < 0.6 on the wall
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(wall.rayfn(), Pose2{}, Pose2{}, 0, laser(0.005, 1))), "");
  ASSERT_EQ(add_scan(p, map, test::synth_scan(boxed.rayfn(), Pose2{}, Pose2{}, kScanPeriodNs, laser(0.005, 2))), "");
  int hidden = 0, visible = 0;
  for (const Segment2& s : map.segments) {
    if (s.stamp_ns != 0) continue;
    const double y0 = std::min(s.a.y(), s.b.y()), y1 = std::max(s.a.y(), s.b.y());
    if (y1 < 0.5 && y0 > -0.5) ++hidden;
    if (y0 > 0.75 || y1 < -0.75) ++visible;
  }
  // Every old wall segment in the shadow (beams 1 deg apart: ~17 at 3 m over 1 m) is kept...
  EXPECT_GE(hidden, 15);
  int old_in_shadow = 0;
  {
    LocalMap only_old;
    ASSERT_EQ(add_scan(p, only_old, test::synth_scan(wall.rayfn(), Pose2{}, Pose2{}, 0, laser(0.005, 1))), "");
    for (const Segment2& s : only_old.segments)
      old_in_shadow += std::max(s.a.y(), s.b.y()) < 0.5 && std::min(s.a.y(), s.b.y()) > -0.5 ? 1 : 0;
  }
  EXPECT_EQ(hidden, old_in_shadow);
  // ... and every old one in view is superseded.
  EXPECT_EQ(visible, 0);
}

TEST(RayClearing, OutOfViewIsKeptUntilTheWindowDropsIt) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  world.segs.push_back({{-3, -5}, {-3, 5}});
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser(0.005, 1))), "");
  const std::size_t front = map.segments.size();
  // The robot turns round: the 180 deg scan now sees only the wall at x = -3.
  for (int k = 1; k <= 10; ++k)
    ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{0, 0, std::numbers::pi}, Pose2{}, k * kScanPeriodNs,
                                                laser(0.005, 1u + static_cast<std::uint32_t>(k)))), "");
  EXPECT_EQ(count_stamp(map, 0), front);
  for (const Segment2& s : map.segments) {
    if (s.stamp_ns == 0) {
      EXPECT_GT(s.a.x(), 2.9);
    } else {
      EXPECT_EQ(s.stamp_ns, 10 * kScanPeriodNs);  // the turned view: one copy
    }
  }
  slide_window(p, map, static_cast<std::int64_t>(p.window_age_s * 1e9) + 1, Vector2d::Zero());
  EXPECT_EQ(count_stamp(map, 0), 0u);
}

// A box edge at bearing 11.7 deg with the wall behind. The old scan (0.2 deg
// beams) reaches closer to the edge than the new one (1 deg beams: the beam at
// 12 deg slipped past the edge): old box points whose nearest new beam is a
// wall beam are in doubt and kept, so the edge is not eroded; old box points
// whose nearest new beam is on the box go.
TEST(RayClearing, SilhouetteEdgeNotClearedByBeamPastIt) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  const double w = 1.5 * std::tan(11.7 * std::numbers::pi / 180);
  add_box(world, {1.5, -w}, {1.7, w});
  test::SynthScanSpec fine = laser();
  fine.beams = 901;
  fine.angle_step = std::numbers::pi / 900;
  MapParams p;
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, fine)), "");
  const std::vector<Segment2> old = map.segments;
  const RangeScan2D coarse = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, kScanPeriodNs, laser());
  ASSERT_EQ(add_scan(p, map, coarse), "");
  auto on_box = [](const Segment2& s) { return s.a.x() < 2.0 && s.b.x() < 2.0; };
  // Closed form: nearest coarse beam of a point (sensor at the origin, beams at whole degrees).
  auto wall_beam_nearest = [&](const Vector2d& q) {
    const long k = std::lround((std::atan2(q.y(), q.x()) - coarse.angle_min) / coarse.angle_step);
    return coarse.ranges[static_cast<std::size_t>(k)] > 2.0f;
  };
  int kept = 0, cleared = 0;
  double old_edge = 0.0;
  for (const Segment2& s : old) {
    if (!on_box(s)) continue;
    old_edge = std::max({old_edge, std::abs(s.a.y()), std::abs(s.b.y())});
    const bool doubt = wall_beam_nearest(s.a) || wall_beam_nearest(s.b) || wall_beam_nearest(0.5 * (s.a + s.b));
    const bool still = std::any_of(map.segments.begin(), map.segments.end(), [&](const Segment2& m) {
      return m.stamp_ns == 0 && m.a == s.a && m.b == s.b;
    });
    EXPECT_EQ(still, doubt) << s.a.transpose() << " -> " << s.b.transpose();
    kept += still ? 1 : 0;
    cleared += still ? 0 : 1;
  }
  EXPECT_GE(kept, 2);      // both edges
  EXPECT_GE(cleared, 20);  // the face between (down-sampled to 2 cm)
  double edge = 0.0;
  for (const Segment2& s : map.segments)
    if (on_box(s)) edge = std::max({edge, std::abs(s.a.y()), std::abs(s.b.y())});
  EXPECT_DOUBLE_EQ(edge, old_edge);
  EXPECT_GT(old_edge, 1.5 * std::tan(11.5 * std::numbers::pi / 180));  // past the last coarse box beam's cell
}

// Both endpoints AND the midpoint must be seen through: a long chord (bridged
// dropouts, down-sampling) can pass behind a new object with both ends in view.
TEST(RayClearing, ChordBehindNewObjectIsKept) {
  Shapes wall, posted;
  wall.segs.push_back({{3, -5}, {3, 5}});
  posted = wall;
  posted.circles.push_back({{1.5, 0.0}, 0.1});
  MapParams p;
  for (bool with_post : {true, false}) {
    LocalMap map;
    Segment2 chord;
    chord.a = {3.0, -0.5};
    chord.b = {3.0, 0.5};
    chord.normal = {-1, 0};
    map.segments.push_back(chord);
    const Shapes& w = with_post ? posted : wall;
    ASSERT_EQ(add_scan(p, map, test::synth_scan(w.rayfn(), Pose2{}, Pose2{}, 1, laser())), "");
    const auto it = std::find_if(map.segments.begin(), map.segments.end(), [](const Segment2& s) { return s.stamp_ns == 0; });
    if (with_post) {
      ASSERT_NE(it, map.segments.end());
      EXPECT_EQ(it->reobserved, 1u | 4u);  // both ends seen, the middle hidden
    } else {
      EXPECT_EQ(it, map.segments.end());
    }
  }
}

// A scan split into chunks clears exactly what the whole scan clears,
// including old segments that straddle the chunk seam (marks add up).
TEST(RayClearing, ChunksClearLikeTheWholeScan) {
  Shapes world;
  world.segs.push_back({{3, -5}, {3, 5}});
  world.circles.push_back({{1.8, 1.0}, 0.15});
  add_box(world, {2.0, -1.6}, {2.3, -1.0});
  MapParams p;
  const RangeScan2D old_scan = test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser(0.01, 1));
  const RangeScan2D whole =
      test::synth_scan(world.rayfn(), Pose2{0.1, 0.05, 0.02}, Pose2{0.18, 0, 0}, kScanPeriodNs, laser(0.01, 2));
  const std::size_t cut = 95;
  RangeScan2D right = whole, left = whole;
  right.ranges.resize(cut);
  right.valid.resize(cut);
  left.ranges.erase(left.ranges.begin(), left.ranges.begin() + static_cast<std::ptrdiff_t>(cut));
  left.valid.erase(left.valid.begin(), left.valid.begin() + static_cast<std::ptrdiff_t>(cut));
  left.angle_min = whole.angle_min + static_cast<double>(cut) * whole.angle_step;

  LocalMap a, b;
  ASSERT_EQ(add_scan(p, a, old_scan), "");
  ASSERT_EQ(add_scan(p, b, old_scan), "");
  const std::size_t n_old = a.segments.size();
  ASSERT_EQ(add_scan(p, a, whole), "");
  ASSERT_EQ(add_scan(p, b, right), "");
  ASSERT_EQ(add_scan(p, b, left), "");
  std::vector<std::pair<Vector2d, Vector2d>> kept_a, kept_b;
  for (const Segment2& s : a.segments) if (s.stamp_ns == 0) kept_a.push_back({s.a, s.b});
  for (const Segment2& s : b.segments) if (s.stamp_ns == 0) kept_b.push_back({s.a, s.b});
  EXPECT_EQ(kept_a, kept_b);
  EXPECT_LT(kept_a.size(), n_old / 4);  // most of the old scan was superseded
  // Old segments straddling the seam's bearing (in the new sensor frame) were cleared.
  const math::Pose2 T_S_W = math::inverse(math::compose(whole.T_W_R, whole.T_R_S));
  const double seam = left.angle_min - 0.5 * whole.angle_step;
  int straddling = 0;
  LocalMap o;
  ASSERT_EQ(add_scan(p, o, old_scan), "");
  for (const Segment2& s : o.segments) {
    const Vector2d qa = math::apply(T_S_W, s.a), qb = math::apply(T_S_W, s.b);
    const double ba = std::atan2(qa.y(), qa.x()), bb = std::atan2(qb.y(), qb.x());
    if ((ba - seam) * (bb - seam) < 0.0) {
      ++straddling;
      EXPECT_EQ(std::count(kept_b.begin(), kept_b.end(), std::make_pair(s.a, s.b)), 0);
    }
  }
  EXPECT_GE(straddling, 1);
}

TEST(RayClearing, SonarClearsSonarOnlyAndLaserClearsLaserOnly) {
  Shapes with, without;
  without.segs.push_back({{1.5, -6}, {1.5, 6}});
  with = without;
  const Vector2d post(0.8, 0.3);
  with.circles.push_back({post, 0.05});
  MapParams p;
  p.sonar_laser_max_age_s = 0.0;  // draw every echo: this test is about clearing alone
  LocalMap map;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(with.rayfn(), Pose2{}, Pose2{}, 0, sonar_ring())), "");
  auto near_post = [&] {
    int n = 0;
    for (const Segment2& s : map.segments) n += math::distance_to_segment(s.a, s.b, post) < 0.15 ? 1 : 0;
    return n;
  };
  ASSERT_GE(near_post(), 1);
  const std::size_t first = map.segments.size();
  // The post is gone; the next ring from the same spot: one copy of the wall, no post.
  const std::int64_t t1 = 100'000'000;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(without.rayfn(), Pose2{}, Pose2{}, t1, sonar_ring())), "");
  EXPECT_EQ(near_post(), 0);
  EXPECT_EQ(count_stamp(map, t1), map.segments.size());
  EXPECT_GT(map.segments.size(), first / 2);
  // Out-of-range echoes (the cones facing away from the wall) say nothing: arcs of the
  // first ring there would be kept. Here every drawn arc faced the wall and is replaced.
  // A laser scan (newer, same spot) clears no sonar segment...
  const std::size_t sonar_n = map.segments.size();
  const std::int64_t t2 = 200'000'000;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(without.rayfn(), Pose2{}, Pose2{}, t2, laser())), "");
  EXPECT_EQ(count_stamp(map, t1), sonar_n);
  const std::size_t laser_n = count_stamp(map, t2);
  ASSERT_GT(laser_n, 50u);
  // ... and a newer sonar ring clears no laser segment (only the older sonar).
  const std::int64_t t3 = 300'000'000;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(without.rayfn(), Pose2{}, Pose2{}, t3, sonar_ring())), "");
  EXPECT_EQ(count_stamp(map, t2), laser_n);
  EXPECT_EQ(count_stamp(map, t1), 0u);
  for (const Segment2& s : map.segments) EXPECT_EQ(s.kind == SensorKind::kLaser, s.stamp_ns == t2);
  // The robot moves and turns a little between rings (arcs shift inside their
  // cones): the front arcs, facing the wall, are replaced. (Cones at an oblique
  // wall echo from their near edge, so their range jumps as the robot turns: an
  // old arc found behind the new echo is not seen through and is kept until it
  // ages out.)
  const std::int64_t t4 = 400'000'000;
  ASSERT_EQ(add_scan(p, map, test::synth_scan(without.rayfn(), Pose2{0.02, 0.0, 0.03}, Pose2{}, t4, sonar_ring())), "");
  int front_old = 0;
  for (const Segment2& s : map.segments) {
    const Vector2d m = 0.5 * (s.a + s.b);
    front_old += s.stamp_ns == t3 && std::abs(std::atan2(m.y(), m.x())) < 30.0 * std::numbers::pi / 180 ? 1 : 0;
  }
  EXPECT_EQ(front_old, 0);
  EXPECT_LT(count_stamp(map, t3), count_stamp(map, t4));
}

TEST(RayClearing, BadParamsRejected) {
  EXPECT_EQ(validate(MapParams{}), "");
  for (double bad : {-0.01, std::nan(""), std::numeric_limits<double>::infinity(), 1.5}) {
    MapParams p;
    p.clear_tolerance = bad;
    EXPECT_NE(validate(p), "") << bad;
    LocalMap map;
    Shapes world;
    world.segs.push_back({{2, -5}, {2, 5}});
    EXPECT_NE(add_scan(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser())), "");
    EXPECT_TRUE(map.segments.empty());
    EXPECT_EQ(clear_reobserved_segments(p, map, test::synth_scan(world.rayfn(), Pose2{}, Pose2{}, 0, laser())), 0u);
  }
}

}  // namespace
}  // namespace hemm::mapping
