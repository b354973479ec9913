#include "common/haptics/vps/cache.h"

#include <cmath>
#include <cstring>
#include <type_traits>

namespace hemm::vps {

namespace {

constexpr char kMagic[8] = {'H', 'E', 'M', 'M', 'V', 'P', 'S', '\0'};
constexpr std::size_t kHeader = 8 + 4 + 4 + 8 + 8;

class Writer {
 public:
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    buf.insert(buf.end(), p, p + sizeof(T));
  }
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    buf.insert(buf.end(), b, b + n);
  }
  void vec3(const Eigen::Vector3d& v) {
    for (int k = 0; k < 3; ++k) put(v[k]);
  }
  std::vector<std::uint8_t> buf;
};

class Reader {
 public:
  Reader(const std::uint8_t* d, std::size_t n) : d_(d), n_(n) {}
  template <typename T>
  bool get(T* v) {
    if (n_ - pos_ < sizeof(T)) return false;
    std::memcpy(v, d_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool bytes(void* p, std::size_t n) {
    if (n_ - pos_ < n) return false;
    if (n == 0) return true;  // an empty vector's data() may be null: memcpy must not see it
    std::memcpy(p, d_ + pos_, n);
    pos_ += n;
    return true;
  }
  bool vec3(Eigen::Vector3d* v) { return get(&(*v)[0]) && get(&(*v)[1]) && get(&(*v)[2]); }
  std::size_t remaining() const { return n_ - pos_; }

 private:
  const std::uint8_t* d_;
  std::size_t n_;
  std::size_t pos_ = 0;
};

// A sphere tree in nodes [root, end): finite spheres; the root covers the
// range [first, first + count); children come after their parent (no cycles)
// within the table and split its range (a traversal visits each point once).
std::optional<VpsError> check_tree(const std::vector<SphereNode>& nodes, const std::vector<std::int32_t>& parent,
                                   std::int64_t root, std::int64_t end, std::int64_t first, std::int64_t count) {
  if (root < 0 || end > static_cast<std::int64_t>(nodes.size()) || root >= end)
    return VpsError{"invalid sphere tree"};
  for (std::int64_t i = root; i < end; ++i) {
    const SphereNode& nd = nodes[static_cast<std::size_t>(i)];
    bool ok = std::isfinite(nd.cx) && std::isfinite(nd.cy) && std::isfinite(nd.cz) && std::isfinite(nd.radius) &&
              nd.radius >= 0 && nd.count > 0 && nd.first >= first &&
              nd.first + static_cast<std::int64_t>(nd.count) <= first + count;
    if (i == root) ok = ok && nd.first == first && nd.count == count && parent[static_cast<std::size_t>(i)] == -1;
    if (ok && (nd.left != -1 || nd.right != -1)) {
      ok = nd.left > i && nd.right > i && nd.left < end && nd.right < end;
      if (ok) {
        const SphereNode& a = nodes[static_cast<std::size_t>(nd.left)];
        const SphereNode& b = nodes[static_cast<std::size_t>(nd.right)];
        ok = a.first == nd.first && b.first == a.first + a.count && a.count + b.count == nd.count &&
             parent[static_cast<std::size_t>(nd.left)] == i && parent[static_cast<std::size_t>(nd.right)] == i;
      }
    }
    if (!ok) return VpsError{"invalid sphere node " + std::to_string(i)};
  }
  return std::nullopt;
}

}  // namespace

std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t size) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < size; ++i) {
    h ^= data[i];
    h *= 1099511628211ull;
  }
  return h;
}

template <typename T>
void put_vector(Writer* w, const std::vector<T>& v) {
  w->bytes(v.data(), v.size() * sizeof(T));
}

std::vector<std::uint8_t> serialize_vps(const Voxmap& vm, const PointShell& ps) {
  Writer w;
  w.put(vm.voxel_size);
  w.vec3(vm.origin);
  for (int k = 0; k < 3; ++k) w.put(static_cast<std::int32_t>(vm.block_dims[k]));
  w.put(static_cast<std::uint8_t>(vm.signed_field ? 1 : 0));
  w.put(static_cast<std::int32_t>(vm.layers_out));
  w.put(static_cast<std::int32_t>(vm.layers_in));
  w.put(static_cast<std::uint64_t>(vm.surface_voxels));
  w.put(static_cast<std::uint64_t>(vm.sheet_voxels));
  w.put(static_cast<std::uint64_t>(vm.top.size()));
  put_vector(&w, vm.top);
  put_vector(&w, vm.coarse);
  w.put(static_cast<std::uint64_t>(vm.blocks.size()));
  put_vector(&w, vm.blocks);
  put_vector(&w, vm.sheet_of_block);
  w.put(static_cast<std::uint64_t>(vm.sheets.size()));
  put_vector(&w, vm.sheets);
  w.put(ps.voxel_size);
  w.vec3(ps.reference_point);
  w.put(ps.total_weight);
  w.put(static_cast<std::int32_t>(ps.levels));
  for (const ShellLevel& l : ps.level) {
    w.put(l.first);
    w.put(l.count);
    w.put(l.root);
    w.put(l.node_count);
    w.put(l.spacing);
    w.put(l.total_weight);
  }
  w.put(static_cast<std::uint64_t>(ps.size()));
  for (const auto* v : {&ps.px, &ps.py, &ps.pz, &ps.nx, &ps.ny, &ps.nz, &ps.weight}) put_vector(&w, *v);
  put_vector(&w, ps.level_weight);
  put_vector(&w, ps.point_level);
  w.put(static_cast<std::uint64_t>(ps.nodes.size()));
  put_vector(&w, ps.nodes);
  put_vector(&w, ps.parent);
  put_vector(&w, ps.level_index);
  w.put(static_cast<std::uint64_t>(ps.level_nodes.size()));
  put_vector(&w, ps.level_nodes);
  put_vector(&w, ps.level_parent);
  std::uint8_t header[kHeader];
  std::memcpy(header, kMagic, 8);
  const std::uint32_t version = kCacheVersion, reserved = 0;
  const std::uint64_t size = w.buf.size(), sum = fnv1a64(w.buf.data(), w.buf.size());
  std::memcpy(header + 8, &version, 4);
  std::memcpy(header + 12, &reserved, 4);
  std::memcpy(header + 16, &size, 8);
  std::memcpy(header + 24, &sum, 8);
  std::vector<std::uint8_t> out(kHeader + w.buf.size());
  std::memcpy(out.data(), header, kHeader);
  if (!w.buf.empty()) std::memcpy(out.data() + kHeader, w.buf.data(), w.buf.size());
  return out;
}

std::optional<VpsError> deserialize_vps(const std::uint8_t* data, std::size_t size, Voxmap* vm_out,
                                        PointShell* ps_out) {
  if (size < kHeader) return VpsError{"truncated: shorter than the header"};
  if (std::memcmp(data, kMagic, 8) != 0) return VpsError{"not a .vps file (bad magic)"};
  std::uint32_t version;
  std::uint64_t psize, sum;
  std::memcpy(&version, data + 8, 4);
  std::memcpy(&psize, data + 16, 8);
  std::memcpy(&sum, data + 24, 8);
  if (version != kCacheVersion)
    return VpsError{"unsupported version " + std::to_string(version) + " (expected " +
                    std::to_string(kCacheVersion) + ")"};
  if (psize != size - kHeader)
    return VpsError{"truncated or padded: header says " + std::to_string(psize) + " payload bytes, file has " +
                    std::to_string(size - kHeader)};
  if (fnv1a64(data + kHeader, psize) != sum) return VpsError{"checksum mismatch (corrupt file)"};
  Reader r(data + kHeader, psize);
  const VpsError trunc{"truncated payload"};
  auto get_vector = [&r](auto* v, std::uint64_t n) {
    using T = typename std::remove_reference_t<decltype(*v)>::value_type;
    if (n > r.remaining() / sizeof(T)) return false;
    v->resize(n);
    return r.bytes(v->data(), n * sizeof(T));
  };
  Voxmap vm;
  std::int32_t bd[3], lo, li;
  std::uint8_t sg;
  std::uint64_t surf, sheet_vox, ntop, nblocks, nsheets;
  if (!r.get(&vm.voxel_size) || !r.vec3(&vm.origin) || !r.get(&bd[0]) || !r.get(&bd[1]) || !r.get(&bd[2]) ||
      !r.get(&sg) || !r.get(&lo) || !r.get(&li) || !r.get(&surf) || !r.get(&sheet_vox) || !r.get(&ntop))
    return trunc;
  if (!(vm.voxel_size > 0) || !std::isfinite(vm.voxel_size) || !vm.origin.allFinite())
    return VpsError{"invalid voxel size or origin"};
  if (bd[0] <= 0 || bd[1] <= 0 || bd[2] <= 0 || bd[0] > (1 << 20) || bd[1] > (1 << 20) || bd[2] > (1 << 20))
    return VpsError{"invalid block dimensions"};
  const double prod = static_cast<double>(bd[0]) * bd[1] * bd[2];
  if (prod > static_cast<double>(kMaxBlocks) || static_cast<double>(ntop) != prod)
    return VpsError{"block table size does not match the block dimensions"};
  if (sg > 1 || lo < 1 || lo > 100 || li < 0 || li > 100) return VpsError{"invalid field flags or layers"};
  vm.block_dims = Eigen::Vector3i(bd[0], bd[1], bd[2]);
  vm.signed_field = sg == 1;
  vm.layers_out = lo;
  vm.layers_in = li;
  vm.surface_voxels = surf;
  vm.sheet_voxels = sheet_vox;
  if (!get_vector(&vm.top, ntop) || !get_vector(&vm.coarse, ntop) || !r.get(&nblocks)) return trunc;
  if (nblocks > ntop) return VpsError{"more voxel blocks than grid blocks"};
  if (!get_vector(&vm.blocks, nblocks) || !get_vector(&vm.sheet_of_block, nblocks) || !r.get(&nsheets)) return trunc;
  if (nsheets > nblocks) return VpsError{"more sheet blocks than voxel blocks"};
  if (!get_vector(&vm.sheets, nsheets)) return trunc;
  for (std::int32_t t : vm.top) {
    if (t < kBlockUniformInside || t >= static_cast<std::int64_t>(nblocks)) return VpsError{"invalid block index"};
  }
  for (std::size_t b = 0; b < vm.blocks.size(); ++b) {
    const std::int32_t si = vm.sheet_of_block[b];
    if (si < -1 || si >= static_cast<std::int64_t>(nsheets)) return VpsError{"invalid sheet block index"};
    for (const Voxel& v : vm.blocks[b].v) {
      if (!std::isfinite(v.sdf) || v.layer == -128 || v.flags > (kFlagThin | kFlagSheet | kFlagNoGradient | kFlagInferred) ||
          ((v.flags & kFlagSheet) != 0 && si < 0))
        return VpsError{"invalid voxel value"};
    }
  }
  for (const SheetBlock& sb : vm.sheets)
    for (int i = 0; i < kBlockVoxels; ++i)
      if (!std::isfinite(sb.phi[i]) || !std::isfinite(sb.thickness[i]) || sb.thickness[i] < 0)
        return VpsError{"invalid sheet value"};
  PointShell ps;
  std::int32_t levels;
  std::uint64_t npts, nnodes, nlevel_nodes;
  if (!r.get(&ps.voxel_size) || !r.vec3(&ps.reference_point) || !r.get(&ps.total_weight) || !r.get(&levels))
    return trunc;
  for (ShellLevel& l : ps.level) {
    if (!r.get(&l.first) || !r.get(&l.count) || !r.get(&l.root) || !r.get(&l.node_count) || !r.get(&l.spacing) ||
        !r.get(&l.total_weight))
      return trunc;
  }
  if (!r.get(&npts)) return trunc;
  if (!(ps.voxel_size > 0) || !std::isfinite(ps.voxel_size) || !ps.reference_point.allFinite() ||
      !std::isfinite(ps.total_weight) || levels < 0 || levels > kMaxShellLevels || npts > (1ull << 30) ||
      (npts > 0) != (levels > 0))
    return VpsError{"invalid pointshell header"};
  ps.levels = levels;
  for (auto* v : {&ps.px, &ps.py, &ps.pz, &ps.nx, &ps.ny, &ps.nz, &ps.weight})
    if (!get_vector(v, npts)) return trunc;
  if (npts > r.remaining() / (kMaxShellLevels * sizeof(float)) ||
      !get_vector(&ps.level_weight, npts * kMaxShellLevels) || !get_vector(&ps.point_level, npts) || !r.get(&nnodes))
    return trunc;
  if (nnodes > 2 * npts + 1) return VpsError{"too many sphere nodes"};
  if (!get_vector(&ps.nodes, nnodes) || !get_vector(&ps.parent, nnodes) || !get_vector(&ps.level_index, npts) ||
      !r.get(&nlevel_nodes))
    return trunc;
  if (nlevel_nodes > 2 * npts + kMaxShellLevels) return VpsError{"too many sphere nodes"};
  if (!get_vector(&ps.level_nodes, nlevel_nodes) || !get_vector(&ps.level_parent, nlevel_nodes)) return trunc;
  if (r.remaining() != 0) return VpsError{"trailing bytes after the pointshell"};
  for (std::size_t i = 0; i < npts; ++i) {
    const Eigen::Vector3d p(ps.px[i], ps.py[i], ps.pz[i]), n(ps.nx[i], ps.ny[i], ps.nz[i]);
    bool ok = p.allFinite() && n.allFinite() && std::abs(n.norm() - 1.0) < 1e-5 && std::isfinite(ps.weight[i]) &&
              ps.weight[i] >= 0 && ps.point_level[i] >= 0 && ps.point_level[i] < levels;
    for (int l = 0; l < kMaxShellLevels && ok; ++l) {
      const float w = ps.level_weight[i * kMaxShellLevels + static_cast<std::size_t>(l)];
      ok = std::isfinite(w) && w >= 0;
    }
    if (!ok) return VpsError{"invalid point " + std::to_string(i)};
  }
  if (npts > 0) {
    if (auto e = check_tree(ps.nodes, ps.parent, 0, static_cast<std::int64_t>(nnodes), 0,
                            static_cast<std::int64_t>(npts)))
      return e;
  }
  // The levels' new points partition the points in level order, each level's
  // tree covers its own range, and the trees tile the level node table.
  std::int64_t next_first = 0, next_node = 0;
  std::vector<char> listed(npts, 0);
  for (int l = 0; l < levels; ++l) {
    const ShellLevel& lev = ps.level[static_cast<std::size_t>(l)];
    const VpsError bad{"invalid pointshell level " + std::to_string(l)};
    if (lev.first != next_first || lev.count < 0 || lev.first + static_cast<std::int64_t>(lev.count) > static_cast<std::int64_t>(npts) ||
        !std::isfinite(lev.spacing) || !std::isfinite(lev.total_weight))
      return bad;
    for (std::int64_t j = lev.first; j < lev.first + lev.count; ++j) {
      const std::int32_t pi = ps.level_index[static_cast<std::size_t>(j)];
      if (pi < 0 || static_cast<std::uint64_t>(pi) >= npts || listed[static_cast<std::size_t>(pi)] ||
          ps.point_level[static_cast<std::size_t>(pi)] != l)
        return bad;
      listed[static_cast<std::size_t>(pi)] = 1;
    }
    next_first += lev.count;
    if (lev.count == 0) {
      if (lev.root != -1 || lev.node_count != 0) return bad;
      continue;
    }
    if (lev.root != next_node || lev.node_count < 1) return bad;
    if (auto e = check_tree(ps.level_nodes, ps.level_parent, lev.root, lev.root + static_cast<std::int64_t>(lev.node_count),
                            lev.first, lev.count))
      return e;
    next_node = lev.root + static_cast<std::int64_t>(lev.node_count);
  }
  if (next_first != static_cast<std::int64_t>(npts) || next_node != static_cast<std::int64_t>(nlevel_nodes))
    return VpsError{"pointshell levels do not cover the points and nodes"};
  *vm_out = std::move(vm);
  *ps_out = std::move(ps);
  return std::nullopt;
}

}  // namespace hemm::vps
