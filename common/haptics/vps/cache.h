// The .vps cache: a voxmap and a pointshell in one versioned byte buffer.
// Pure (bytes in, bytes out); file reading lives in the hemm-vps tool.
//
// Layout (little-endian): "HEMMVPS\0" magic, u32 version, u32 reserved,
// u64 payload size, u64 FNV-1a-64 checksum of the payload, payload. Loading
// checks every size and value; a truncated or corrupt buffer gives a clear
// error and leaves the outputs untouched.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/haptics/vps/pointshell.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::vps {

inline constexpr std::uint32_t kCacheVersion = 2;  // 2: voxel gradients and sheets, multi-level float pointshell

std::vector<std::uint8_t> serialize_vps(const Voxmap& vm, const PointShell& ps);

std::optional<VpsError> deserialize_vps(const std::uint8_t* data, std::size_t size, Voxmap* vm, PointShell* ps);

std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t size);

}  // namespace hemm::vps
