#include "common/haptics/vps/voxmap.h"

#include <cmath>
#include <deque>
#include <limits>
#include <unordered_map>

#include "common/haptics/vps/geometry.h"

namespace hemm::vps {

namespace {

constexpr std::int8_t kUnset = -128;
constexpr std::int32_t kNoSheet = -1;
constexpr std::int32_t kThinNoSheet = -2;  // thin surface voxel of a point cloud (no normal)

// The sheet through a thin surface voxel: + face plane (unit normal n through
// the point q) and the wall thickness behind it.
struct SheetSource {
  Eigen::Vector3d n;
  Eigen::Vector3d q;
  double thickness;
};

struct BuildBlock {
  std::array<float, kBlockVoxels> dist;
  std::array<std::int32_t, kBlockVoxels> tri;
  std::array<std::int32_t, kBlockVoxels> comp;
  std::array<std::int32_t, kBlockVoxels> src;  // sheet index (>= 0), kNoSheet, or kThinNoSheet
  std::array<std::int8_t, kBlockVoxels> layer;
  explicit BuildBlock(std::int32_t c) {
    dist.fill(std::numeric_limits<float>::infinity());
    tri.fill(-1);
    comp.fill(c);
    src.fill(-1);
    layer.fill(kUnset);
  }
};

inline Eigen::Vector3i local_coords(int i) { return {i & 7, (i >> 3) & 7, i >> 6}; }

// The d-th of the six face neighbours of v (d / 2 the axis, d % 2 the side).
inline Eigen::Vector3i face_neighbour(const Eigen::Vector3i& v, int d) {
  Eigen::Vector3i v2 = v;
  v2[d / 2] += (d % 2) ? 1 : -1;
  return v2;
}

// Angle-weighted pseudo-normals (face, edge, vertex) give a robust inside/outside
// sign for a point from its closest feature on a watertight mesh.
struct PseudoNormals {
  std::vector<Eigen::Vector3d> face;
  std::vector<std::array<Eigen::Vector3d, 3>> edge;  // per triangle: ab, bc, ca
  std::vector<Eigen::Vector3d> vertex;

  void build(const mesh::TriangleMesh& m) {
    const std::size_t nt = m.triangles.size();
    face.resize(nt);
    edge.resize(nt);
    vertex.assign(m.vertices.size(), Eigen::Vector3d::Zero());
    std::unordered_map<std::uint64_t, Eigen::Vector3d> edges;
    edges.reserve(nt * 2);
    auto key = [](std::uint32_t a, std::uint32_t b) {
      return (static_cast<std::uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
    };
    for (std::size_t t = 0; t < nt; ++t) {
      const auto& tr = m.triangles[t];
      const Eigen::Vector3d& a = m.vertices[tr[0]];
      const Eigen::Vector3d& b = m.vertices[tr[1]];
      const Eigen::Vector3d& c = m.vertices[tr[2]];
      const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
      face[t] = n;
      const Eigen::Vector3d* p[3] = {&a, &b, &c};
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d e1 = (*p[(k + 1) % 3] - *p[k]).normalized();
        const Eigen::Vector3d e2 = (*p[(k + 2) % 3] - *p[k]).normalized();
        const double ang = std::acos(std::clamp(e1.dot(e2), -1.0, 1.0));
        vertex[tr[k]] += ang * n;
        auto it = edges.try_emplace(key(tr[k], tr[(k + 1) % 3]), Eigen::Vector3d::Zero()).first;
        it->second += n;
      }
    }
    for (std::size_t t = 0; t < nt; ++t) {
      const auto& tr = m.triangles[t];
      for (int k = 0; k < 3; ++k) edge[t][k] = edges.at(key(tr[k], tr[(k + 1) % 3]));
    }
  }
  const Eigen::Vector3d& of(const mesh::TriangleMesh& m, std::int32_t t, int feature) const {
    const auto& tr = m.triangles[static_cast<std::size_t>(t)];
    switch (feature) {
      case 1: return vertex[tr[0]];
      case 2: return vertex[tr[1]];
      case 3: return vertex[tr[2]];
      case 4: return edge[static_cast<std::size_t>(t)][0];
      case 5: return edge[static_cast<std::size_t>(t)][1];
      case 6: return edge[static_cast<std::size_t>(t)][2];
      default: return face[static_cast<std::size_t>(t)];
    }
  }
};

class Builder {
 public:
  Builder(const mesh::TriangleMesh& m, double s, const Eigen::Vector3d& origin, const Eigen::Vector3i& bd,
          bool is_signed, bool points)
      : m_(m), s_(s), origin_(origin), bd_(bd), dims_(bd * kBlockDim), signed_(is_signed), points_(points) {
    nblocks_ = static_cast<std::size_t>(bd.x()) * bd.y() * bd.z();
    top_.assign(nblocks_, -1);
    if (signed_) pn_.build(m);
  }

  void run(int layers_out, int layers_in) {
    surface_pass();
    if (signed_) {
      label_components();
      vote_components();
    }
    sheet_pass();
    layer_pass(layers_out, layers_in);
  }

  void finish(int layers_out, int layers_in, Voxmap* vm, VoxmapBuildInfo* info);

 private:
  std::size_t block_linear_of(const Eigen::Vector3i& b) const {
    return (static_cast<std::size_t>(b.z()) * bd_.y() + b.y()) * bd_.x() + b.x();
  }
  Eigen::Vector3i block_coords(std::size_t bl) const {
    const auto x = static_cast<int>(bl % static_cast<std::size_t>(bd_.x()));
    const auto yz = bl / static_cast<std::size_t>(bd_.x());
    return {x, static_cast<int>(yz % static_cast<std::size_t>(bd_.y())),
            static_cast<int>(yz / static_cast<std::size_t>(bd_.y()))};
  }
  static Eigen::Vector3i block_of_voxel(const Eigen::Vector3i& v) {
    return {v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift};
  }
  bool in_dims(const Eigen::Vector3i& v) const {
    return v.x() >= 0 && v.y() >= 0 && v.z() >= 0 && v.x() < dims_.x() && v.y() < dims_.y() && v.z() < dims_.z();
  }
  Eigen::Vector3d centre(const Eigen::Vector3i& v) const {
    return origin_ + (v.cast<double>() + Eigen::Vector3d::Constant(0.5)) * s_;
  }
  BuildBlock& block_alloc(std::size_t bl, std::int32_t comp) {
    if (top_[bl] < 0) {
      top_[bl] = static_cast<std::int32_t>(blocks_.size());
      blocks_.emplace_back(comp);
      block_of_index_.push_back(bl);
    }
    return blocks_[static_cast<std::size_t>(top_[bl])];
  }
  double tri_dist(const Eigen::Vector3d& p, std::int32_t t) const {
    const auto& tr = m_.triangles[static_cast<std::size_t>(t)];
    return std::sqrt(point_triangle_distance_sq(p, m_.vertices[tr[0]], m_.vertices[tr[1]], m_.vertices[tr[2]]));
  }
  // +1 outside, -1 inside, 0 on the surface: from the pseudo-normal of the closest feature.
  int side_of(const Eigen::Vector3d& p, std::int32_t t) const {
    const auto& tr = m_.triangles[static_cast<std::size_t>(t)];
    const ClosestPoint cp = closest_point_on_triangle(p, m_.vertices[tr[0]], m_.vertices[tr[1]], m_.vertices[tr[2]]);
    const double d = (p - cp.point).dot(pn_.of(m_, t, cp.feature));
    return d > 0 ? 1 : (d < 0 ? -1 : 0);
  }

  bool free_component(const Eigen::Vector3i& v, std::int32_t* comp) const;
  bool inside_at(const Eigen::Vector3i& v) const;
  void surface_pass();
  void sheet_pass();
  void label_components();
  void vote_components();
  void layer_pass(int layers_out, int layers_in);

  const mesh::TriangleMesh& m_;
  double s_;
  Eigen::Vector3d origin_;
  Eigen::Vector3i bd_, dims_;
  bool signed_;
  bool points_;
  std::size_t nblocks_ = 0;
  std::vector<std::int32_t> top_;
  std::deque<BuildBlock> blocks_;  // deque: references stay valid while growing
  std::vector<std::size_t> block_of_index_;
  std::vector<std::int32_t> block_comp_;
  std::vector<char> comp_inside_;
  PseudoNormals pn_;
  std::vector<SheetSource> sheet_src_;
  std::size_t surface_count_ = 0;
};

// The free-space component of voxel v (in the grid); false for a surface voxel.
bool Builder::free_component(const Eigen::Vector3i& v, std::int32_t* comp) const {
  const Eigen::Vector3i B(v.x() >> kBlockShift, v.y() >> kBlockShift, v.z() >> kBlockShift);
  const std::size_t bl = block_linear_of(B);
  if (top_[bl] < 0) {
    *comp = block_comp_[bl];
    return true;
  }
  const BuildBlock& b = blocks_[static_cast<std::size_t>(top_[bl])];
  const int j = voxel_in_block(v);
  if (b.layer[j] == 0) return false;
  *comp = b.comp[j];
  return true;
}

// A non-surface voxel of a free region voted inside (signed fields only).
bool Builder::inside_at(const Eigen::Vector3i& v) const {
  std::int32_t c = -1;
  if (!signed_ || !in_dims(v) || !free_component(v, &c)) return false;
  return c >= 0 && comp_inside_[static_cast<std::size_t>(c)] != 0;
}

// Thin surface voxels (no inside voxel within two voxels: a face lying on a
// voxel boundary makes a surface band two voxels thick, which is not a thin
// wall; every surface voxel of an unsigned field) get a sheet: the nearest
// pair of opposed faces among the triangles the surrounding surface voxels
// found (their planes bound the wall: + face, thickness), or, with no such
// pair (open sheet, open edge), the nearest face alone with thickness 0.
void Builder::sheet_pass() {
  std::vector<std::int32_t> cand;
  std::vector<Eigen::Vector3d> cn, cq;
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (blocks_[k].layer[i] != 0) continue;
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      bool thin = true;
      for (int d = 0; d < 125 && thin && signed_; ++d)
        thin = !inside_at(v + Eigen::Vector3i(d % 5 - 2, (d / 5) % 5 - 2, d / 25 - 2));
      if (!thin) continue;
      if (points_) {
        blocks_[k].src[i] = kThinNoSheet;
        continue;
      }
      cand.clear();
      for (int d = 0; d < 125; ++d) {
        const Eigen::Vector3i v2 = v + Eigen::Vector3i(d % 5 - 2, (d / 5) % 5 - 2, d / 25 - 2);
        if (!in_dims(v2)) continue;
        const Eigen::Vector3i B2(v2.x() >> kBlockShift, v2.y() >> kBlockShift, v2.z() >> kBlockShift);
        const std::int32_t bi = top_[block_linear_of(B2)];
        if (bi < 0) continue;
        const BuildBlock& nb = blocks_[static_cast<std::size_t>(bi)];
        const int j = voxel_in_block(v2);
        if (nb.layer[j] != 0 || nb.tri[j] < 0) continue;
        if (std::find(cand.begin(), cand.end(), nb.tri[j]) == cand.end()) cand.push_back(nb.tri[j]);
      }
      const Eigen::Vector3d c = centre(v);
      cn.clear();
      cq.clear();
      for (const std::int32_t t : cand) {
        const auto& tr = m_.triangles[static_cast<std::size_t>(t)];
        const Eigen::Vector3d& a = m_.vertices[tr[0]];
        const Eigen::Vector3d& b = m_.vertices[tr[1]];
        const Eigen::Vector3d& cc = m_.vertices[tr[2]];
        cn.push_back((b - a).cross(cc - a).normalized());
        cq.push_back(closest_point_on_triangle(c, a, b, cc).point);
      }
      // Nearest face, and the nearest opposed pair bounding a wall <= 2.5 voxels thick.
      std::size_t best1 = 0;
      for (std::size_t a = 1; a < cand.size(); ++a)
        if ((cq[a] - c).squaredNorm() < (cq[best1] - c).squaredNorm()) best1 = a;
      double best_score = std::numeric_limits<double>::infinity();
      std::size_t pa = 0, pb = 0;
      for (std::size_t a = 0; a < cand.size(); ++a) {
        for (std::size_t b = 0; b < cand.size(); ++b) {
          if (cn[a].dot(cn[b]) > -0.7) continue;
          const double th = cn[a].dot(cq[a] - cq[b]);
          if (th < -0.05 * s_ || th > 2.5 * s_) continue;
          const double score = (cq[a] - c).norm() + (cq[b] - c).norm();
          if (score < best_score) {
            best_score = score;
            pa = a;
            pb = b;
          }
        }
      }
      SheetSource src;
      if (std::isfinite(best_score)) {
        src = {cn[pa], cq[pa], std::max(0.0, cn[pa].dot(cq[pa] - cq[pb]))};
      } else if (!cand.empty()) {
        src = {cn[best1], cq[best1], 0.0};
      } else {
        continue;
      }
      blocks_[k].src[i] = static_cast<std::int32_t>(sheet_src_.size());
      sheet_src_.push_back(src);
    }
  }
}

void Builder::surface_pass() {
  const double h = 0.5 * s_ * (1.0 + 1e-9);
  for (std::size_t t = 0; t < m_.triangles.size(); ++t) {
    const auto& tr = m_.triangles[t];
    const Eigen::Vector3d& a = m_.vertices[tr[0]];
    const Eigen::Vector3d& b = m_.vertices[tr[1]];
    const Eigen::Vector3d& c = m_.vertices[tr[2]];
    const Eigen::Vector3d lo = ((a.cwiseMin(b).cwiseMin(c) - origin_) / s_).array() - 1e-9;
    const Eigen::Vector3d hi = ((a.cwiseMax(b).cwiseMax(c) - origin_) / s_).array() + 1e-9;
    Eigen::Vector3i il, ih;
    for (int k = 0; k < 3; ++k) {
      il[k] = std::max(0, static_cast<int>(std::floor(lo[k])));
      ih[k] = std::min(dims_[k] - 1, static_cast<int>(std::floor(hi[k])));
      if (il[k] > ih[k]) goto next_triangle;
    }
    for (int z = il.z(); z <= ih.z(); ++z) {
      for (int y = il.y(); y <= ih.y(); ++y) {
        for (int x = il.x(); x <= ih.x(); ++x) {
          const Eigen::Vector3i v(x, y, z);
          const Eigen::Vector3d cc = centre(v);
          if (!triangle_box_overlap(cc, h, a, b, c)) continue;
          const Eigen::Vector3i bc(x >> kBlockShift, y >> kBlockShift, z >> kBlockShift);
          BuildBlock& blk = block_alloc(block_linear_of(bc), -1);
          const int i = voxel_in_block(v);
          if (blk.layer[i] != 0) {
            blk.layer[i] = 0;
            ++surface_count_;
          }
          const auto ti = static_cast<std::int32_t>(t);
          const double d = tri_dist(cc, ti);
          if (d < blk.dist[i]) {
            blk.dist[i] = static_cast<float>(d);
            blk.tri[i] = ti;
          }
        }
      }
    }
  next_triangle:;
  }
}

void Builder::label_components() {
  // Connected regions of free (non-surface) space, 6-connected. Nodes are whole
  // empty blocks or single voxels of blocks that hold surface voxels.
  block_comp_.assign(nblocks_, -1);
  std::vector<std::uint64_t> stack;
  const std::uint64_t kWhole = 512;
  std::int32_t comp = 0;
  auto visit_neighbours = [&](std::uint64_t node, std::int32_t c) {
    const std::size_t bl = node >> 10;
    const int i = static_cast<int>(node & 1023);
    const Eigen::Vector3i B = block_coords(bl);
    if (i == static_cast<int>(kWhole)) {
      for (int d = 0; d < 6; ++d) {
        const int ax = d / 2, sg = (d % 2) ? 1 : -1;
        Eigen::Vector3i B2 = B;
        B2[ax] += sg;
        if (B2[ax] < 0 || B2[ax] >= bd_[ax]) continue;
        const std::size_t bl2 = block_linear_of(B2);
        if (top_[bl2] < 0) {
          if (block_comp_[bl2] < 0) {
            block_comp_[bl2] = c;
            stack.push_back((static_cast<std::uint64_t>(bl2) << 10) | kWhole);
          }
        } else {
          BuildBlock& nb = blocks_[static_cast<std::size_t>(top_[bl2])];
          const int face = sg > 0 ? 0 : kBlockDim - 1;
          for (int p = 0; p < kBlockDim; ++p) {
            for (int q = 0; q < kBlockDim; ++q) {
              Eigen::Vector3i l;
              l[ax] = face;
              l[(ax + 1) % 3] = p;
              l[(ax + 2) % 3] = q;
              const int j = voxel_in_block(l);
              if (nb.layer[j] != 0 && nb.comp[j] < 0) {
                nb.comp[j] = c;
                stack.push_back((static_cast<std::uint64_t>(bl2) << 10) | static_cast<std::uint64_t>(j));
              }
            }
          }
        }
      }
      return;
    }
    const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
    for (int d = 0; d < 6; ++d) {
      Eigen::Vector3i v2 = v;
      v2[d / 2] += (d % 2) ? 1 : -1;
      if (!in_dims(v2)) continue;
      const Eigen::Vector3i B2(v2.x() >> kBlockShift, v2.y() >> kBlockShift, v2.z() >> kBlockShift);
      const std::size_t bl2 = block_linear_of(B2);
      if (top_[bl2] < 0) {
        if (block_comp_[bl2] < 0) {
          block_comp_[bl2] = c;
          stack.push_back((static_cast<std::uint64_t>(bl2) << 10) | kWhole);
        }
      } else {
        BuildBlock& nb = blocks_[static_cast<std::size_t>(top_[bl2])];
        const int j = voxel_in_block(v2);
        if (nb.layer[j] != 0 && nb.comp[j] < 0) {
          nb.comp[j] = c;
          stack.push_back((static_cast<std::uint64_t>(bl2) << 10) | static_cast<std::uint64_t>(j));
        }
      }
    }
  };
  auto flood = [&](std::uint64_t start, std::int32_t c) {
    stack.clear();
    stack.push_back(start);
    while (!stack.empty()) {
      const std::uint64_t n = stack.back();
      stack.pop_back();
      visit_neighbours(n, c);
    }
  };
  for (std::size_t bl = 0; bl < nblocks_; ++bl) {
    if (top_[bl] < 0) {
      if (block_comp_[bl] < 0) {
        block_comp_[bl] = comp;
        flood((static_cast<std::uint64_t>(bl) << 10) | kWhole, comp);
        ++comp;
      }
    } else {
      BuildBlock& blk = blocks_[static_cast<std::size_t>(top_[bl])];
      for (int i = 0; i < kBlockVoxels; ++i) {
        if (blk.layer[i] != 0 && blk.comp[i] < 0) {
          blk.comp[i] = comp;
          flood((static_cast<std::uint64_t>(bl) << 10) | static_cast<std::uint64_t>(i), comp);
          ++comp;
        }
      }
    }
  }
  comp_inside_.assign(static_cast<std::size_t>(comp), 0);
}

void Builder::vote_components() {
  // Each free region is inside or outside as a whole: the majority of the
  // pseudo-normal signs of its voxels next to the surface decides.
  std::vector<std::int64_t> votes(comp_inside_.size(), 0);
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const BuildBlock& blk = blocks_[k];
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (blk.layer[i] != 0) continue;
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      for (int d = 0; d < 6; ++d) {
        Eigen::Vector3i v2 = v;
        v2[d / 2] += (d % 2) ? 1 : -1;
        std::int32_t c = -1;
        if (!in_dims(v2) || !free_component(v2, &c) || c < 0) continue;
        votes[static_cast<std::size_t>(c)] += side_of(centre(v2), blk.tri[i]);
      }
    }
  }
  for (std::size_t c = 0; c < votes.size(); ++c) comp_inside_[c] = votes[c] < 0 ? 1 : 0;
}

void Builder::layer_pass(int layers_out, int layers_in) {
  std::vector<std::uint64_t> frontier, next;
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (blocks_[k].layer[i] == 0) frontier.push_back((static_cast<std::uint64_t>(block_of_index_[k]) << 9) | i);
    }
  }
  const int lmax = signed_ ? std::max(layers_out, layers_in) : layers_out;
  for (int layer = 1; layer <= lmax; ++layer) {
    next.clear();
    for (const std::uint64_t node : frontier) {
      const std::size_t bl = node >> 9;
      const int i = static_cast<int>(node & 511);
      const std::int32_t t = blocks_[static_cast<std::size_t>(top_[bl])].tri[i];
      const std::int32_t src = std::max(kNoSheet, blocks_[static_cast<std::size_t>(top_[bl])].src[i]);
      const Eigen::Vector3i v = block_coords(bl) * kBlockDim + local_coords(i);
      for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            if (dx == 0 && dy == 0 && dz == 0) continue;
            const Eigen::Vector3i v2 = v + Eigen::Vector3i(dx, dy, dz);
            if (!in_dims(v2)) continue;
            const Eigen::Vector3i B2(v2.x() >> kBlockShift, v2.y() >> kBlockShift, v2.z() >> kBlockShift);
            const std::size_t bl2 = block_linear_of(B2);
            const int j = voxel_in_block(v2);
            if (top_[bl2] < 0) {
              const std::int32_t c = signed_ ? block_comp_[bl2] : -1;
              const bool inside = c >= 0 && comp_inside_[static_cast<std::size_t>(c)];
              if (layer > (inside ? layers_in : layers_out)) continue;
              block_alloc(bl2, c);
            }
            BuildBlock& nb = blocks_[static_cast<std::size_t>(top_[bl2])];
            const std::int8_t cur = nb.layer[j];
            if (cur == kUnset) {
              const std::int32_t c = nb.comp[j];
              const bool inside = signed_ && c >= 0 && comp_inside_[static_cast<std::size_t>(c)];
              if (layer > (inside ? layers_in : layers_out)) continue;
              nb.layer[j] = static_cast<std::int8_t>(inside ? -layer : layer);
              nb.tri[j] = t;
              nb.src[j] = inside ? kNoSheet : src;  // the sheet of the surface voxel it was reached from
              nb.dist[j] = static_cast<float>(tri_dist(centre(v2), t));
              next.push_back((static_cast<std::uint64_t>(bl2) << 9) | static_cast<std::uint64_t>(j));
            } else if ((cur == layer || cur == -layer) && nb.tri[j] != t) {
              // Closest-triangle propagation: keep the nearer of the parents' triangles.
              const double d = tri_dist(centre(v2), t);
              if (d < nb.dist[j]) {
                nb.dist[j] = static_cast<float>(d);
                nb.tri[j] = t;
              }
            }
          }
        }
      }
    }
    frontier.swap(next);
  }
  // Two refinement sweeps: a voxel reached diagonally only saw the triangles of
  // its parents, a surface voxel only those crossing it (the nearest one may
  // cross only a neighbour); offer each every triangle its 26 neighbours
  // found (unique ones).
  std::int32_t cand[26];
  for (int sweep = 0; sweep < 2; ++sweep)
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    BuildBlock& blk = blocks_[k];
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const std::int8_t L = blk.layer[i];
      if (L == kUnset) continue;  // surface voxels too: the SAT pass saw only the triangles crossing them
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      int nc = 0;
      for (int d = 0; d < 27; ++d) {
        if (d == 13) continue;
        const Eigen::Vector3i v2 = v + Eigen::Vector3i(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1);
        if (!in_dims(v2)) continue;
        const Eigen::Vector3i B2(v2.x() >> kBlockShift, v2.y() >> kBlockShift, v2.z() >> kBlockShift);
        const std::int32_t bi = top_[block_linear_of(B2)];
        if (bi < 0) continue;
        const std::int32_t t2 = blocks_[static_cast<std::size_t>(bi)].tri[voxel_in_block(v2)];
        if (t2 < 0 || t2 == blk.tri[i]) continue;
        bool dup = false;
        for (int c = 0; c < nc && !dup; ++c) dup = cand[c] == t2;
        if (!dup) cand[nc++] = t2;
      }
      const Eigen::Vector3d cc = centre(v);
      for (int c = 0; c < nc; ++c) {
        const double d = tri_dist(cc, cand[c]);
        if (d < blk.dist[i]) {
          blk.dist[i] = static_cast<float>(d);
          blk.tri[i] = cand[c];
        }
      }
    }
  }
}

void Builder::finish(int layers_out, int layers_in, Voxmap* vm, VoxmapBuildInfo* info) {
  Voxmap out;
  out.voxel_size = s_;
  out.origin = origin_;
  out.block_dims = bd_;
  out.signed_field = signed_;
  out.layers_out = layers_out;
  out.layers_in = signed_ ? layers_in : 0;
  out.top.assign(nblocks_, kBlockEmpty);
  out.blocks.resize(blocks_.size());
  out.sheet_of_block.assign(blocks_.size(), -1);
  const float far_out = out.far_outside_sdf(), far_in = out.far_inside_sdf();
  auto is_inside_comp = [&](std::int32_t c) {
    return signed_ && c >= 0 && comp_inside_[static_cast<std::size_t>(c)] != 0;
  };
  auto encode = [](const Eigen::Vector3d& g, Voxel* v) {
    for (int k = 0; k < 3; ++k)
      v->grad[k] = static_cast<std::int16_t>(std::lround(std::clamp(g[k], -1.0, 1.0) * kGradScale));
  };
  std::size_t uniform_inside = 0;
  for (std::size_t bl = 0; bl < nblocks_; ++bl) {
    if (top_[bl] >= 0) {
      out.top[bl] = top_[bl];
    } else if (signed_ && is_inside_comp(block_comp_[bl])) {
      out.top[bl] = kBlockUniformInside;
      ++uniform_inside;
    }
  }
  // Closest points (for the kink test below), per stored voxel.
  std::vector<std::array<Eigen::Vector3f, kBlockVoxels>> closest(blocks_.size());
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const BuildBlock& b = blocks_[k];
    VoxelBlock& o = out.blocks[k];
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      Voxel& vx = o.v[static_cast<std::size_t>(i)];
      const std::int8_t L = b.layer[i];
      vx.flags = 0;
      vx.grad[0] = vx.grad[1] = vx.grad[2] = 0;
      closest[k][static_cast<std::size_t>(i)].setConstant(std::numeric_limits<float>::quiet_NaN());
      if (L == kUnset || b.tri[i] < 0) {
        const bool inside = is_inside_comp(b.comp[i]);
        vx.layer = inside ? kLayerFarInside : kLayerFarOutside;
        vx.sdf = inside ? far_in : far_out;
        vx.flags = kFlagNoGradient;
        continue;
      }
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      const Eigen::Vector3d c = centre(v);
      const auto& tr = m_.triangles[static_cast<std::size_t>(b.tri[i])];
      const ClosestPoint cp =
          closest_point_on_triangle(c, m_.vertices[tr[0]], m_.vertices[tr[1]], m_.vertices[tr[2]]);
      closest[k][static_cast<std::size_t>(i)] = cp.point.cast<float>();
      // Sign: surface voxels by the pseudo-normal, layers by their region.
      int sign = 1;
      if (L == 0) {
        sign = signed_ ? side_of(c, b.tri[i]) : 1;
      } else if (L < 0) {
        sign = -1;
      }
      vx.layer = L;
      vx.sdf = static_cast<float>(sign) * b.dist[i];
      const Eigen::Vector3d diff = c - cp.point;
      const double r = diff.norm();
      if (r > 1e-6 * s_ && sign != 0) {
        encode(static_cast<double>(sign) * diff / r, &vx);
      } else if (signed_) {
        encode(pn_.of(m_, b.tri[i], cp.feature).normalized(), &vx);  // on the surface: the outward normal
      } else {
        vx.flags |= kFlagNoGradient;  // on an unsigned surface: no direction
      }
      if (points_) vx.flags |= kFlagNoGradient;  // a point's distance field is a cone: no useful gradient
    }
  }
  // Kinks: where neighbouring centres have far-apart closest points (the
  // medial axis between two faces, inside sharp edges) the gradient jumps
  // and its Taylor prediction is wrong: interpolate trilinearly there.
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Eigen::Vector3f& q = closest[k][static_cast<std::size_t>(i)];
      if (!q.allFinite()) continue;
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      for (int d = 0; d < 6; ++d) {
        const Eigen::Vector3i v2 = face_neighbour(v, d);
        if (!in_dims(v2)) continue;
        const std::int32_t bi = top_[block_linear_of(block_of_voxel(v2))];
        if (bi < 0) continue;
        const Eigen::Vector3f& q2 = closest[static_cast<std::size_t>(bi)][static_cast<std::size_t>(voxel_in_block(v2))];
        if (q2.allFinite() && (q - q2).norm() > 2.0 * s_) {
          out.blocks[k].v[static_cast<std::size_t>(i)].flags |= kFlagNoGradient;
          break;
        }
      }
    }
  }
  closest.clear();
  closest.shrink_to_fit();
  // Thin surface voxels and sheets (surface voxels and the outward layers
  // reached from them).
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const BuildBlock& b = blocks_[k];
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      Voxel& vx = out.blocks[k].v[static_cast<std::size_t>(i)];
      if (b.layer[i] == 0 && b.src[i] != kNoSheet) vx.flags |= kFlagThin;
      if (b.src[i] < 0 || b.layer[i] == kUnset || b.layer[i] < 0) continue;
      const SheetSource& sh = sheet_src_[static_cast<std::size_t>(b.src[i])];
      std::int32_t& si = out.sheet_of_block[k];
      if (si < 0) {
        si = static_cast<std::int32_t>(out.sheets.size());
        out.sheets.emplace_back();
        out.sheets.back().phi.fill(0.0f);
        out.sheets.back().thickness.fill(0.0f);
      }
      const Eigen::Vector3d c = centre(B * kBlockDim + local_coords(i));
      out.sheets[static_cast<std::size_t>(si)].phi[static_cast<std::size_t>(i)] =
          static_cast<float>(sh.n.dot(c - sh.q));
      out.sheets[static_cast<std::size_t>(si)].thickness[static_cast<std::size_t>(i)] =
          static_cast<float>(sh.thickness);
      encode(sh.n, &vx);
      vx.flags |= kFlagSheet | kFlagNoGradient;  // the slot holds the sheet normal, not the field's gradient
      ++out.sheet_voxels;
    }
  }
  // Coarse clearance per block, in voxels: a lower bound on the Chebyshev
  // voxel distance from any voxel of the block to the nearest surface voxel.
  // Exact-ish near the surface (the gap to each nearby surface block's box of
  // surface voxels, within kNear blocks), a block-level chamfer beyond.
  constexpr int kNear = 4;
  std::vector<std::uint8_t> block_dist(nblocks_, 255);
  std::vector<std::size_t> surface_blocks;
  std::vector<std::array<int, 6>> boxes;  // surface voxels' box per surface block (lo xyz, hi xyz)
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    std::array<int, 6> box = {1 << 30, 1 << 30, 1 << 30, -(1 << 30), -(1 << 30), -(1 << 30)};
    const Eigen::Vector3i B = block_coords(block_of_index_[k]);
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (blocks_[k].layer[i] != 0) continue;
      const Eigen::Vector3i v = B * kBlockDim + local_coords(i);
      for (int a = 0; a < 3; ++a) {
        box[static_cast<std::size_t>(a)] = std::min(box[static_cast<std::size_t>(a)], v[a]);
        box[static_cast<std::size_t>(a + 3)] = std::max(box[static_cast<std::size_t>(a + 3)], v[a]);
      }
    }
    if (box[0] > box[3]) continue;
    block_dist[block_of_index_[k]] = 0;
    surface_blocks.push_back(block_of_index_[k]);
    boxes.push_back(box);
  }
  for (int pass = 0; pass < 2; ++pass) {
    const int step = pass == 0 ? 1 : -1;
    const int z0 = pass == 0 ? 0 : bd_.z() - 1, z1 = pass == 0 ? bd_.z() : -1;
    const int y0 = pass == 0 ? 0 : bd_.y() - 1, y1 = pass == 0 ? bd_.y() : -1;
    const int x0 = pass == 0 ? 0 : bd_.x() - 1, x1 = pass == 0 ? bd_.x() : -1;
    for (int z = z0; z != z1; z += step) {
      for (int y = y0; y != y1; y += step) {
        for (int x = x0; x != x1; x += step) {
          const std::size_t bl = block_linear_of({x, y, z});
          int best = block_dist[bl];
          // The 13 neighbours already visited in this sweep direction.
          for (int d = 0; d < 13; ++d) {
            const int dx = d % 3 - 1, dy = (d / 3) % 3 - 1, dz = d / 9 - 1;  // lexicographically before (0,0,0)
            const Eigen::Vector3i n(x + step * dx, y + step * dy, z + step * dz);
            if (n.x() < 0 || n.y() < 0 || n.z() < 0 || n.x() >= bd_.x() || n.y() >= bd_.y() || n.z() >= bd_.z())
              continue;
            best = std::min(best, block_dist[block_linear_of(n)] + 1);
          }
          block_dist[bl] = static_cast<std::uint8_t>(std::min(best, 255));
        }
      }
    }
  }
  out.coarse.assign(nblocks_, 255);
  for (std::size_t bl = 0; bl < nblocks_; ++bl) {
    // Block distance c >= 1: at least (c - 1) whole blocks between, plus one voxel.
    const int c = block_dist[bl];
    out.coarse[bl] = static_cast<std::uint8_t>(c == 0 ? 0 : std::min(255, (c - 1) * kBlockDim + 1));
  }
  for (std::size_t j = 0; j < surface_blocks.size(); ++j) {
    const Eigen::Vector3i S = block_coords(surface_blocks[j]);
    const std::array<int, 6>& box = boxes[j];
    for (int dz = -kNear; dz <= kNear; ++dz) {
      for (int dy = -kNear; dy <= kNear; ++dy) {
        for (int dx = -kNear; dx <= kNear; ++dx) {
          const Eigen::Vector3i B = S + Eigen::Vector3i(dx, dy, dz);
          if (B.x() < 0 || B.y() < 0 || B.z() < 0 || B.x() >= bd_.x() || B.y() >= bd_.y() || B.z() >= bd_.z())
            continue;
          const std::size_t bl = block_linear_of(B);
          if (out.coarse[bl] == 0) continue;
          int gap = 0;
          for (int a = 0; a < 3; ++a) {
            const int lo = B[a] * kBlockDim, hi = lo + kBlockDim - 1;
            gap = std::max({gap, box[static_cast<std::size_t>(a)] - hi, lo - box[static_cast<std::size_t>(a + 3)]});
          }
          out.coarse[bl] = static_cast<std::uint8_t>(std::min<int>(out.coarse[bl], std::max(gap, 1)));
        }
      }
    }
  }
  out.surface_voxels = surface_count_;
  if (info != nullptr) {
    info->surface_voxels = surface_count_;
    info->allocated_blocks = blocks_.size();
    info->uniform_inside_blocks = uniform_inside;
    info->components = comp_inside_.size();
    info->surface_index.clear();
    info->surface_triangle.clear();
    for (std::size_t k = 0; k < blocks_.size(); ++k) {
      const Eigen::Vector3i B = block_coords(block_of_index_[k]);
      for (int i = 0; i < kBlockVoxels; ++i) {
        if (blocks_[k].layer[i] != 0) continue;
        info->surface_index.push_back(B * kBlockDim + local_coords(i));
        info->surface_triangle.push_back(blocks_[k].tri[i]);
      }
    }
  }
  *vm = std::move(out);
}

std::optional<VpsError> check_params(const VoxmapParams& p) {
  if (!(p.voxel_size > 0.0) || !std::isfinite(p.voxel_size)) return VpsError{"voxel size must be positive and finite"};
  if (p.layers_out < 1 || p.layers_out > 100 || p.layers_in < 1 || p.layers_in > 100)
    return VpsError{"distance layers must be in 1..100"};
  if (p.roi && (p.roi->isEmpty() || !p.roi->min().allFinite() || !p.roi->max().allFinite()))
    return VpsError{"region of interest is empty or not finite"};
  return std::nullopt;
}

std::optional<VpsError> build_core(const mesh::TriangleMesh& m, const Eigen::AlignedBox3d& bounds, bool is_signed, bool points,
                                   const VoxmapParams& p, Voxmap* out, VoxmapBuildInfo* info) {
  Eigen::AlignedBox3d region = bounds;
  if (p.roi) region = region.intersection(*p.roi);
  if (region.isEmpty()) return VpsError{"the region of interest does not overlap the geometry"};
  const double s = p.voxel_size;
  const int pad = p.layers_out + 2;
  const Eigen::Vector3d origin = region.min() - Eigen::Vector3d::Constant(pad * s);
  Eigen::Vector3i bd;
  double nblocks = 1.0;
  for (int k = 0; k < 3; ++k) {
    const double voxels = std::ceil(region.sizes()[k] / s) + 2.0 * pad + 1.0;
    const double blocks = std::ceil(voxels / kBlockDim);
    if (blocks > (1 << 20)) return VpsError{"voxel size too small for the region (too many voxels along an axis)"};
    bd[k] = static_cast<int>(blocks);
    nblocks *= blocks;
  }
  if (nblocks > static_cast<double>(kMaxBlocks))
    return VpsError{"voxel grid of " + std::to_string(static_cast<long long>(nblocks)) +
                    " blocks exceeds the limit; use a larger voxel or a region of interest"};
  // Bound the voxelization work (voxels visited per triangle bounding box)
  // before starting: hostile or mis-scaled input must not run for hours.
  double work = 0.0;
  const Eigen::Vector3d dims = (bd * kBlockDim).cast<double>();
  for (const auto& tr : m.triangles) {
    const Eigen::Vector3d& a = m.vertices[tr[0]];
    const Eigen::Vector3d& b2 = m.vertices[tr[1]];
    const Eigen::Vector3d& c = m.vertices[tr[2]];
    const Eigen::Vector3d lo = ((a.cwiseMin(b2).cwiseMin(c) - origin) / s).cwiseMax(Eigen::Vector3d::Zero());
    const Eigen::Vector3d hi = ((a.cwiseMax(b2).cwiseMax(c) - origin) / s).cwiseMin(dims);
    if ((hi.array() < lo.array()).any()) continue;
    work += (std::floor(hi.x()) - std::floor(lo.x()) + 1) * (std::floor(hi.y()) - std::floor(lo.y()) + 1) *
            (std::floor(hi.z()) - std::floor(lo.z()) + 1);
  }
  if (work > kMaxVoxelizationWork)
    return VpsError{"voxelization would test " + std::to_string(static_cast<long long>(work)) +
                    " triangle-voxel pairs, more than the limit; use a larger voxel or a region of interest"};
  Builder b(m, s, origin, bd, is_signed, points);
  b.run(p.layers_out, p.layers_in);
  b.finish(p.layers_out, p.layers_in, out, info);
  return std::nullopt;
}

}  // namespace

std::optional<VpsError> build_voxmap(const mesh::TriangleMesh& mesh, const VoxmapParams& params, Voxmap* out,
                                     VoxmapBuildInfo* info) {
  if (auto e = check_params(params)) return e;
  mesh::TriangleMesh valid;
  mesh::MeshReport report;
  if (auto e = mesh::validate_mesh(mesh, params.limits, &valid, &report)) return VpsError{"mesh: " + e->message};
  const bool is_signed = report.watertight() && !params.force_unsigned;
  Voxmap vm;
  VoxmapBuildInfo local;
  if (auto e = build_core(valid, report.bounds, is_signed, false, params, &vm, info != nullptr ? &local : nullptr)) return e;
  *out = std::move(vm);
  if (info != nullptr) {
    local.mesh_report = report;
    local.triangles = valid.triangles.size();
    local.mesh = std::move(valid);
    *info = std::move(local);
  }
  return std::nullopt;
}

std::optional<VpsError> build_voxmap_from_points(const std::vector<Eigen::Vector3d>& points,
                                                 const VoxmapParams& params, Voxmap* out) {
  if (auto e = check_params(params)) return e;
  if (points.empty()) return VpsError{"point cloud is empty"};
  if (points.size() > params.limits.max_triangles) return VpsError{"point cloud has too many points"};
  // Each point becomes a degenerate triangle (a, a, a): the SAT test reduces to
  // point-in-box and the closest point to the point itself.
  mesh::TriangleMesh m;
  m.vertices.reserve(points.size());
  Eigen::AlignedBox3d bounds;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) return VpsError{"point " + std::to_string(i) + " is not finite"};
    m.vertices.push_back(points[i]);
    bounds.extend(points[i]);
    const auto k = static_cast<std::uint32_t>(i);
    m.triangles.push_back({k, k, k});
  }
  if (!(bounds.sizes().maxCoeff() <= params.limits.max_extent))
    return VpsError{"point cloud extent exceeds the limit (wrong units?)"};
  Voxmap vm;
  if (auto e = build_core(m, bounds, false, true, params, &vm, nullptr)) return e;
  *out = std::move(vm);
  return std::nullopt;
}

}  // namespace hemm::vps
