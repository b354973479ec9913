// The map's down-sampling and neighbour search done with PCL, next to the
// purpose-built versions (polyline spacing, midpoint grid), on the same
// SIMULATED 10k-point room scan. PCL stays in this TU only.
#include <benchmark/benchmark.h>
#include <numbers>

#include <algorithm>
#include <cmath>
#include <random>

#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "common/haptics/proxy/reference_scene.h"
#include "common/mapping/local_map.h"

namespace {

using Eigen::Vector2d;
using namespace hemm;

std::vector<Vector2d> room_points(int n) {
  haptics::ExactScene world;
  haptics::add_box(world, {-4, -3}, {5, 3});
  haptics::add_box(world, {1.5, 0.5}, {2.2, 1.4});
  world.circles.push_back({{2.5, -1.0}, 0.25});
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Vector2d> pts;
  for (int i = 0; i < n; ++i) {
    const double a = -std::numbers::pi + 2 * std::numbers::pi * i / n;
    const Vector2d u(std::cos(a), std::sin(a));
    if (auto r = haptics::raycast(world, {0.1, 0}, u, 10.0)) pts.push_back(Vector2d(0.1, 0) + (*r + noise(rng)) * u);
  }
  return pts;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr to_cloud(const std::vector<Vector2d>& pts) {
  auto c = pcl::PointCloud<pcl::PointXYZ>::Ptr(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : pts) c->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), 0.0f));
  return c;
}

void BM_PclVoxelGrid5cm(benchmark::State& state) {
  const auto cloud = to_cloud(room_points(static_cast<int>(state.range(0))));
  pcl::VoxelGrid<pcl::PointXYZ> vg;
  vg.setLeafSize(0.05f, 0.05f, 0.05f);
  std::size_t out_n = 0;
  for (auto _ : state) {
    pcl::PointCloud<pcl::PointXYZ> out;
    vg.setInputCloud(cloud);
    vg.filter(out);
    out_n = out.size();
    benchmark::DoNotOptimize(out.points.data());
  }
  state.counters["points_out"] = static_cast<double>(out_n);
}
BENCHMARK(BM_PclVoxelGrid5cm)->Arg(10000)->Unit(benchmark::kMicrosecond);

void BM_PclKdTreeRadius(benchmark::State& state) {
  // k-d tree over segment midpoints of the built map; radius 0.2 m + half a piece.
  const auto pts = room_points(static_cast<int>(state.range(0)));
  mapping::LocalMap lm;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    mapping::Segment2 seg;
    seg.a = pts[i - 1];
    seg.b = pts[i];
    lm.segments.push_back(seg);
  }
  const mapping::MapSnapshot snap = mapping::build_snapshot(mapping::MapParams{}, lm);
  auto mids = pcl::PointCloud<pcl::PointXYZ>::Ptr(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& seg : snap.segments) {
    const Vector2d m = 0.5 * (seg.a + seg.b);
    mids->push_back(pcl::PointXYZ(static_cast<float>(m.x()), static_cast<float>(m.y()), 0.0f));
  }
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(mids);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-4, 5), uy(-3, 3);
  std::vector<pcl::PointXYZ> q(1024);
  for (auto& v : q) v = pcl::PointXYZ(static_cast<float>(ux(rng)), static_cast<float>(uy(rng)), 0.0f);
  std::vector<int> idx;
  std::vector<float> d2;
  std::size_t k = 0;
  for (auto _ : state) {
    tree.radiusSearch(q[k++ & 1023], 0.2 + snap.max_half_length, idx, d2);
    benchmark::DoNotOptimize(idx.data());
  }
}
BENCHMARK(BM_PclKdTreeRadius)->Arg(10000)->Unit(benchmark::kNanosecond);

void BM_GridQuery(benchmark::State& state) {
  const auto pts = room_points(static_cast<int>(state.range(0)));
  mapping::LocalMap lm;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    mapping::Segment2 seg;
    seg.a = pts[i - 1];
    seg.b = pts[i];
    lm.segments.push_back(seg);
  }
  const mapping::MapSnapshot snap = mapping::build_snapshot(mapping::MapParams{}, lm);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-4, 5), uy(-3, 3);
  std::vector<Vector2d> q(1024);
  for (auto& v : q) v = Vector2d(ux(rng), uy(rng));
  std::uint32_t out[4096];
  std::size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(mapping::query_segments(snap, q[k++ & 1023], 0.2, out, 4096));
  }
}
BENCHMARK(BM_GridQuery)->Arg(10000)->Unit(benchmark::kNanosecond);

// Normals: PCL's PCA normal estimation on the scan points (extruded to three
// z layers, so the plane fit is well posed) against the polyline segment
// normals, both scored against the exact normals of a rectangular room
// (axis-aligned walls). Reports time and mean angular error side by side.
struct RoomScan {
  std::vector<Vector2d> pts;
  std::vector<Vector2d> truth;  // exact inward normal per point
};
RoomScan room_only(int n) {
  haptics::ExactScene world;
  const Vector2d lo(-4, -3), hi(5, 3);
  haptics::add_box(world, lo, hi);
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.01);
  RoomScan r;
  for (int i = 0; i < n; ++i) {
    const double a = -std::numbers::pi + 2 * std::numbers::pi * i / n;
    const Vector2d u(std::cos(a), std::sin(a));
    const auto d = haptics::raycast(world, {0.1, 0}, u, 20.0);
    if (!d) continue;
    const Vector2d p = Vector2d(0.1, 0) + *d * u;
    // Nearest wall decides the exact normal.
    const double dl = p.x() - lo.x(), dr = hi.x() - p.x(), db = p.y() - lo.y(), dt = hi.y() - p.y();
    const double m = std::min({dl, dr, db, dt});
    r.truth.push_back(m == dl ? Vector2d(1, 0) : m == dr ? Vector2d(-1, 0) : m == db ? Vector2d(0, 1) : Vector2d(0, -1));
    r.pts.push_back(Vector2d(0.1, 0) + (*d + noise(rng)) * u);
  }
  return r;
}
double angle_between(const Vector2d& a, const Vector2d& b) {
  return std::acos(std::clamp(std::abs(a.normalized().dot(b.normalized())), 0.0, 1.0));
}

void BM_PclNormalEstimation(benchmark::State& state) {
  const RoomScan r = room_only(static_cast<int>(state.range(0)));
  auto cloud = pcl::PointCloud<pcl::PointXYZ>::Ptr(new pcl::PointCloud<pcl::PointXYZ>);
  for (const double z : {-0.05, 0.0, 0.05})
    for (const auto& p : r.pts) cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(z)));
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  auto tree = pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>);
  ne.setSearchMethod(tree);
  ne.setRadiusSearch(0.15);
  pcl::PointCloud<pcl::Normal> normals;
  for (auto _ : state) {
    ne.setInputCloud(cloud);
    ne.compute(normals);
    benchmark::DoNotOptimize(normals.points.data());
  }
  double err = 0.0;
  std::size_t cnt = 0;
  for (std::size_t i = 0; i < r.pts.size(); ++i) {  // the z = -0.05 layer is the first block... use the middle one
    const pcl::Normal& nn = normals[r.pts.size() + i];
    if (!std::isfinite(nn.normal_x)) continue;
    err += angle_between(Vector2d(nn.normal_x, nn.normal_y), r.truth[i]);
    ++cnt;
  }
  state.counters["mean_err_deg"] = cnt ? err / static_cast<double>(cnt) * 180.0 / std::numbers::pi : -1.0;
}
BENCHMARK(BM_PclNormalEstimation)->Arg(181)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);

void BM_SegmentNormals(benchmark::State& state) {
  const RoomScan r = room_only(static_cast<int>(state.range(0)));
  // The same points as a scan (ranges from the sensor at (0.1, 0)).
  mapping::RangeScan2D s;
  s.T_W_R = {0.1, 0.0, 0.0};
  s.angle_min = -std::numbers::pi;
  s.angle_step = 2 * std::numbers::pi / static_cast<double>(state.range(0));
  s.range_min = 0.05;
  s.range_max = 20.0;
  for (const auto& p : r.pts) {
    s.ranges.push_back(static_cast<float>((p - Vector2d(0.1, 0)).norm()));
    s.valid.push_back(1);
  }
  std::vector<mapping::Segment2> segs;
  for (auto _ : state) {
    segs.clear();
    mapping::extract_segments(mapping::MapParams{}, s, segs);
    benchmark::DoNotOptimize(segs.data());
  }
  // Score each point by the mean of its (up to two) adjacent segment normals.
  double err = 0.0;
  std::size_t cnt = 0;
  for (const auto& seg : segs) {
    const Vector2d mid = 0.5 * (seg.a + seg.b);
    std::size_t best = 0;
    double bd = 1e300;
    for (std::size_t i = 0; i < r.pts.size(); ++i) {
      const double d = (r.pts[i] - mid).squaredNorm();
      if (d < bd) bd = d, best = i;
    }
    err += angle_between(seg.normal, r.truth[best]);
    ++cnt;
  }
  state.counters["mean_err_deg"] = cnt ? err / static_cast<double>(cnt) * 180.0 / std::numbers::pi : -1.0;
  state.counters["segments"] = static_cast<double>(segs.size());
}
BENCHMARK(BM_SegmentNormals)->Arg(181)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
