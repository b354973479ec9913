#include "robot_side/control/seen_voxels.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hemm::robot {

std::optional<std::string> validate(const SeenVoxelParams& p) {
  if (!(p.voxel_size >= 0.002 && p.voxel_size <= 0.5)) return "seen voxels: voxel_size must be in [0.002, 0.5] m";
  if (p.keep_ns <= 0) return "seen voxels: keep_ns must be positive";
  if (p.max_voxels == 0 || p.max_voxels > 10'000'000) return "seen voxels: max_voxels must be in 1..1e7";
  if (!std::isfinite(p.min_z) || !(p.max_range > 0.0 && p.max_range <= 100.0))
    return "seen voxels: min_z finite, max_range in (0, 100] m";
  return std::nullopt;
}

SeenVoxels::SeenVoxels(const SeenVoxelParams& p) : p_(p) {
  if (auto e = validate(p)) throw std::invalid_argument(*e);
}

std::uint64_t SeenVoxels::key_of(const Eigen::Vector3d& p) const {
  // 21 bits per axis: +-20 km at 2 cm.
  const auto idx = [&](double x) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(x / p_.voxel_size)) + (1 << 20)) &
           0x1FFFFFu;
  };
  return idx(p.x()) | (idx(p.y()) << 21) | (idx(p.z()) << 42);
}

void SeenVoxels::forget_before(std::int64_t t_ns) {
  std::erase_if(voxels_, [&](const auto& kv) { return kv.second.stamp_ns < t_ns; });
}

std::size_t SeenVoxels::add_frame(const mapping::DepthImage& img, const Eigen::Isometry3d& T_P_S) {
  const mapping::DepthIntrinsics& K = img.K;
  const std::size_t n = static_cast<std::size_t>(std::max(0, K.width)) * static_cast<std::size_t>(std::max(0, K.height));
  std::size_t used = 0;
  if (img.depth.size() == n && img.status.size() == n && T_P_S.matrix().allFinite()) {
    for (int v = 0; v < K.height; ++v) {
      for (int u = 0; u < K.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(K.width) + static_cast<std::size_t>(u);
        if (img.status[i] != mapping::DepthStatus::kValid || !(img.depth[i] > 0.0f)) continue;
        const Eigen::Vector3d p_S = mapping::pixel_ray_z1(K, u, v) * static_cast<double>(img.depth[i]);
        if (!p_S.allFinite() || p_S.norm() > p_.max_range) continue;
        const Eigen::Vector3d p = T_P_S * p_S;
        if (p.z() < p_.min_z) continue;
        voxels_[key_of(p)] = Voxel{p.cast<float>(), img.stamp_ns};
        ++used;
      }
    }
  }
  forget_before(img.stamp_ns - p_.keep_ns);
  if (voxels_.size() > p_.max_voxels) {
    // The oldest go first: drop everything older than the max_voxels-th newest.
    std::vector<std::int64_t> stamps;
    stamps.reserve(voxels_.size());
    for (const auto& kv : voxels_) stamps.push_back(kv.second.stamp_ns);
    const auto nth = stamps.begin() + static_cast<std::ptrdiff_t>(stamps.size() - p_.max_voxels);
    std::nth_element(stamps.begin(), nth, stamps.end());
    forget_before(*nth);
    // Ties at the threshold stamp may still exceed the bound: drop any.
    for (auto it = voxels_.begin(); voxels_.size() > p_.max_voxels;) it = voxels_.erase(it);
  }
  return used;
}

std::size_t SeenVoxels::memory_bytes() const {
  // Nodes (key, value, next pointer, allocator header) and the bucket array.
  return voxels_.size() * (sizeof(std::uint64_t) + sizeof(Voxel) + 2 * sizeof(void*)) +
         voxels_.bucket_count() * sizeof(void*);
}

void SeenVoxels::points(std::vector<Eigen::Vector3f>* out) const {
  out->clear();
  out->reserve(voxels_.size());
  for (const auto& kv : voxels_) out->push_back(kv.second.point);
}

}  // namespace hemm::robot
