#include "robot_side/truth/voxmap_coverage.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

namespace hemm::robot {
namespace {

// Distance along unit d from o to the triangle (a, b, c) (Moller-Trumbore),
// or a negative number if the ray misses it.
double ray_triangle(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d p = d.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-15) return -1.0;
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = o - a;
  const double u = s.dot(p) * inv;
  if (u < 0.0 || u > 1.0) return -1.0;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < 0.0 || u + v > 1.0) return -1.0;
  return e2.dot(q) * inv;
}

// Distance along unit d from o into the box, or a negative number if the ray misses it.
double ray_box(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (o[k] < box.min()[k] || o[k] > box.max()[k]) return -1.0;
      continue;
    }
    double a = (box.min()[k] - o[k]) / d[k], b = (box.max()[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return -1.0;
  }
  return t0;
}

// Samples of the meshes' faces turned toward o, unoccluded from o, and
// accepted by in_view(x) (the camera's image and range limits).
template <class InView>
std::vector<Eigen::Vector3d> samples_seen_from(const std::vector<const mesh::TriangleMesh*>& meshes, const Eigen::Vector3d& o,
                                               const VisibleSurfaceParams& params, const InView& in_view) {
  std::vector<Eigen::AlignedBox3d> bounds;
  for (const mesh::TriangleMesh* m : meshes) {
    Eigen::AlignedBox3d b;
    for (const Eigen::Vector3d& v : m->vertices) b.extend(v);
    bounds.push_back(b);
  }
  std::mt19937_64 rng(params.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<Eigen::Vector3d> out;
  for (const mesh::TriangleMesh* m : meshes) {
    for (const auto& t : m->triangles) {
      const Eigen::Vector3d& a = m->vertices[t[0]];
      const Eigen::Vector3d& b = m->vertices[t[1]];
      const Eigen::Vector3d& c = m->vertices[t[2]];
      const Eigen::Vector3d n2 = (b - a).cross(c - a);  // outward, twice the area
      const double expected = 0.5 * n2.norm() * params.density;
      // The fractional part drawn at random keeps the density exact on small triangles.
      auto count = static_cast<std::size_t>(std::floor(expected));
      if (uni(rng) < expected - std::floor(expected)) ++count;
      for (std::size_t i = 0; i < count; ++i) {
        double r1 = uni(rng), r2 = uni(rng);
        if (r1 + r2 > 1.0) {
          r1 = 1.0 - r1;
          r2 = 1.0 - r2;
        }
        const Eigen::Vector3d x = a + r1 * (b - a) + r2 * (c - a);
        if (!params.region.contains(x)) continue;
        if (n2.dot(o - x) <= 0.0) continue;  // a face turned away
        if (!in_view(x)) continue;
        const double range = (x - o).norm();
        const Eigen::Vector3d d = (x - o) / range;
        const double limit = range - params.tolerance;
        bool hidden = false;
        for (std::size_t j = 0; j < meshes.size() && !hidden; ++j) {
          const double tb = ray_box(bounds[j], o, d);
          if (tb < 0.0 || tb >= limit) continue;
          const mesh::TriangleMesh& mj = *meshes[j];
          for (const auto& tj : mj.triangles) {
            const double th = ray_triangle(o, d, mj.vertices[tj[0]], mj.vertices[tj[1]], mj.vertices[tj[2]]);
            if (th > 0.0 && th < limit) {
              hidden = true;
              break;
            }
          }
        }
        if (!hidden) out.push_back(x);
      }
    }
  }
  return out;
}

}  // namespace

std::vector<Eigen::Vector3d> visible_surface_samples(const std::vector<const mesh::TriangleMesh*>& meshes,
                                                     const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_W_S,
                                                     const VisibleSurfaceParams& params) {
  const Eigen::Isometry3d T_S_W = T_W_S.inverse();
  return samples_seen_from(meshes, T_W_S.translation(), params, [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3d x_S = T_S_W * x;
    if (x_S.z() <= 0.0) return false;
    const double u = K.fx * x_S.x() / x_S.z() + K.cx, v = K.fy * x_S.y() / x_S.z() + K.cy;
    if (u < 0.0 || u >= K.width || v < 0.0 || v >= K.height) return false;
    const double range = x_S.norm();
    return range >= K.range_min && range <= K.range_max;
  });
}

std::vector<Eigen::Vector3d> surface_samples_seen_from(const std::vector<const mesh::TriangleMesh*>& meshes,
                                                       const Eigen::Vector3d& o_W, double range_min, double range_max,
                                                       const VisibleSurfaceParams& params) {
  return samples_seen_from(meshes, o_W, params, [&](const Eigen::Vector3d& x) {
    const double range = (x - o_W).norm();
    return range >= range_min && range <= range_max;
  });
}

double surface_coverage(const vps::Voxmap& vm, const std::vector<Eigen::Vector3d>& samples, int reach) {
  if (samples.empty()) return 0.0;
  std::size_t covered = 0;
  for (const Eigen::Vector3d& x : samples) {
    const Eigen::Vector3i v = vps::voxel_of(vm, x);
    bool near = false;
    for (int dz = -reach; dz <= reach && !near; ++dz)
      for (int dy = -reach; dy <= reach && !near; ++dy)
        for (int dx = -reach; dx <= reach && !near; ++dx)
          near = vps::sample_voxel(vm, v + Eigen::Vector3i(dx, dy, dz)).layer == 0;
    covered += near ? 1 : 0;
  }
  return static_cast<double>(covered) / static_cast<double>(samples.size());
}

}  // namespace hemm::robot
