#include "common/mesh/primitives.h"

#include <cmath>
#include <map>
#include <numbers>

namespace hemm::mesh {

TriangleMesh make_icosphere(double radius, int subdivisions) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& v : m.vertices) v.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      const auto id = static_cast<std::uint32_t>(m.vertices.size() - 1);
      mid.emplace(key, id);
      return id;
    };
    std::vector<std::array<std::uint32_t, 3>> next;
    next.reserve(m.triangles.size() * 4);
    for (const auto& tr : m.triangles) {
      const auto a = midpoint(tr[0], tr[1]), b = midpoint(tr[1], tr[2]), c = midpoint(tr[2], tr[0]);
      next.push_back({tr[0], a, c});
      next.push_back({tr[1], b, a});
      next.push_back({tr[2], c, b});
      next.push_back({a, b, c});
    }
    m.triangles = std::move(next);
  }
  for (auto& v : m.vertices) v *= radius;
  return m;
}

TriangleMesh make_uv_sphere(double radius, int slices, int stacks) {
  TriangleMesh m;
  const double pi = std::numbers::pi;
  m.vertices.push_back({0, 0, radius});
  for (int i = 1; i < stacks; ++i) {
    const double th = pi * i / stacks;
    for (int j = 0; j < slices; ++j) {
      const double ph = 2 * pi * j / slices;
      m.vertices.push_back(radius * Eigen::Vector3d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  }
  m.vertices.push_back({0, 0, -radius});
  const auto south = static_cast<std::uint32_t>(m.vertices.size() - 1);
  auto ring = [&](int i, int j) { return static_cast<std::uint32_t>(1 + (i - 1) * slices + (j % slices)); };
  for (int j = 0; j < slices; ++j) m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i + 1 < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  }
  for (int j = 0; j < slices; ++j) m.triangles.push_back({south, ring(stacks - 1, j + 1), ring(stacks - 1, j)});
  return m;
}

TriangleMesh make_cylinder(double radius, double half_height, int slices) {
  TriangleMesh m;
  const double pi = std::numbers::pi;
  for (int j = 0; j < slices; ++j) {
    const double ph = 2 * pi * j / slices;
    const Eigen::Vector2d c(radius * std::cos(ph), radius * std::sin(ph));
    m.vertices.push_back({c.x(), c.y(), -half_height});
    m.vertices.push_back({c.x(), c.y(), half_height});
  }
  const auto bottom = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.push_back({0, 0, -half_height});
  m.vertices.push_back({0, 0, half_height});
  const std::uint32_t top = bottom + 1;
  auto lo = [&](int j) { return static_cast<std::uint32_t>(2 * (j % slices)); };
  auto hi = [&](int j) { return static_cast<std::uint32_t>(2 * (j % slices) + 1); };
  for (int j = 0; j < slices; ++j) {
    m.triangles.push_back({lo(j), lo(j + 1), hi(j + 1)});  // side, outward
    m.triangles.push_back({lo(j), hi(j + 1), hi(j)});
    m.triangles.push_back({top, hi(j), hi(j + 1)});        // top cap, +z
    m.triangles.push_back({bottom, lo(j + 1), lo(j)});     // bottom cap, -z
  }
  return m;
}

TriangleMesh make_box(const Eigen::Vector3d& h, int n) {
  TriangleMesh m;
  // For each face: normal axis a, sign s; grid over the other two axes (u, v)
  // with u x v = s * e_a so the winding is outward.
  for (int a = 0; a < 3; ++a) {
    for (int s = -1; s <= 1; s += 2) {
      int u = (a + 1) % 3, v = (a + 2) % 3;
      if (s < 0) std::swap(u, v);
      const auto base = static_cast<std::uint32_t>(m.vertices.size());
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; j <= n; ++j) {
          Eigen::Vector3d p;
          p[a] = s * h[a];
          p[u] = -h[u] + 2 * h[u] * i / n;
          p[v] = -h[v] + 2 * h[v] * j / n;
          m.vertices.push_back(p);
        }
      }
      auto id = [&](int i, int j) { return base + static_cast<std::uint32_t>(i * (n + 1) + j); };
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
          m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
      }
    }
  }
  // Weld the shared edge vertices so the box is closed.
  std::map<std::array<long long, 3>, std::uint32_t> weld;
  std::vector<std::uint32_t> remap(m.vertices.size());
  TriangleMesh w;
  const double q = 1e-9 * std::max(1e-12, h.maxCoeff());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const std::array<long long, 3> key = {std::llround(m.vertices[i].x() / q), std::llround(m.vertices[i].y() / q),
                                          std::llround(m.vertices[i].z() / q)};
    auto it = weld.find(key);
    if (it == weld.end()) {
      w.vertices.push_back(m.vertices[i]);
      it = weld.emplace(key, static_cast<std::uint32_t>(w.vertices.size() - 1)).first;
    }
    remap[i] = it->second;
  }
  for (const auto& t : m.triangles) w.triangles.push_back({remap[t[0]], remap[t[1]], remap[t[2]]});
  return w;
}

TriangleMesh make_rectilinear_solid(const std::vector<double>& xs, const std::vector<double>& ys,
                                    const std::vector<double>& zs,
                                    const std::function<bool(int, int, int)>& filled) {
  const int nx = static_cast<int>(xs.size()) - 1, ny = static_cast<int>(ys.size()) - 1,
            nz = static_cast<int>(zs.size()) - 1;
  const std::vector<double>* g[3] = {&xs, &ys, &zs};
  auto in = [&](int i, int j, int k) {
    return i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz && filled(i, j, k);
  };
  TriangleMesh m;
  std::map<std::array<int, 3>, std::uint32_t> vid;
  auto vertex = [&](std::array<int, 3> c) {
    auto it = vid.find(c);
    if (it != vid.end()) return it->second;
    m.vertices.push_back({(*g[0])[c[0]], (*g[1])[c[1]], (*g[2])[c[2]]});
    const auto id = static_cast<std::uint32_t>(m.vertices.size() - 1);
    vid.emplace(c, id);
    return id;
  };
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        if (!in(i, j, k)) continue;
        const std::array<int, 3> c = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          for (int s = -1; s <= 1; s += 2) {
            std::array<int, 3> nb = c;
            nb[a] += s;
            if (in(nb[0], nb[1], nb[2])) continue;
            int u = (a + 1) % 3, v = (a + 2) % 3;
            if (s < 0) std::swap(u, v);
            std::array<int, 3> p0 = c;
            p0[a] += s > 0 ? 1 : 0;
            std::array<int, 3> p1 = p0, p2 = p0, p3 = p0;
            p1[u] += 1;
            p2[u] += 1;
            p2[v] += 1;
            p3[v] += 1;
            const auto a0 = vertex(p0), a1 = vertex(p1), a2 = vertex(p2), a3 = vertex(p3);
            m.triangles.push_back({a0, a1, a2});
            m.triangles.push_back({a0, a2, a3});
          }
        }
      }
    }
  }
  return m;
}

TriangleMesh make_open_sheet(double half_size, int n) {
  TriangleMesh m;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      m.vertices.push_back({-half_size + 2 * half_size * i / n, -half_size + 2 * half_size * j / n, 0.0});
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(i * (n + 1) + j); };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return m;
}

}  // namespace hemm::mesh
