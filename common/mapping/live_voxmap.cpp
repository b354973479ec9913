#include "common/mapping/live_voxmap.h"

#include <pcl/features/normal_3d.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <iterator>
#include <limits>
#include <unordered_map>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_stream.h"

namespace hemm::mapping {
namespace {

constexpr int kKeyBits = 21;
constexpr std::int64_t kKeyBias = std::int64_t{1} << (kKeyBits - 1);
constexpr std::int64_t kKeyMask = (std::int64_t{1} << kKeyBits) - 1;

std::uint64_t key_of(const Eigen::Vector3i& v) {
  return (static_cast<std::uint64_t>((v.x() + kKeyBias) & kKeyMask) << (2 * kKeyBits)) |
         (static_cast<std::uint64_t>((v.y() + kKeyBias) & kKeyMask) << kKeyBits) |
         static_cast<std::uint64_t>((v.z() + kKeyBias) & kKeyMask);
}
Eigen::Vector3i index_of_key(std::uint64_t k) {
  auto f = [](std::uint64_t b) { return static_cast<int>(static_cast<std::int64_t>(b & kKeyMask) - kKeyBias); };
  return {f(k >> (2 * kKeyBits)), f(k >> kKeyBits), f(k)};
}

struct Cell {
  float log_odds = 0.0f;
  std::int32_t hits = 0;
  Eigen::Vector3f sum_p = Eigen::Vector3f::Zero();     // W, metres
  Eigen::Vector3f sum_view = Eigen::Vector3f::Zero();  // unit vectors from the hit toward the sensor
};

// Parameters t0 <= t1 in [0, 1] of the part of a -> b inside box; false if none.
bool clip_segment(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double* t0,
                  double* t1) {
  double lo = 0.0, hi = 1.0;
  const Eigen::Vector3d d = b - a;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (a[k] < box.min()[k] || a[k] > box.max()[k]) return false;
      continue;
    }
    double ta = (box.min()[k] - a[k]) / d[k], tb = (box.max()[k] - a[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    lo = std::max(lo, ta);
    hi = std::min(hi, tb);
    if (lo > hi) return false;
  }
  *t0 = lo;
  *t1 = hi;
  return true;
}

// The newest depth frames, kept as how far each pixel's ray cleared space
// (what integrate() clears: up to clear_margin before a valid return, up to
// range_max along a no-return ray; 0 where the pixel says nothing). The
// snapshot asks them whether a voxel it would put behind a seen surface was
// passed through by a ray: free-space evidence beats the plane-side guess.
constexpr double kFreeMargin = 0.006;  // m before a hit the free-space record reaches: ~3 sigma of the range noise at 1 m
constexpr std::size_t kSeenFrames = 3;  // 0.2 s at 15 Hz; 19 kB each at 80 x 60

struct SeenFrame {
  std::uint32_t cloud_id = 0;
  DepthIntrinsics K;
  Eigen::Isometry3d T_S_W = Eigen::Isometry3d::Identity();
  std::vector<float> cleared_range;  // metres along the pixel's ray, row-major
};

}  // namespace

struct LiveVoxmap::Impl {
  LiveVoxmapParams p;
  LiveVoxmapStats stats;
  std::unordered_map<std::uint64_t, Cell> cells;
  std::deque<SeenFrame> seen;  // oldest first
  // Free-space record (unknown_solid): 1 where a ray passed through the
  // voxel, over the ROI's voxels [free_lo, free_lo + free_dims).
  std::vector<std::uint8_t> free_grid;
  Eigen::Vector3i free_lo = Eigen::Vector3i::Zero(), free_dims = Eigen::Vector3i::Zero();
  // The newest snapshot's completion (temporal coherence) and report.
  mutable Shape3dModel shapes;
  mutable std::vector<CellSample3> shape_samples;  // its input (the shape log)
  mutable LiveVoxmapSnapshotReport snap_stats;

  // The free grid's slot of voxel v, or -1 outside the ROI's voxels.
  std::ptrdiff_t free_slot(const Eigen::Vector3i& v) const {
    const Eigen::Vector3i l = v - free_lo;
    if ((l.array() < 0).any() || (l.array() >= free_dims.array()).any()) return -1;
    return (static_cast<std::ptrdiff_t>(l.z()) * free_dims.y() + l.y()) * free_dims.x() + l.x();
  }
  void place_free_grid() {
    if (!p.unknown_solid) return;
    const Eigen::Vector3i lo = index(p.roi.min()), hi = index(p.roi.max());
    const Eigen::Vector3i dims = (hi - lo).cwiseMax(Eigen::Vector3i::Constant(-1)) + Eigen::Vector3i::Constant(1);
    std::vector<std::uint8_t> next(static_cast<std::size_t>(dims.x()) * dims.y() * dims.z(), 0);
    // What the old record knew of the new ROI is kept.
    for (int z = 0; z < dims.z(); ++z)
      for (int y = 0; y < dims.y(); ++y)
        for (int x = 0; x < dims.x(); ++x) {
          const std::ptrdiff_t o = free_grid.empty() ? -1 : free_slot(lo + Eigen::Vector3i(x, y, z));
          if (o >= 0) next[(static_cast<std::size_t>(z) * dims.y() + y) * dims.x() + x] = free_grid[static_cast<std::size_t>(o)];
        }
    free_grid.swap(next);
    free_lo = lo;
    free_dims = dims;
  }
  bool is_free(const Eigen::Vector3i& v) const {
    const std::ptrdiff_t o = free_slot(v);
    return o >= 0 && free_grid[static_cast<std::size_t>(o)] != 0;
  }

  // The frame a chunk belongs to (its cloud id and image size), begun afresh
  // (replacing the oldest) for a new cloud.
  SeenFrame& seen_frame_of(const DepthChunkData& c) {
    for (SeenFrame& f : seen)
      if (f.cloud_id == c.cloud_id && f.K.width == c.K.width && f.K.height == c.K.height) return f;
    SeenFrame f;
    if (seen.size() >= kSeenFrames) {
      f = std::move(seen.front());
      seen.pop_front();
    }
    f.cloud_id = c.cloud_id;
    f.K = c.K;
    f.T_S_W = c.T_W_S.inverse();
    f.cleared_range.assign(static_cast<std::size_t>(c.K.width) * static_cast<std::size_t>(c.K.height), 0.0f);
    seen.push_back(std::move(f));
    return seen.back();
  }

  // True if a ray of a kept frame passed through x (W) on its way to a
  // return beyond it (or to range_max): x is free space.
  bool seen_free(const Eigen::Vector3d& x) const {
    for (const SeenFrame& f : seen) {
      const Eigen::Vector3d q = f.T_S_W * x;
      if (q.z() <= 0.0) continue;
      const double u = f.K.fx * q.x() / q.z() + f.K.cx, v = f.K.fy * q.y() / q.z() + f.K.cy;
      if (!(u >= 0.0 && v >= 0.0 && u < f.K.width && v < f.K.height)) continue;
      // The ray through x lies between four pixels' rays: on a surface seen
      // obliquely their ranges differ by centimetres, so the nearest pixel
      // alone would clear space just behind it. Interpolate the cleared range
      // bilinearly (exact enough on a plane); where a pixel says nothing,
      // only the nearest one answers.
      const auto W = static_cast<std::size_t>(f.K.width);
      const double uc = std::clamp(u - 0.5, 0.0, f.K.width - 1.0), vc = std::clamp(v - 0.5, 0.0, f.K.height - 1.0);
      const auto u0 = static_cast<std::size_t>(uc), v0 = static_cast<std::size_t>(vc);
      const std::size_t u1 = std::min(u0 + 1, W - 1), v1 = std::min(v0 + 1, static_cast<std::size_t>(f.K.height) - 1);
      const double a = uc - static_cast<double>(u0), b = vc - static_cast<double>(v0);
      const float r00 = f.cleared_range[v0 * W + u0], r01 = f.cleared_range[v0 * W + u1];
      const float r10 = f.cleared_range[v1 * W + u0], r11 = f.cleared_range[v1 * W + u1];
      double cleared = 0.0;
      if (r00 > 0.0f && r01 > 0.0f && r10 > 0.0f && r11 > 0.0f) {
        cleared = (1 - b) * ((1 - a) * r00 + a * r01) + b * ((1 - a) * r10 + a * r11);
      } else {
        cleared = f.cleared_range[static_cast<std::size_t>(v) * W + static_cast<std::size_t>(u)];
      }
      if (q.norm() < cleared) return true;
    }
    return false;
  }

  // True if x (W) lies in the view of a kept frame (in front of its camera,
  // inside its image, within range_max): what the camera looked at, whether
  // a ray reached it or a surface hid it.
  bool in_view(const Eigen::Vector3d& x) const {
    for (const SeenFrame& f : seen) {
      const Eigen::Vector3d q = f.T_S_W * x;
      if (q.z() <= 0.0 || q.norm() > f.K.range_max) continue;
      const double u = f.K.fx * q.x() / q.z() + f.K.cx, v = f.K.fy * q.y() / q.z() + f.K.cy;
      if (u >= 0.0 && v >= 0.0 && u < f.K.width && v < f.K.height) return true;
    }
    return false;
  }

  Eigen::Vector3i index(const Eigen::Vector3d& x) const {
    return {static_cast<int>(std::floor(x.x() / p.voxel_size)), static_cast<int>(std::floor(x.y() / p.voxel_size)),
            static_cast<int>(std::floor(x.z() / p.voxel_size))};
  }

  // Amanatides-Woo walk over the voxels of a -> b (clipped to the ROI),
  // applying a miss to every stored cell on the way.
  // miss false: only the free-space record is marked (the last stretch
  // before a hit, closer than clear_margin: see integrate()).
  void clear(const Eigen::Vector3d& a0, const Eigen::Vector3d& b0, bool miss = true) {
    double t0 = 0, t1 = 0;
    if (!clip_segment(p.roi, a0, b0, &t0, &t1)) return;
    if (!miss && free_grid.empty()) return;
    const Eigen::Vector3d a = a0 + t0 * (b0 - a0), b = a0 + t1 * (b0 - a0);
    if (miss) ++stats.rays_cleared;
    const double s = p.voxel_size;
    const Eigen::Vector3d d = b - a;
    Eigen::Vector3i v = index(a);
    const Eigen::Vector3i end = index(b);
    std::array<int, 3> step{};
    std::array<double, 3> tmax{}, tdelta{};
    for (int k = 0; k < 3; ++k) {
      if (d[k] > 0) {
        step[k] = 1;
        tmax[k] = ((v[k] + 1) * s - a[k]) / d[k];
        tdelta[k] = s / d[k];
      } else if (d[k] < 0) {
        step[k] = -1;
        tmax[k] = (v[k] * s - a[k]) / d[k];
        tdelta[k] = -s / d[k];
      } else {
        tmax[k] = tdelta[k] = std::numeric_limits<double>::infinity();
      }
    }
    const int max_steps = (end - v).cwiseAbs().sum() + 1;
    const bool record = !free_grid.empty();
    for (int i = 0; i <= max_steps; ++i) {
      if (record) {
        const std::ptrdiff_t o = free_slot(v);
        if (o >= 0) free_grid[static_cast<std::size_t>(o)] = 1;
      }
      auto it = miss ? cells.find(key_of(v)) : cells.end();
      if (it != cells.end()) {
        ++stats.voxels_cleared;
        it->second.log_odds += p.log_odds_miss;
        if (it->second.log_odds < p.log_odds_min) {
          cells.erase(it);
          ++stats.cells_forgotten;
        }
      }
      if (v == end) break;
      const int k = static_cast<int>(std::min_element(tmax.begin(), tmax.end()) - tmax.begin());
      if (tmax[static_cast<std::size_t>(k)] > 1.0) break;
      v[k] += step[static_cast<std::size_t>(k)];
      tmax[static_cast<std::size_t>(k)] += tdelta[static_cast<std::size_t>(k)];
    }
  }

  void hit(const Eigen::Vector3d& x, const Eigen::Vector3d& o) {
    const std::uint64_t key = key_of(index(x));
    auto it = cells.find(key);
    if (it == cells.end()) {
      if (cells.size() >= p.max_cells) {
        ++stats.cells_refused;
        return;
      }
      it = cells.emplace(key, Cell{}).first;
    }
    Cell& c = it->second;
    // A cell that was not occupied starts its surface estimate afresh (what
    // was there before has been cleared away).
    if (c.log_odds < p.occupied) {
      c.hits = 0;
      c.sum_p.setZero();
      c.sum_view.setZero();
    }
    c.log_odds = std::min(p.log_odds_max, c.log_odds + p.log_odds_hit);
    ++c.hits;
    c.sum_p += x.cast<float>();
    c.sum_view += (o - x).normalized().cast<float>();
  }
};

std::optional<std::string> LiveVoxmap::check(const LiveVoxmapParams& p) {
  if (!(p.voxel_size >= 0.001 && p.voxel_size <= 0.2)) return "live voxmap: voxel size not in [1 mm, 20 cm]";
  if (p.roi.isEmpty() || !p.roi.min().allFinite() || !p.roi.max().allFinite())
    return "live voxmap: region of interest empty or not finite";
  const double lim = (kKeyBias - 64) * p.voxel_size;
  if (p.roi.min().minCoeff() < -lim || p.roi.max().maxCoeff() > lim)
    return "live voxmap: region of interest beyond the index range";
  if (!(p.log_odds_hit > 0 && p.log_odds_miss < 0 && p.log_odds_min < 0 && p.log_odds_max > p.occupied &&
        p.occupied > 0 && p.log_odds_hit >= p.occupied))
    return "live voxmap: log-odds settings inconsistent";
  if (!(p.downsample_leaf > 0 && p.downsample_leaf <= p.voxel_size)) return "live voxmap: leaf not in (0, voxel]";
  if (p.outlier_neighbours < 0 || !(p.outlier_stddev > 0)) return "live voxmap: bad outlier settings";
  if (!(p.clear_margin >= 0) || !(p.normal_radius >= p.voxel_size)) return "live voxmap: bad margin or normal radius";
  if (p.layers < 1 || p.layers > 20) return "live voxmap: layers not in 1..20";
  if (p.min_support < 1) return "live voxmap: min_support must be positive";
  if (!(p.min_view_cosine >= 0.0 && p.min_view_cosine < 1.0)) return "live voxmap: min_view_cosine must be in [0, 1)";
  if (p.max_cells < 1) return "live voxmap: max_cells must be positive";
  if (const std::string e = validate(p.shapes); p.shape_completion && !e.empty()) return "live voxmap: " + e;
  if (p.unknown_solid) {
    const Eigen::Vector3d n = p.roi.sizes() / p.voxel_size;
    if (n.x() * n.y() * n.z() > 64e6) return "live voxmap: region of interest too large for the free-space record (64 M voxels)";
  }
  return std::nullopt;
}

LiveVoxmap::LiveVoxmap(const LiveVoxmapParams& params) : impl_(std::make_unique<Impl>()) {
  impl_->p = params;
  impl_->place_free_grid();
}
LiveVoxmap::~LiveVoxmap() = default;
LiveVoxmap::LiveVoxmap(LiveVoxmap&&) noexcept = default;
LiveVoxmap& LiveVoxmap::operator=(LiveVoxmap&&) noexcept = default;

void LiveVoxmap::integrate(const DepthChunkData& c) {
  Impl& m = *impl_;
  const LiveVoxmapParams& p = m.p;
  ++m.stats.chunks;
  SeenFrame& seen = m.seen_frame_of(c);
  const Eigen::Vector3d o = c.T_W_S.translation();
  const Eigen::Matrix3d R = c.T_W_S.linear();
  // Hits whose cell can be in the ROI; rays of everything else only clear.
  const Eigen::AlignedBox3d grown(p.roi.min() - Eigen::Vector3d::Constant(p.voxel_size),
                                  p.roi.max() + Eigen::Vector3d::Constant(p.voxel_size));
  pcl::PointCloud<pcl::PointXYZ>::Ptr raw(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> free_segments;
  for (int r = 0; r < c.row_count; ++r) {
    for (int u = 0; u < c.K.width; ++u) {
      const std::size_t k = static_cast<std::size_t>(r) * c.K.width + u;
      const Eigen::Vector3d ray_W = R * pixel_ray_z1(c.K, u, c.first_row + r);
      // How far this pixel's ray cleared space, kept for snapshot()'s free-space check.
      float& cleared = seen.cleared_range[static_cast<std::size_t>(c.first_row + r) * c.K.width + u];
      if (c.status[k] == DepthStatus::kNoReturn) {
        cleared = static_cast<float>(c.K.range_max);
        free_segments.emplace_back(o, o + c.K.range_max * ray_W.normalized());
      } else if (c.status[k] == DepthStatus::kValid) {
        const Eigen::Vector3d x = o + static_cast<double>(c.depth[k]) * ray_W;
        const double len = (x - o).norm();
        cleared = static_cast<float>(std::max(0.0, len - p.clear_margin));
        if (grown.contains(x)) {
          raw->push_back(pcl::PointXYZ(static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z())));
        } else if (len > p.clear_margin) {
          free_segments.emplace_back(o, o + (x - o) * ((len - p.clear_margin) / len));
        }
      }
    }
  }
  m.stats.points_in_roi += raw->size();
  pcl::PointCloud<pcl::PointXYZ>::Ptr kept(new pcl::PointCloud<pcl::PointXYZ>);
  if (!raw->empty()) {
    pcl::PointCloud<pcl::PointXYZ>::Ptr down(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setInputCloud(raw);
    const auto leaf = static_cast<float>(p.downsample_leaf);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.filter(*down);
    if (p.outlier_neighbours > 0 && down->size() > static_cast<std::size_t>(p.outlier_neighbours)) {
      pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
      sor.setInputCloud(down);
      sor.setMeanK(p.outlier_neighbours);
      sor.setStddevMulThresh(p.outlier_stddev);
      sor.filter(*kept);
    } else {
      kept = down;
    }
  }
  m.stats.points_kept += kept->size();
  // Clear first, then add this chunk's hits: its own rays must not erase them.
  for (const auto& [a, b] : free_segments) m.clear(a, b);
  for (const auto& q : kept->points) {
    const Eigen::Vector3d x(q.x, q.y, q.z);
    const double len = (x - o).norm();
    if (len > p.clear_margin) m.clear(o, o + (x - o) * ((len - p.clear_margin) / len));
    // The free-space record goes on to kFreeMargin before the hit: the
    // clear margin keeps a grazing ray off the surface's own cells'
    // occupancy, but as "unseen" it would put the unknown boundary 1.5 cm
    // proud of every seen surface's edge.
    if (len > p.clear_margin && p.clear_margin > kFreeMargin)
      m.clear(o + (x - o) * ((len - p.clear_margin) / len), o + (x - o) * ((len - kFreeMargin) / len), false);
  }
  for (const auto& q : kept->points) {
    const Eigen::Vector3d x(q.x, q.y, q.z);
    if (p.roi.contains(x)) m.hit(x, o);
  }
}

void LiveVoxmap::set_roi(const Eigen::AlignedBox3d& roi_W) {
  Impl& m = *impl_;
  m.p.roi = roi_W;
  m.place_free_grid();
  for (auto it = m.cells.begin(); it != m.cells.end();) {
    const Eigen::Vector3d centre = (index_of_key(it->first).cast<double>() + Eigen::Vector3d::Constant(0.5)) * m.p.voxel_size;
    it = roi_W.contains(centre) ? std::next(it) : m.cells.erase(it);
  }
}

std::optional<std::string> LiveVoxmap::snapshot(vps::Voxmap* out, std::int64_t (*now_ns)()) const {
  const Impl& m = *impl_;
  const LiveVoxmapParams& p = m.p;
  const double s = p.voxel_size;
  const int L = p.layers;
  const std::int64_t t_begin = now_ns != nullptr ? now_ns() : 0;
  LiveVoxmapSnapshotReport rep;  // into snap_stats at the end
  // Occupied cells: index, mean point, hit count, viewing direction.
  std::vector<Eigen::Vector3i> idx;
  std::vector<Eigen::Vector3d> view, sum_p;
  std::vector<double> hits;
  pcl::PointCloud<pcl::PointXYZ>::Ptr means(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& [key, c] : m.cells) {
    if (c.log_odds < p.occupied || c.hits < 1) continue;
    idx.push_back(index_of_key(key));
    const Eigen::Vector3f mean = c.sum_p / static_cast<float>(c.hits);
    means->push_back(pcl::PointXYZ(mean.x(), mean.y(), mean.z()));
    view.push_back(c.sum_view.cast<double>().normalized());
    sum_p.push_back(c.sum_p.cast<double>());
    hits.push_back(c.hits);
  }
  if (idx.empty()) return "live voxmap: nothing occupied yet";
  // Normals of the surface through the cell means (PCL), toward the sensor,
  // and the surface point of each cell: the hit-weighted centroid of its
  // neighbourhood. A cell's own mean is biased where noise spreads a surface
  // over two voxel layers (each layer keeps one tail of the noise); the
  // neighbourhood holds both tails.
  pcl::PointCloud<pcl::Normal> normals;
  std::vector<Eigen::Vector3d> centroid(idx.size());
  std::vector<int> support(idx.size(), 0);
  {
    pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
    tree->setInputCloud(means);
    pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
    ne.setInputCloud(means);
    ne.setSearchMethod(tree);
    ne.setRadiusSearch(p.normal_radius);
    ne.compute(normals);
    std::vector<int> nb;
    std::vector<float> d2;
    for (std::size_t i = 0; i < idx.size(); ++i) {
      Eigen::Vector3d sp = Eigen::Vector3d::Zero();
      double n = 0.0;
      tree->radiusSearch(means->points[i], p.normal_radius, nb, d2);
      support[i] = static_cast<int>(nb.size());
      for (int j : nb) {
        sp += sum_p[static_cast<std::size_t>(j)];
        n += hits[static_cast<std::size_t>(j)];
      }
      centroid[i] = n > 0 ? Eigen::Vector3d(sp / n) : Eigen::Vector3d(sum_p[i] / hits[i]);
    }
  }
  // The cells rendered, with their normals toward the sensor.
  std::vector<Eigen::Vector3d> normal(idx.size(), Eigen::Vector3d::Zero());
  std::vector<std::uint32_t> rendered;
  for (std::size_t i = 0; i < idx.size(); ++i) {
    // A surface needs support: a cell with fewer than min_support cells
    // within the normal radius (itself included) is not rendered.
    if (support[i] < p.min_support) continue;
    const auto& pn = normals.points[i];
    Eigen::Vector3d n(pn.normal_x, pn.normal_y, pn.normal_z);
    if (!n.allFinite() || n.norm() < 0.5) continue;
    if (n.dot(view[i]) < 0) n = -n;
    // A normal the cell was seen almost edge-on along is not a surface the
    // sensor could measure: it comes from a neighbourhood of collinear means
    // (one image row across a surface seen at a grazing angle, rows farther
    // apart than normal_radius), whose covariance leaves the normal anywhere
    // in the plane across the row. Such a cell is not rendered.
    if (n.dot(view[i]) < p.min_view_cosine) continue;
    normal[i] = n;
    rendered.push_back(static_cast<std::uint32_t>(i));
  }
  const SeenFrame* newest = m.seen.empty() ? nullptr : &m.seen.back();
  const Eigen::Vector3d newest_origin =
      newest != nullptr ? Eigen::Vector3d(newest->T_S_W.inverse().translation()) : Eigen::Vector3d::Zero();
  // Shape completion on the rendered cells (their surface points and normals).
  std::vector<std::int32_t> owner(idx.size(), -1);
  Shape3dModel& shapes = m.shapes;
  if (p.shape_completion) {
    const std::int64_t t0 = now_ns != nullptr ? now_ns() : 0;
    std::vector<CellSample3> samples;
    samples.reserve(rendered.size());
    // The cells' own means, not the neighbourhood centroids: those are
    // pulled inward by up to half the normal radius at a surface's edge,
    // and the edges are what pins a primitive's extents.
    const double fx = newest != nullptr ? newest->K.fx : 0.0;
    for (std::uint32_t i : rendered) {
      const Eigen::Vector3d mean = sum_p[i] / hits[i];
      samples.push_back(CellSample3{mean, normal[i], view[i], fx > 0.0 ? (mean - newest_origin).norm() / fx : 0.0});
    }
    const SeenFree seen_free = [&m](const Eigen::Vector3d& x) { return m.is_free(m.index(x)) || m.seen_free(x); };
    complete_shapes_3d(p.shapes, samples, seen_free, shapes);
    for (std::size_t r = 0; r < rendered.size(); ++r) owner[rendered[r]] = shapes.owner[r];
    m.shape_samples.swap(samples);
    for (const Primitive3& q : shapes.primitives) {
      ++rep.primitives;
      rep.boxes += q.kind == PrimitiveKind::kBox ? 1 : 0;
      rep.cylinders += q.kind == PrimitiveKind::kCylinder ? 1 : 0;
      rep.spheres += q.kind == PrimitiveKind::kSphere ? 1 : 0;
    }
    rep.primitives_kept = shapes.kept;
    rep.primitives_refused_free = shapes.refused_free;
    for (std::int32_t o : shapes.owner) rep.cells_completed += o >= 0 ? 1 : 0;
    if (now_ns != nullptr) rep.completion_ns = now_ns() - t0;
  } else {
    shapes = Shape3dModel{};
    m.shape_samples.clear();
  }
  Eigen::Vector3i lo = idx[0], hi = idx[0];
  for (const auto& v : idx) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  // A primitive's unseen back may reach beyond the seen cells.
  for (const Primitive3& q : shapes.primitives) {
    const Eigen::AlignedBox3d b = primitive_bounds(q);
    lo = lo.cwiseMin(m.index(b.min()));
    hi = hi.cwiseMax(m.index(b.max()));
  }
  const int pad = L + 2;
  const Eigen::Vector3i org = lo - Eigen::Vector3i::Constant(pad);
  vps::Voxmap vm;
  vm.voxel_size = s;
  vm.origin = org.cast<double>() * s;
  for (int k = 0; k < 3; ++k) vm.block_dims[k] = (hi[k] - lo[k] + 1 + 2 * pad + vps::kBlockDim - 1) / vps::kBlockDim;
  vm.signed_field = true;
  vm.layers_out = vm.layers_in = L;
  const std::size_t nblocks = static_cast<std::size_t>(vm.block_dims.x()) * vm.block_dims.y() * vm.block_dims.z();
  if (nblocks > static_cast<std::size_t>(vps::kMaxBlocks)) return "live voxmap: snapshot grid too large";
  vm.top.assign(nblocks, vps::kBlockEmpty);
  std::vector<std::array<float, vps::kBlockVoxels>> best;  // |distance| to the nearest patch so far
  std::vector<std::array<std::int8_t, vps::kBlockVoxels>> cheb;
  // Per voxel, the nearest patch it lies in front of: its value if a ray
  // shows that a voxel some patch puts behind it is free.
  std::vector<std::array<vps::Voxel, vps::kBlockVoxels>> best_outside;
  std::vector<Eigen::Vector3i> block_first;  // the first voxel of each stored block
  // Per voxel, whether it lies in the shadow of some patch (see below).
  std::vector<std::array<std::uint8_t, vps::kBlockVoxels>> shadowed;
  // Per voxel, where its value comes from (precedence over unknown space).
  enum Source : std::uint8_t { kNone = 0, kMeasured, kGuess, kFitted };
  std::vector<std::array<std::uint8_t, vps::kBlockVoxels>> source;
  const float far_out = vm.far_outside_sdf();
  std::vector<std::uint8_t> has_surface;
  // The block holding grid voxel v, allocated (far outside) on first use.
  auto block_at = [&](const Eigen::Vector3i& v) -> std::size_t {
    const Eigen::Vector3i b(v.x() >> vps::kBlockShift, v.y() >> vps::kBlockShift, v.z() >> vps::kBlockShift);
    std::int32_t& t = vm.top[vps::block_linear(vm, b)];
    if (t == vps::kBlockEmpty) {
      t = static_cast<std::int32_t>(vm.blocks.size());
      vps::VoxelBlock blk;
      for (vps::Voxel& vx : blk.v) vx = vps::Voxel{far_out, {0, 0, 0}, vps::kLayerFarOutside, 0};
      vm.blocks.push_back(blk);
      vm.sheet_of_block.push_back(-1);  // point clouds carry no sheets
      best.emplace_back();
      best.back().fill(std::numeric_limits<float>::infinity());
      cheb.emplace_back();
      cheb.back().fill(std::numeric_limits<std::int8_t>::max());
      has_surface.push_back(0);
      best_outside.emplace_back();
      best_outside.back().fill(vps::Voxel{std::numeric_limits<float>::infinity(), {0, 0, 0}, 0, 0});
      shadowed.emplace_back();
      shadowed.back().fill(0);
      source.emplace_back();
      source.back().fill(kNone);
      block_first.push_back(b * vps::kBlockDim);
    }
    return static_cast<std::size_t>(t);
  };
  // A patch's shadow: the space behind it whose line of sight toward where
  // it was seen from crosses its plane within a radius of its centre. Right
  // behind a patch (within its rim) is inside; beyond the rims only a shadow
  // shows that a seen surface is in front (beside every shadow: over a small
  // top seen edge-on or out of the image, beside a side seen edge-on).
  // Radius: half the normal radius (a rendered cell has the next image rows
  // within it, and at a surface's edge its centre lies up to about that far
  // inside) plus half a voxel; or, where the camera's samples lie farther
  // apart (fine voxels), half the sample spacing on the surface plus half a
  // voxel: the newest frame's pixel pitch at the cell's range over the
  // cosine between normal and view. (Tests: 2.5 cm with the probe's 5 cm
  // radius cut a block's top seen at 11 degrees 5 mm low, 3.5 cm reached
  // over the mug's top; without the spacing term 5 mm voxels left holes
  // under the bench's table, 60 % force error against 26 %.)
  const double shadow_radius = 0.5 * (p.normal_radius + s);
  for (std::uint32_t i : rendered) {
    if (owner[i] >= 0) continue;  // a primitive stands for it
    const Eigen::Vector3d& n = normal[i];
    const Eigen::Vector3d& c = centroid[i];
    const Eigen::Vector3i base = idx[i] - org;
    double shadow_r = shadow_radius;
    if (newest != nullptr && newest->K.fx > 0.0) {
      const double spacing = (c - newest_origin).norm() / newest->K.fx / n.dot(view[i]);
      shadow_r = std::max(shadow_radius, 0.5 * (spacing + s));
    }
    const double shadow_r2 = shadow_r * shadow_r;
    for (int dz = -L; dz <= L; ++dz) {
      for (int dy = -L; dy <= L; ++dy) {
        for (int dx = -L; dx <= L; ++dx) {
          const Eigen::Vector3i v = base + Eigen::Vector3i(dx, dy, dz);
          const std::size_t bi = block_at(v);
          const int vi = vps::voxel_in_block(v);
          const Eigen::Vector3d x = vps::voxel_centre(vm, v);
          const auto ch = static_cast<std::int8_t>(std::max({std::abs(dx), std::abs(dy), std::abs(dz)}));
          if (ch == 0) has_surface[bi] = 1;
          auto& cb = cheb[bi][static_cast<std::size_t>(vi)];
          cb = std::min(cb, ch);
          // Distance to the cell's patch, a disc of radius one voxel in its
          // plane, signed by the side of that plane (behind a seen surface is
          // inside: unseen is not free). Over a seen surface some disc lies
          // right above or below x (exact plane distance); the rim keeps a
          // cell from reaching as far as an endless plane. The nearest patch wins.
          const double h = n.dot(x - c);
          const double lateral = (x - c - h * n).norm();
          if (h < 0.0) {
            // Behind the plane: in the patch's shadow if the line of sight
            // from x toward the sensor crosses the plane near the patch.
            // (n . view >= min_view_cosine > 0 here.)
            const Eigen::Vector3d on_plane = x - (h / n.dot(view[i])) * view[i] - c;
            if (on_plane.squaredNorm() <= shadow_r2) shadowed[bi][static_cast<std::size_t>(vi)] = 1;
          }
          // (sqrt, not std::hypot: the values are centimetres, far from
          // overflow, and glibc's hypot was a fifth of the voxmap thread's
          // CPU in the telemanip runs.)
          const double beyond_rim = std::max(lateral - s, 0.0);
          const double sd = std::copysign(std::sqrt(beyond_rim * beyond_rim + h * h), h);
          const auto dist = static_cast<float>(std::abs(sd));
          vps::Voxel& out_vx = best_outside[bi][static_cast<std::size_t>(vi)];
          const bool nearest = dist < best[bi][static_cast<std::size_t>(vi)];
          const bool nearest_outside = sd >= 0.0 && dist < out_vx.sdf;
          if (nearest || nearest_outside) {
            vps::Voxel vx{static_cast<float>(sd), {0, 0, 0}, 0, 0};
            // Over the patch the field's gradient is its normal; beyond its
            // rim it bends round the edge: there the engine interpolates.
            for (int a = 0; a < 3; ++a) vx.grad[a] = static_cast<std::int16_t>(std::lround(n[a] * vps::kGradScale));
            vx.flags = lateral > s ? vps::kFlagNoGradient : std::uint8_t{0};
            if (nearest) {
              best[bi][static_cast<std::size_t>(vi)] = dist;
              vps::Voxel& dst = vm.blocks[bi].v[static_cast<std::size_t>(vi)];
              dst.sdf = vx.sdf;
              std::copy(std::begin(vx.grad), std::end(vx.grad), std::begin(dst.grad));
              dst.flags = vx.flags;
            }
            if (nearest_outside) out_vx = vx;
          }
        }
      }
    }
  }
  for (std::size_t bi = 0; bi < vm.blocks.size(); ++bi) {
    auto& blk = vm.blocks[bi];
    for (std::size_t vi = 0; vi < static_cast<std::size_t>(vps::kBlockVoxels); ++vi) {
      const std::int8_t ch = cheb[bi][vi];
      if (ch == std::numeric_limits<std::int8_t>::max()) continue;
      vps::Voxel& vx = blk.v[vi];
      source[bi][vi] = (vx.flags & vps::kFlagNoGradient) != 0 ? kGuess : kMeasured;
      if (vx.sdf < 0.0f) {
        // Behind the nearest patch's plane but beyond its rim, in no patch's
        // shadow (beside the seen surfaces: above a small top seen edge-on
        // whose front face's plane reaches over it, out of the image or in
        // the row the camera dropped at its silhouette; beside a side seen
        // edge-on), or a ray passed through: outside, at
        // the distance of the nearest patch it lies in front of if that is
        // nearer than the nearest patch's (a voxel cleared by the noise just
        // behind a surface stays at its small distance: no step in the field);
        // else at the nearest patch's distance, with no gradient to trust.
        const auto i = static_cast<int>(vi);
        const Eigen::Vector3i v = block_first[bi] + Eigen::Vector3i(i & (vps::kBlockDim - 1),
                                                                    (i >> vps::kBlockShift) & (vps::kBlockDim - 1),
                                                                    i >> (2 * vps::kBlockShift));
        const bool beyond_rim = (vx.flags & vps::kFlagNoGradient) != 0;
        if ((beyond_rim && shadowed[bi][vi] == 0) || m.seen_free(vps::voxel_centre(vm, v))) {
          const vps::Voxel& o = best_outside[bi][vi];
          if (o.sdf < -vx.sdf) {
            vx.sdf = o.sdf;
            std::copy(std::begin(o.grad), std::end(o.grad), std::begin(vx.grad));
            vx.flags = o.flags;
            source[bi][vi] = (o.flags & vps::kFlagNoGradient) != 0 ? kGuess : kMeasured;
          } else {
            vx.sdf = -vx.sdf;
            vx.flags = vps::kFlagNoGradient;
            source[bi][vi] = kGuess;
          }
        }
      }
      blk.v[vi].layer = static_cast<std::int8_t>(blk.v[vi].sdf < 0.0f ? -ch : ch);
    }
  }
  // A voxel's layer from its distance (primitives, unknown space): never
  // more than the Chebyshev distance to a surface voxel, so the contact's
  // layer test never skips a voxel it should test.
  auto layer_of = [&](float d) {
    const int k = std::min(126, static_cast<int>(std::floor(std::abs(d) / s)));
    return static_cast<std::int8_t>(d < 0.0f ? -k : k);
  };
  // Primitives: the union of the raw surfaces and each primitive's solid, in
  // closed form, over the voxels within the layers of it. Inferred where the
  // nearest surface point of the primitive has no cell of its own near it.
  if (!shapes.primitives.empty()) {
    std::unordered_map<std::uint64_t, std::uint32_t> cell_at;  // rendered cells owned by a primitive
    for (std::uint32_t i : rendered)
      if (owner[i] >= 0) cell_at.emplace(key_of(idx[i]), i);
    const Eigen::Vector3i dims = vm.dims();
    for (std::size_t qi = 0; qi < shapes.primitives.size(); ++qi) {
      const Primitive3& q = shapes.primitives[qi];
      const Eigen::AlignedBox3d b = primitive_bounds(q);
      const Eigen::Vector3i v0 = (m.index(b.min()) - org - Eigen::Vector3i::Constant(L + 1)).cwiseMax(0);
      const Eigen::Vector3i v1 = (m.index(b.max()) - org + Eigen::Vector3i::Constant(L + 1)).cwiseMin(dims - Eigen::Vector3i::Ones());
      for (int z = v0.z(); z <= v1.z(); ++z)
        for (int y = v0.y(); y <= v1.y(); ++y)
          for (int x = v0.x(); x <= v1.x(); ++x) {
            const Eigen::Vector3i v(x, y, z);
            const Eigen::Vector3d c = vps::voxel_centre(vm, v);
            Eigen::Vector3d g;
            bool kink = false;
            const double d = primitive_sdf(q, c, &g, &kink, s);
            if (d > (L + 0.5) * s) continue;
            const std::size_t bi = block_at(v);
            const auto vi = static_cast<std::size_t>(vps::voxel_in_block(v));
            vps::Voxel& vx = vm.blocks[bi].v[vi];
            if (!(d < vx.sdf)) continue;  // the union: the nearer solid wins
            // Seen: an owned cell within 1.5 voxels of the nearest surface point.
            const Eigen::Vector3d foot = c - d * g;
            const Eigen::Vector3i fv = m.index(foot);
            bool seen = false;
            for (int k = 0; k < 27 && !seen; ++k) {
              const Eigen::Vector3i nv = fv + Eigen::Vector3i(k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1);
              const auto it = cell_at.find(key_of(nv));
              seen = it != cell_at.end() && owner[it->second] == static_cast<std::int32_t>(qi) &&
                     (sum_p[it->second] / hits[it->second] - foot).squaredNorm() <= 2.25 * s * s;
            }
            vx.sdf = static_cast<float>(d);
            for (int a = 0; a < 3; ++a) vx.grad[a] = static_cast<std::int16_t>(std::lround(g[a] * vps::kGradScale));
            vx.flags = static_cast<std::uint8_t>((kink ? vps::kFlagNoGradient : 0) | (seen ? 0 : vps::kFlagInferred));
            vx.layer = layer_of(vx.sdf);
            if (vx.layer == 0) has_surface[bi] = 1;
            source[bi][vi] = kFitted;
          }
    }
  }
  // Unknown is solid: voxels not holding a seen surface or a primitive take
  // the signed distance to the boundary of the space rays passed through
  // when that is nearer inside (free: +distance to the nearest unseen voxel;
  // unseen: -distance to the nearest free voxel; half a voxel off the
  // centres). Exact nearest voxels by a search over the layers' cube, once
  // per stored voxel that needs it.
  if (p.unknown_solid && !m.free_grid.empty()) {
    const std::int64_t t0 = now_ns != nullptr ? now_ns() : 0;
    // A voxel of W's grid is unseen: in the ROI's record and not free.
    auto unseen = [&](const Eigen::Vector3i& w) {
      const std::ptrdiff_t o = m.free_slot(w);
      return o >= 0 && m.free_grid[static_cast<std::size_t>(o)] == 0;
    };
    for (std::size_t bi = 0; bi < vm.blocks.size(); ++bi) {
      // A block with no free voxel within the layers of it (deep in unseen
      // space, e.g. under the table) needs no search: all of it is as deep
      // as the layers reach.
      bool free_near = false;
      {
        const Eigen::Vector3i w0 = block_first[bi] + org - Eigen::Vector3i::Constant(L);
        const int n = vps::kBlockDim + 2 * L;
        for (int z = 0; z < n && !free_near; ++z)
          for (int y = 0; y < n && !free_near; ++y)
            for (int x = 0; x < n && !free_near; ++x) {
              const Eigen::Vector3i u = w0 + Eigen::Vector3i(x, y, z);
              free_near = m.free_slot(u) >= 0 && !unseen(u);
            }
      }
      for (std::size_t vi = 0; vi < static_cast<std::size_t>(vps::kBlockVoxels); ++vi) {
        const std::uint8_t src = source[bi][vi];
        if (src == kMeasured || src == kFitted) continue;
        const auto i = static_cast<int>(vi);
        const Eigen::Vector3i v = block_first[bi] + Eigen::Vector3i(i & (vps::kBlockDim - 1),
                                                                    (i >> vps::kBlockShift) & (vps::kBlockDim - 1),
                                                                    i >> (2 * vps::kBlockShift));
        const Eigen::Vector3i w = v + org;  // W's voxel index
        if (m.free_slot(w) < 0) continue;   // outside the ROI: nothing recorded
        const bool in = unseen(w);
        if (!in) continue;  // free space keeps its value (outside)
        // Unseen, and the camera looked there: hidden behind what it saw.
        // Out of every kept frame's view is no evidence either way (a mast
        // camera's image ends below the height the tool comes down from):
        // not made solid.
        if (!m.in_view(vps::voxel_centre(vm, v))) continue;
        // The nearest free voxel within the layers: shells of growing
        // Chebyshev radius k, until k^2 exceeds the best squared distance.
        int best2 = std::numeric_limits<int>::max();
        Eigen::Vector3i bestd = Eigen::Vector3i::Zero();
        for (int k = 1; free_near && k <= L && k * k < best2; ++k)
          for (int dz = -k; dz <= k; ++dz)
            for (int dy = -k; dy <= k; ++dy)
              for (int dx = -k; dx <= k; dx += (std::abs(dz) == k || std::abs(dy) == k) ? 1 : 2 * k) {
                const int d2 = dx * dx + dy * dy + dz * dz;
                if (d2 >= best2) continue;
                const Eigen::Vector3i u = w + Eigen::Vector3i(dx, dy, dz);
                if (m.free_slot(u) >= 0 && !unseen(u)) {
                  best2 = d2;
                  bestd = Eigen::Vector3i(dx, dy, dz);
                }
              }
        vps::Voxel& vx = vm.blocks[bi].v[vi];
        const double dist = best2 == std::numeric_limits<int>::max() ? (L + 1) * s : (std::sqrt(best2) - 0.5) * s;
        const auto d = static_cast<float>(-dist);
        if (!(d < vx.sdf)) continue;
        vx.sdf = d;
        const Eigen::Vector3d g = best2 == std::numeric_limits<int>::max() ? Eigen::Vector3d::UnitZ()
                                                                             : Eigen::Vector3d(bestd.cast<double>().normalized());
        for (int a = 0; a < 3; ++a) vx.grad[a] = static_cast<std::int16_t>(std::lround(g[a] * vps::kGradScale));
        vx.flags = vps::kFlagNoGradient | vps::kFlagInferred;  // a voxel staircase: no gradient to trust
        vx.layer = layer_of(vx.sdf);
        if (vx.layer == 0) has_surface[bi] = 1;
        ++rep.voxels_unknown;
      }
    }
    if (now_ns != nullptr) rep.unknown_ns = now_ns() - t0;
  }
  for (std::size_t bi = 0; bi < vm.blocks.size(); ++bi)
    for (std::size_t vi = 0; vi < static_cast<std::size_t>(vps::kBlockVoxels); ++vi) {
      const vps::Voxel& vx = vm.blocks[bi].v[vi];
      if (source[bi][vi] == kNone && vx.layer == vps::kLayerFarOutside) continue;
      if (vx.layer == 0) ++vm.surface_voxels;
      rep.voxels_primitive += source[bi][vi] == kFitted ? 1 : 0;
      rep.voxels_inferred += (vx.flags & vps::kFlagInferred) != 0 ? 1 : 0;
    }
  // Coarse block distance to the nearest block with surface voxels
  // (Chebyshev, breadth first over the 26-neighbourhood), for culling.
  vm.coarse.assign(nblocks, 255);
  std::deque<std::size_t> queue;
  for (std::size_t bl = 0; bl < nblocks; ++bl) {
    const std::int32_t t = vm.top[bl];
    if (t >= 0 && has_surface[static_cast<std::size_t>(t)] != 0) {
      vm.coarse[bl] = 0;
      queue.push_back(bl);
    }
  }
  const Eigen::Vector3i bd = vm.block_dims;
  while (!queue.empty()) {
    const std::size_t bl = queue.front();
    queue.pop_front();
    const int bx = static_cast<int>(bl % static_cast<std::size_t>(bd.x()));
    const int by = static_cast<int>((bl / static_cast<std::size_t>(bd.x())) % static_cast<std::size_t>(bd.y()));
    const int bz = static_cast<int>(bl / (static_cast<std::size_t>(bd.x()) * static_cast<std::size_t>(bd.y())));
    const int next = vm.coarse[bl] + 1;
    if (next > 255) continue;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i b(bx + dx, by + dy, bz + dz);
          if ((b.array() < 0).any() || (b.array() >= bd.array()).any()) continue;
          const std::size_t nb = vps::block_linear(vm, b);
          if (vm.coarse[nb] <= next) continue;
          vm.coarse[nb] = static_cast<std::uint8_t>(next);
          queue.push_back(nb);
        }
      }
    }
  }
  // The engine culls on a lower bound in voxels: a block c blocks away has
  // at least c - 1 whole blocks between, plus one voxel.
  for (std::uint8_t& c : vm.coarse)
    if (c != 0) c = static_cast<std::uint8_t>(std::min(255, (c - 1) * vps::kBlockDim + 1));
  if (now_ns != nullptr) rep.snapshot_ns = now_ns() - t_begin;
  m.snap_stats = rep;
  *out = std::move(vm);
  return std::nullopt;
}

std::size_t LiveVoxmap::cells() const { return impl_->cells.size(); }
std::size_t LiveVoxmap::occupied_cells() const {
  std::size_t n = 0;
  for (const auto& [k, c] : impl_->cells) n += c.log_odds >= impl_->p.occupied ? 1 : 0;
  return n;
}
std::size_t LiveVoxmap::memory_bytes() const {
  const auto& c = impl_->cells;
  // A node holds the value and a next pointer; the bucket array one pointer per bucket.
  return c.size() * (sizeof(std::pair<const std::uint64_t, Cell>) + sizeof(void*)) + c.bucket_count() * sizeof(void*);
}
const LiveVoxmapStats& LiveVoxmap::stats() const { return impl_->stats; }
const LiveVoxmapSnapshotReport& LiveVoxmap::snapshot_report() const { return impl_->snap_stats; }
const Shape3dModel& LiveVoxmap::shapes() const { return impl_->shapes; }
const std::vector<CellSample3>& LiveVoxmap::shape_samples() const { return impl_->shape_samples; }
std::size_t LiveVoxmap::free_space_bytes() const { return impl_->free_grid.capacity(); }
bool LiveVoxmap::recorded_free(const Eigen::Vector3d& x) const { return impl_->is_free(impl_->index(x)); }
const LiveVoxmapParams& LiveVoxmap::params() const { return impl_->p; }

}  // namespace hemm::mapping
