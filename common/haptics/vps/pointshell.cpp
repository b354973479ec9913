#include "common/haptics/vps/pointshell.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "common/haptics/vps/geometry.h"

namespace hemm::vps {

namespace {

std::uint64_t voxel_key(const Eigen::Vector3i& v) {
  return static_cast<std::uint64_t>(v.x()) | (static_cast<std::uint64_t>(v.y()) << 21) |
         (static_cast<std::uint64_t>(v.z()) << 42);
}

// Area of triangle (a, b, c) inside the box [lo, hi] (Sutherland-Hodgman).
double clipped_area(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                    const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  Eigen::Vector3d buf[2][12];
  int n = 3;
  buf[0][0] = a;
  buf[0][1] = b;
  buf[0][2] = c;
  int cur = 0;
  for (int plane = 0; plane < 6 && n > 0; ++plane) {
    const int ax = plane / 2;
    const bool upper = plane % 2;
    const double lim = upper ? hi[ax] : lo[ax];
    auto inside = [&](const Eigen::Vector3d& p) { return upper ? p[ax] <= lim : p[ax] >= lim; };
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d& p = buf[cur][i];
      const Eigen::Vector3d& q = buf[cur][(i + 1) % n];
      const bool pin = inside(p), qin = inside(q);
      if (pin) buf[1 - cur][m++] = p;
      if (pin != qin) {
        const double t = (lim - p[ax]) / (q[ax] - p[ax]);
        buf[1 - cur][m++] = p + t * (q - p);
      }
    }
    n = m;
    cur = 1 - cur;
  }
  if (n < 3) return 0.0;
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (int i = 1; i + 1 < n; ++i) acc += (buf[cur][i] - buf[cur][0]).cross(buf[cur][i + 1] - buf[cur][0]);
  return 0.5 * acc.norm();
}

int build_node(PointShell* ps, std::vector<std::int32_t>* perm, int first, int count, int leaf_size, int depth) {
  Eigen::AlignedBox3d box;
  for (int i = first; i < first + count; ++i) box.extend(ps->points[static_cast<std::size_t>((*perm)[i])]);
  SphereNode node;
  node.centre = box.center();
  node.radius = 0.0;
  for (int i = first; i < first + count; ++i)
    node.radius = std::max(node.radius, (ps->points[static_cast<std::size_t>((*perm)[i])] - node.centre).norm());
  node.first = first;
  node.count = count;
  node.left = node.right = -1;
  const int id = static_cast<int>(ps->nodes.size());
  ps->nodes.push_back(node);
  ps->depth = std::max(ps->depth, depth);
  if (count <= leaf_size) return id;
  int axis;
  box.sizes().maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(perm->begin() + first, perm->begin() + first + half, perm->begin() + first + count,
                   [&](std::int32_t a, std::int32_t b) {
                     return ps->points[static_cast<std::size_t>(a)][axis] < ps->points[static_cast<std::size_t>(b)][axis];
                   });
  const int l = build_node(ps, perm, first, half, leaf_size, depth + 1);
  const int r = build_node(ps, perm, first + half, count - half, leaf_size, depth + 1);
  ps->nodes[static_cast<std::size_t>(id)].left = l;
  ps->nodes[static_cast<std::size_t>(id)].right = r;
  return id;
}

}  // namespace

void build_sphere_tree(PointShell* ps, int leaf_size) {
  ps->nodes.clear();
  ps->depth = 0;
  const int n = static_cast<int>(ps->points.size());
  if (n == 0) return;
  std::vector<std::int32_t> perm(static_cast<std::size_t>(n));
  std::iota(perm.begin(), perm.end(), 0);
  build_node(ps, &perm, 0, n, std::max(1, leaf_size), 0);
  auto reorder = [&](auto& v) {
    auto copy = v;
    for (std::size_t i = 0; i < perm.size(); ++i) v[i] = copy[static_cast<std::size_t>(perm[i])];
  };
  reorder(ps->points);
  reorder(ps->normals);
  reorder(ps->weights);
}

std::optional<VpsError> build_pointshell(const mesh::TriangleMesh& mesh, const PointShellParams& params,
                                         const Eigen::Vector3d& reference_point, PointShell* out) {
  if (!reference_point.allFinite()) return VpsError{"reference point is not finite"};
  if (params.leaf_size < 1 || params.leaf_size > 4096) return VpsError{"leaf size must be in 1..4096"};
  VoxmapParams vp;
  vp.voxel_size = params.voxel_size;
  vp.layers_in = 2;
  vp.layers_out = 2;
  vp.limits = params.limits;
  Voxmap vm;
  VoxmapBuildInfo info;
  if (auto e = build_voxmap(mesh, vp, &vm, &info)) return e;
  const mesh::TriangleMesh& m = info.mesh;
  const double s = vm.voxel_size;
  PointShell ps;
  ps.voxel_size = s;
  ps.reference_point = reference_point;
  const std::size_t n = info.surface_index.size();
  std::unordered_map<std::uint64_t, std::size_t> index;
  index.reserve(n * 2);
  for (std::size_t k = 0; k < n; ++k) index.emplace(voxel_key(info.surface_index[k]), k);
  // Each triangle's area is split over the surface voxels it crosses by
  // clipping. Voxel bounds are origin + i s on both sides of a face so no area
  // falls between voxels, and the parts are rescaled to the triangle's area so
  // a face lying exactly on a voxel boundary is not counted twice.
  struct Part {
    std::size_t voxel;
    std::int32_t tri;
    double area;
  };
  std::vector<Part> parts, tri_parts;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const auto& tr = m.triangles[t];
    const Eigen::Vector3d& a = m.vertices[tr[0]];
    const Eigen::Vector3d& b = m.vertices[tr[1]];
    const Eigen::Vector3d& c = m.vertices[tr[2]];
    const Eigen::Vector3i lo = voxel_of(vm, a.cwiseMin(b).cwiseMin(c)) - Eigen::Vector3i::Ones();
    const Eigen::Vector3i hi = voxel_of(vm, a.cwiseMax(b).cwiseMax(c)) + Eigen::Vector3i::Ones();
    tri_parts.clear();
    double sum = 0.0;
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const Eigen::Vector3i v(x, y, z);
          const auto it = index.find(voxel_key(v));
          if (it == index.end()) continue;
          const Eigen::Vector3d vlo = vm.origin + v.cast<double>() * s;
          const Eigen::Vector3d vhi = vm.origin + (v + Eigen::Vector3i::Ones()).cast<double>() * s;
          const double part = clipped_area(a, b, c, vlo, vhi);
          if (part <= 0.0) continue;
          tri_parts.push_back({it->second, static_cast<std::int32_t>(t), part});
          sum += part;
        }
    if (sum <= 0.0) continue;
    const double scale = 0.5 * (b - a).cross(c - a).norm() / sum;
    for (Part p : tri_parts) {
      p.area *= scale;
      parts.push_back(p);
    }
  }
  std::sort(parts.begin(), parts.end(), [](const Part& x, const Part& y) { return x.voxel < y.voxel; });
  // Per surface voxel, the triangles are grouped by normal (a voxel on an edge
  // or corner holds several faces); each group gives one point: the voxel
  // centre projected onto the group's nearest triangle, with the group's
  // area-weighted inward normal and area.
  struct Group {
    Eigen::Vector3d normal_sum;
    Eigen::Vector3d first_normal;
    double area;
    double best_d2;
    Eigen::Vector3d point;
  };
  const double cos_group = std::cos(35.0 * 3.14159265358979 / 180.0);
  std::vector<Group> groups;
  for (std::size_t i = 0; i < parts.size();) {
    const std::size_t k = parts[i].voxel;
    const Eigen::Vector3d centre = voxel_centre(vm, info.surface_index[k]);
    groups.clear();
    for (; i < parts.size() && parts[i].voxel == k; ++i) {
      const auto& tr = m.triangles[static_cast<std::size_t>(parts[i].tri)];
      const Eigen::Vector3d& a = m.vertices[tr[0]];
      const Eigen::Vector3d& b = m.vertices[tr[1]];
      const Eigen::Vector3d& c = m.vertices[tr[2]];
      const Eigen::Vector3d nt = (b - a).cross(c - a).normalized();
      Group* g = nullptr;
      for (Group& cand : groups) {
        if (cand.first_normal.dot(nt) > cos_group) {
          g = &cand;
          break;
        }
      }
      if (g == nullptr) {
        groups.push_back({Eigen::Vector3d::Zero(), nt, 0.0, std::numeric_limits<double>::infinity(),
                          Eigen::Vector3d::Zero()});
        g = &groups.back();
      }
      g->normal_sum += parts[i].area * nt;
      g->area += parts[i].area;
      // Q = ||T - c||^2 minimised over the group's triangles: the closest point.
      const Eigen::Vector3d q = closest_point_on_triangle(centre, a, b, c).point;
      const double d2 = (q - centre).squaredNorm();
      if (d2 < g->best_d2) {
        g->best_d2 = d2;
        g->point = q;
      }
    }
    for (const Group& g : groups) {
      if (g.area <= 1e-9 * s * s || g.normal_sum.norm() <= 0.0) continue;
      Eigen::Vector3d inward = -g.normal_sum.normalized();
      if (vm.signed_field) {
        const Eigen::Vector3d grad = sdf_gradient(vm, g.point);  // points outward
        if (grad.norm() > 1e-9 && grad.dot(inward) > 0.0) inward = -grad.normalized();
      }
      ps.points.push_back(g.point);
      ps.normals.push_back(inward);
      ps.weights.push_back(params.area_weights ? g.area : 1.0);
    }
  }
  if (ps.points.empty()) return VpsError{"pointshell has no points"};
  ps.total_weight = std::accumulate(ps.weights.begin(), ps.weights.end(), 0.0);
  build_sphere_tree(&ps, params.leaf_size);
  *out = std::move(ps);
  return std::nullopt;
}

}  // namespace hemm::vps
