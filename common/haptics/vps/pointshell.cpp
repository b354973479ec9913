#include "common/haptics/vps/pointshell.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <string>
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

// One sphere tree over points [first, first + count) of the level arrays
// (perm holds indices into the level's input order); returns the node index.
struct TreeBuilder {
  const std::vector<Eigen::Vector3d>& pts;
  std::vector<std::int32_t>& perm;
  std::vector<SphereNode>& nodes;
  std::vector<std::int32_t>& parent;
  int leaf_size;
  int offset;  // position of perm[0] in the shell's arrays

  std::int32_t build(int first, int count, std::int32_t up) {
    Eigen::AlignedBox3d box;
    for (int i = first; i < first + count; ++i) box.extend(pts[static_cast<std::size_t>(perm[static_cast<std::size_t>(i)])]);
    const Eigen::Vector3d c = box.center();
    const Eigen::Vector3f cf = c.cast<float>();
    double r = 0.0;
    for (int i = first; i < first + count; ++i)
      r = std::max(r, (pts[static_cast<std::size_t>(perm[static_cast<std::size_t>(i)])] - cf.cast<double>()).norm());
    // Rounded up so the float sphere still holds every point.
    SphereNode node{cf.x(), cf.y(), cf.z(), static_cast<float>(r * (1 + 1e-6) + 1e-9), offset + first, count, -1, -1};
    const auto id = static_cast<std::int32_t>(nodes.size());
    nodes.push_back(node);
    parent.push_back(up);
    if (count <= leaf_size) return id;
    int axis;
    box.sizes().maxCoeff(&axis);
    const int half = count / 2;
    std::nth_element(perm.begin() + first, perm.begin() + first + half, perm.begin() + first + count,
                     [&](std::int32_t a, std::int32_t b) {
                       return pts[static_cast<std::size_t>(a)][axis] < pts[static_cast<std::size_t>(b)][axis];
                     });
    const std::int32_t l = build(first, half, id);
    const std::int32_t rr = build(first + half, count - half, id);
    nodes[static_cast<std::size_t>(id)].left = l;
    nodes[static_cast<std::size_t>(id)].right = rr;
    return id;
  }
};

}  // namespace

std::optional<VpsError> build_pointshell_from_points(const std::vector<Eigen::Vector3d>& points,
                                                     const std::vector<Eigen::Vector3d>& normals,
                                                     const std::vector<double>& weights, double voxel_size,
                                                     int levels, int leaf_size,
                                                     const Eigen::Vector3d& reference_point, PointShell* out) {
  const std::size_t n = points.size();
  if (n == 0) return VpsError{"pointshell has no points"};
  if (normals.size() != n || weights.size() != n) return VpsError{"points, normals and weights differ in number"};
  if (n > (std::size_t{1} << 30)) return VpsError{"pointshell has too many points"};
  if (!(voxel_size > 0) || !std::isfinite(voxel_size)) return VpsError{"pointshell voxel size must be positive"};
  if (levels < 1 || levels > kMaxShellLevels) return VpsError{"pointshell levels must be in 1..6"};
  if (leaf_size < 1) return VpsError{"leaf size must be at least 1"};
  if (!reference_point.allFinite()) return VpsError{"reference point is not finite"};
  Eigen::AlignedBox3d bounds;
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite() || !normals[i].allFinite() || std::abs(normals[i].norm() - 1.0) > 1e-6 ||
        !std::isfinite(weights[i]) || weights[i] < 0)
      return VpsError{"invalid point " + std::to_string(i)};
    bounds.extend(points[i]);
  }
  // Levels from the finest down: level l keeps, per cell of spacing * 2^k
  // and normal group, the point of level l+1 nearest the group's centroid;
  // its weight is the group's. Stop early when a level would be tiny or its
  // cells as large as the object.
  const double cos_group = std::cos(35.0 * std::numbers::pi / 180.0);
  std::vector<std::vector<std::int32_t>> members;  // members[k]: point indices of level (finest - k)
  std::vector<std::vector<double>> wts;            // their weights at that level
  members.emplace_back(n);
  std::iota(members[0].begin(), members[0].end(), 0);
  wts.emplace_back(weights);
  struct Item {
    std::uint64_t cell;
    std::int32_t idx;
    double w;
  };
  std::vector<Item> items;
  for (int k = 1; k < levels; ++k) {
    const double cell = voxel_size * std::ldexp(1.0, k);
    if (cell > 0.5 * bounds.sizes().maxCoeff()) break;
    const std::vector<std::int32_t>& prev = members.back();
    const std::vector<double>& pw = wts.back();
    items.clear();
    for (std::size_t j = 0; j < prev.size(); ++j) {
      const Eigen::Vector3d g = (points[static_cast<std::size_t>(prev[j])] - bounds.min()) / cell;
      const auto key = static_cast<std::uint64_t>(g.x()) | (static_cast<std::uint64_t>(g.y()) << 21) |
                       (static_cast<std::uint64_t>(g.z()) << 42);
      items.push_back({key, prev[j], pw[j]});
    }
    std::sort(items.begin(), items.end(), [](const Item& a, const Item& b) { return a.cell < b.cell; });
    std::vector<std::int32_t> next;
    std::vector<double> next_w;
    struct Group {
      Eigen::Vector3d normal, centroid;
      double w;
      std::vector<std::int32_t> idx;
    };
    std::vector<Group> groups;
    for (std::size_t i = 0; i < items.size();) {
      const std::uint64_t key = items[i].cell;
      groups.clear();
      for (; i < items.size() && items[i].cell == key; ++i) {
        const auto pi = static_cast<std::size_t>(items[i].idx);
        Group* g = nullptr;
        for (Group& c : groups)
          if (c.normal.dot(normals[pi]) > cos_group) {
            g = &c;
            break;
          }
        if (g == nullptr) {
          groups.push_back({normals[pi], Eigen::Vector3d::Zero(), 0.0, {}});
          g = &groups.back();
        }
        g->centroid += items[i].w * points[pi];
        g->w += items[i].w;
        g->idx.push_back(items[i].idx);
      }
      for (Group& g : groups) {
        const Eigen::Vector3d c = g.w > 0 ? Eigen::Vector3d(g.centroid / g.w) : points[static_cast<std::size_t>(g.idx[0])];
        std::int32_t best = g.idx[0];
        for (const std::int32_t j : g.idx)
          if ((points[static_cast<std::size_t>(j)] - c).squaredNorm() <
              (points[static_cast<std::size_t>(best)] - c).squaredNorm())
            best = j;
        next.push_back(best);
        next_w.push_back(g.w);
      }
    }
    if (next.size() < 16 || next.size() == prev.size()) break;
    members.push_back(std::move(next));
    wts.push_back(std::move(next_w));
  }
  const int L = static_cast<int>(members.size());  // levels built; level l is members[L - 1 - l]
  std::vector<std::int32_t> first_level(n, L - 1);
  std::vector<std::array<float, kMaxShellLevels>> lw(n);
  for (auto& a : lw) a.fill(0.0f);
  for (int l = 0; l < L; ++l) {
    const auto& m = members[static_cast<std::size_t>(L - 1 - l)];
    const auto& w = wts[static_cast<std::size_t>(L - 1 - l)];
    for (std::size_t j = 0; j < m.size(); ++j) {
      const auto i = static_cast<std::size_t>(m[j]);
      first_level[i] = std::min(first_level[i], l);
      lw[i][static_cast<std::size_t>(l)] = static_cast<float>(w[j]);
    }
  }
  PointShell ps;
  ps.voxel_size = voxel_size;
  ps.reference_point = reference_point;
  ps.levels = L;
  // The tree over all points fixes the order of the point arrays.
  std::vector<std::int32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  {
    TreeBuilder tb{points, order, ps.nodes, ps.parent, leaf_size, 0};
    tb.build(0, static_cast<int>(n), -1);
  }
  std::vector<std::int32_t> pos_of(n);
  for (std::size_t j = 0; j < n; ++j) pos_of[static_cast<std::size_t>(order[j])] = static_cast<std::int32_t>(j);
  for (int l = 0; l < L; ++l) {
    std::vector<std::int32_t> perm;
    for (std::size_t i = 0; i < n; ++i)
      if (first_level[i] == l) perm.push_back(static_cast<std::int32_t>(i));
    ShellLevel& lev = ps.level[static_cast<std::size_t>(l)];
    lev.first = static_cast<std::int32_t>(ps.level_index.size());
    lev.count = static_cast<std::int32_t>(perm.size());
    lev.spacing = voxel_size * std::ldexp(1.0, L - 1 - l);
    if (!perm.empty()) {
      const auto before = static_cast<std::int32_t>(ps.level_nodes.size());
      TreeBuilder tb{points, perm, ps.level_nodes, ps.level_parent, leaf_size, lev.first};
      lev.root = tb.build(0, static_cast<int>(perm.size()), -1);
      lev.node_count = static_cast<std::int32_t>(ps.level_nodes.size()) - before;
    }
    for (const std::int32_t i : perm) ps.level_index.push_back(pos_of[static_cast<std::size_t>(i)]);
  }
  for (const std::int32_t oi : order) {
    const auto i = static_cast<std::size_t>(oi);
    ps.px.push_back(static_cast<float>(points[i].x()));
    ps.py.push_back(static_cast<float>(points[i].y()));
    ps.pz.push_back(static_cast<float>(points[i].z()));
    ps.nx.push_back(static_cast<float>(normals[i].x()));
    ps.ny.push_back(static_cast<float>(normals[i].y()));
    ps.nz.push_back(static_cast<float>(normals[i].z()));
    ps.weight.push_back(lw[i][static_cast<std::size_t>(L - 1)]);
    ps.point_level.push_back(first_level[i]);
    for (int l = 0; l < kMaxShellLevels; ++l) ps.level_weight.push_back(lw[i][static_cast<std::size_t>(l)]);
  }
  for (int l = 0; l < L; ++l) {
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) sum += ps.level_weight[i * kMaxShellLevels + static_cast<std::size_t>(l)];
    ps.level[static_cast<std::size_t>(l)].total_weight = sum;
  }
  ps.total_weight = ps.level[static_cast<std::size_t>(L - 1)].total_weight;
  *out = std::move(ps);
  return std::nullopt;
}

std::optional<VpsError> build_pointshell(const mesh::TriangleMesh& mesh, const PointShellParams& params,
                                         const Eigen::Vector3d& reference_point, PointShell* out) {
  if (!reference_point.allFinite()) return VpsError{"reference point is not finite"};
  if (params.leaf_size < 1 || params.leaf_size > 4096) return VpsError{"leaf size must be in 1..4096"};
  if (params.levels < 1 || params.levels > kMaxShellLevels) return VpsError{"pointshell levels must be in 1..6"};
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
  std::vector<Eigen::Vector3d> pts, nrm;
  std::vector<double> wts;
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
  const double cos_group = std::cos(35.0 * std::numbers::pi / 180.0);
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
      pts.push_back(g.point);
      nrm.push_back(inward);
      wts.push_back(params.area_weights ? g.area : 1.0);
    }
  }
  if (pts.empty()) return VpsError{"pointshell has no points"};
  return build_pointshell_from_points(pts, nrm, wts, s, params.levels, params.leaf_size, reference_point, out);
}

}  // namespace hemm::vps
