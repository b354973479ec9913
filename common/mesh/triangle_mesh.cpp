#include "common/mesh/triangle_mesh.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace hemm::mesh {

namespace {
std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (static_cast<std::uint64_t>(a) << 32) | b;
}
}  // namespace

double mesh_area(const TriangleMesh& mesh) {
  double a = 0.0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d& p0 = mesh.vertices[t[0]];
    a += 0.5 * (mesh.vertices[t[1]] - p0).cross(mesh.vertices[t[2]] - p0).norm();
  }
  return a;
}

Eigen::AlignedBox3d mesh_bounds(const TriangleMesh& mesh) {
  Eigen::AlignedBox3d b;
  for (const auto& v : mesh.vertices) b.extend(v);
  return b;
}

std::size_t weld_identical_vertices(TriangleMesh* m) {
  struct Hash {
    std::size_t operator()(const std::array<double, 3>& a) const {
      std::size_t h = 0;
      for (double d : a) h = h * 1000003u ^ std::hash<double>()(d);
      return h;
    }
  };
  std::unordered_map<std::array<double, 3>, std::uint32_t, Hash> ids;
  ids.reserve(m->vertices.size());
  std::vector<std::uint32_t> remap(m->vertices.size());
  std::vector<Eigen::Vector3d> kept;
  kept.reserve(m->vertices.size());
  for (std::size_t i = 0; i < m->vertices.size(); ++i) {
    const Eigen::Vector3d& v = m->vertices[i];
    const auto [it, inserted] = ids.try_emplace({v.x(), v.y(), v.z()}, static_cast<std::uint32_t>(kept.size()));
    if (inserted) kept.push_back(v);
    remap[i] = it->second;
  }
  const std::size_t merged = m->vertices.size() - kept.size();
  for (auto& t : m->triangles)
    for (auto& k : t)
      if (k < remap.size()) k = remap[k];
  m->vertices = std::move(kept);
  return merged;
}

void append_mesh(TriangleMesh* a, const TriangleMesh& b, const Eigen::Isometry3d& T) {
  const auto base = static_cast<std::uint32_t>(a->vertices.size());
  a->vertices.reserve(a->vertices.size() + b.vertices.size());
  for (const auto& v : b.vertices) a->vertices.push_back(T * v);
  a->triangles.reserve(a->triangles.size() + b.triangles.size());
  for (const auto& t : b.triangles) a->triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

std::optional<MeshError> validate_mesh(const TriangleMesh& in, const MeshLimits& limits,
                                       TriangleMesh* out, MeshReport* report) {
  if (in.vertices.empty() || in.triangles.empty()) return MeshError{"mesh is empty (no vertices or no triangles)"};
  if (in.triangles.size() > limits.max_triangles)
    return MeshError{"mesh has " + std::to_string(in.triangles.size()) + " triangles, more than the limit of " +
                     std::to_string(limits.max_triangles)};
  if (in.vertices.size() >= 0xFFFFFFFFull) return MeshError{"too many vertices"};
  for (std::size_t i = 0; i < in.vertices.size(); ++i) {
    if (!in.vertices[i].allFinite())
      return MeshError{"vertex " + std::to_string(i) + " has a non-finite coordinate (NaN or inf)"};
  }
  MeshReport r;
  r.input_triangles = in.triangles.size();
  TriangleMesh m;
  m.vertices = in.vertices;
  m.triangles.reserve(in.triangles.size());
  std::vector<char> used(in.vertices.size(), 0);
  for (std::size_t i = 0; i < in.triangles.size(); ++i) {
    const auto& t = in.triangles[i];
    for (int k = 0; k < 3; ++k) {
      if (t[k] >= in.vertices.size())
        return MeshError{"triangle " + std::to_string(i) + " refers to vertex " + std::to_string(t[k]) +
                         " but the mesh has " + std::to_string(in.vertices.size()) + " vertices"};
    }
    const Eigen::Vector3d& a = in.vertices[t[0]];
    const double area = 0.5 * (in.vertices[t[1]] - a).cross(in.vertices[t[2]] - a).norm();
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || !(area > limits.degenerate_area)) {
      ++r.degenerate_dropped;
      continue;
    }
    m.triangles.push_back(t);
    for (int k = 0; k < 3; ++k) used[t[k]] = 1;
  }
  if (m.triangles.empty()) return MeshError{"no triangle left after dropping degenerate ones"};
  for (std::size_t i = 0; i < used.size(); ++i) {
    if (used[i]) {
      r.bounds.extend(m.vertices[i]);
    } else {
      ++r.unused_vertices;
    }
  }
  const double extent = r.bounds.sizes().maxCoeff();
  if (!(extent <= limits.max_extent))
    return MeshError{"mesh extent " + std::to_string(extent) + " m exceeds the limit of " +
                     std::to_string(limits.max_extent) + " m (wrong units?)"};
  if (!(extent >= limits.min_extent))
    return MeshError{"mesh extent " + std::to_string(extent) + " m is below the limit of " +
                     std::to_string(limits.min_extent) + " m (zero-size mesh?)"};

  // Edge topology: undirected use counts and directed duplicates.
  std::unordered_map<std::uint64_t, int> directed;
  directed.reserve(m.triangles.size() * 3);
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) ++directed[edge_key(t[k], t[(k + 1) % 3])];
  }
  for (const auto& [key, n] : directed) {
    const auto a = static_cast<std::uint32_t>(key >> 32);
    const auto b = static_cast<std::uint32_t>(key & 0xFFFFFFFFu);
    if (n > 1) ++r.inconsistent_edges;
    const auto rev = directed.find(edge_key(b, a));
    const int reverse = rev == directed.end() ? 0 : rev->second;
    // Count each undirected edge once (from its smaller-first direction, or
    // from the only direction that exists).
    if (a < b || reverse == 0) {
      const int uses = n + reverse;
      if (uses == 1) ++r.boundary_edges;
      if (uses >= 3) ++r.nonmanifold_edges;
      if (uses == 2 && n == 2) {
        // Same direction twice: a flipped neighbour (already counted as inconsistent).
      }
    }
  }
  r.closed = r.boundary_edges == 0 && r.nonmanifold_edges == 0;
  r.consistently_oriented = r.inconsistent_edges == 0;
  double vol = 0.0;
  for (const auto& t : m.triangles) vol += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6.0;
  if (r.watertight() && vol < 0.0) {
    for (auto& t : m.triangles) std::swap(t[1], t[2]);
    vol = -vol;
    r.flipped = true;
  }
  r.signed_volume = vol;
  r.area = mesh_area(m);
  *out = std::move(m);
  *report = r;
  return std::nullopt;
}

MassProperties compute_mass_properties(const TriangleMesh& mesh, double density) {
  // Tetrahedra (0, a, b, c): volume det/6, first moment det/24 (a+b+c),
  // second moment det/120 (aa' + bb' + cc' + (a+b+c)(a+b+c)').
  double vol = 0.0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  // Shift to the bounding-box centre first for numerical accuracy.
  const Eigen::Vector3d o = mesh_bounds(mesh).center();
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]] - o, b = mesh.vertices[t[1]] - o, c = mesh.vertices[t[2]] - o;
    const double det = a.dot(b.cross(c));
    vol += det / 6.0;
    const Eigen::Vector3d s = a + b + c;
    first += det / 24.0 * s;
    second += det / 120.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
  MassProperties p;
  p.volume = vol;
  p.mass = density * vol;
  if (std::abs(vol) < 1e-300) return p;
  const Eigen::Vector3d com = first / vol;
  p.centre_of_mass = com + o;
  const Eigen::Matrix3d cov = density * (second - vol * com * com.transpose());
  p.inertia_com = cov.trace() * Eigen::Matrix3d::Identity() - cov;
  return p;
}

}  // namespace hemm::mesh
