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

}  // namespace

std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t size) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < size; ++i) {
    h ^= data[i];
    h *= 1099511628211ull;
  }
  return h;
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
  w.put(static_cast<std::uint64_t>(vm.top.size()));
  w.bytes(vm.top.data(), vm.top.size() * sizeof(std::int32_t));
  w.bytes(vm.coarse.data(), vm.coarse.size());
  w.put(static_cast<std::uint64_t>(vm.blocks.size()));
  for (const VoxelBlock& b : vm.blocks) {
    w.bytes(b.sdf.data(), sizeof(b.sdf));
    w.bytes(b.layer.data(), sizeof(b.layer));
    w.bytes(b.flags.data(), sizeof(b.flags));
  }
  w.put(ps.voxel_size);
  w.vec3(ps.reference_point);
  w.put(ps.total_weight);
  w.put(static_cast<std::int32_t>(ps.depth));
  w.put(static_cast<std::uint64_t>(ps.points.size()));
  for (std::size_t i = 0; i < ps.points.size(); ++i) {
    w.vec3(ps.points[i]);
    w.vec3(ps.normals[i]);
    w.put(ps.weights[i]);
  }
  w.put(static_cast<std::uint64_t>(ps.nodes.size()));
  for (const SphereNode& n : ps.nodes) {
    w.vec3(n.centre);
    w.put(n.radius);
    w.put(n.first);
    w.put(n.count);
    w.put(n.left);
    w.put(n.right);
  }
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
  Voxmap vm;
  std::int32_t bd[3], lo, li;
  std::uint8_t sg;
  std::uint64_t surf, ntop, nblocks;
  if (!r.get(&vm.voxel_size) || !r.vec3(&vm.origin) || !r.get(&bd[0]) || !r.get(&bd[1]) || !r.get(&bd[2]) ||
      !r.get(&sg) || !r.get(&lo) || !r.get(&li) || !r.get(&surf) || !r.get(&ntop))
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
  if (r.remaining() < ntop * 5) return trunc;
  vm.top.resize(ntop);
  vm.coarse.resize(ntop);
  r.bytes(vm.top.data(), ntop * 4);
  r.bytes(vm.coarse.data(), ntop);
  if (!r.get(&nblocks)) return trunc;
  constexpr std::size_t kBlockBytes = kBlockVoxels * (4 + 1 + 1);
  if (nblocks > ntop || r.remaining() / kBlockBytes < nblocks) return trunc;
  for (std::int32_t t : vm.top) {
    if (t < kBlockUniformInside || t >= static_cast<std::int64_t>(nblocks)) return VpsError{"invalid block index"};
  }
  vm.blocks.resize(nblocks);
  for (VoxelBlock& b : vm.blocks) {
    r.bytes(b.sdf.data(), sizeof(b.sdf));
    r.bytes(b.layer.data(), sizeof(b.layer));
    r.bytes(b.flags.data(), sizeof(b.flags));
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (!std::isfinite(b.sdf[i]) || b.layer[i] == -128) return VpsError{"invalid voxel value"};
    }
  }
  PointShell ps;
  std::int32_t depth;
  std::uint64_t npts, nnodes;
  if (!r.get(&ps.voxel_size) || !r.vec3(&ps.reference_point) || !r.get(&ps.total_weight) || !r.get(&depth) ||
      !r.get(&npts))
    return trunc;
  if (!(ps.voxel_size > 0) || !std::isfinite(ps.voxel_size) || !ps.reference_point.allFinite() ||
      !std::isfinite(ps.total_weight) || depth < 0 || depth > 200)
    return VpsError{"invalid pointshell header"};
  ps.depth = depth;
  if (npts > (1ull << 31) || r.remaining() / 56 < npts) return trunc;
  ps.points.resize(npts);
  ps.normals.resize(npts);
  ps.weights.resize(npts);
  for (std::size_t i = 0; i < npts; ++i) {
    r.vec3(&ps.points[i]);
    r.vec3(&ps.normals[i]);
    r.get(&ps.weights[i]);
    if (!ps.points[i].allFinite() || !ps.normals[i].allFinite() || std::abs(ps.normals[i].norm() - 1.0) > 1e-6 ||
        !std::isfinite(ps.weights[i]) || ps.weights[i] < 0)
      return VpsError{"invalid point " + std::to_string(i)};
  }
  if (!r.get(&nnodes)) return trunc;
  if (nnodes > 2 * npts + 1 || r.remaining() / 48 < nnodes) return trunc;
  ps.nodes.resize(nnodes);
  for (std::size_t i = 0; i < nnodes; ++i) {
    SphereNode& n = ps.nodes[i];
    r.vec3(&n.centre);
    r.get(&n.radius);
    r.get(&n.first);
    r.get(&n.count);
    r.get(&n.left);
    r.get(&n.right);
    const auto nn = static_cast<std::int64_t>(nnodes);
    // Children come after their parent: no cycles, bounded traversal.
    const bool leaf = n.left == -1 && n.right == -1;
    const bool inner = n.left > static_cast<std::int64_t>(i) && n.right > static_cast<std::int64_t>(i) &&
                       n.left < nn && n.right < nn;
    if (!n.centre.allFinite() || !std::isfinite(n.radius) || n.radius < 0 || n.first < 0 || n.count < 0 ||
        static_cast<std::uint64_t>(n.first) + static_cast<std::uint64_t>(n.count) > npts || !(leaf || inner))
      return VpsError{"invalid sphere node " + std::to_string(i)};
  }
  if (r.remaining() != 0) return VpsError{"trailing bytes after the pointshell"};
  if (npts > 0 && nnodes == 0) return VpsError{"pointshell without a sphere tree"};
  *vm_out = std::move(vm);
  *ps_out = std::move(ps);
  return std::nullopt;
}

}  // namespace hemm::vps
