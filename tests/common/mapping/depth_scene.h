#pragma once
// Test helper: SIMULATED depth frames of a closed-form scene (floor, a table
// box, optionally a 10 cm block on it) with the depth camera's noise and
// dropouts, sent through the wire encoding into a live voxmap; and the exact
// force of a sphere pressed into a plane.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mapping/depth_stream.h"
#include "common/mapping/live_voxmap.h"

namespace hemm::test {

namespace hm = hemm::mapping;

inline constexpr double kTableTop = 0.7;

// Distance along unit d from o to the box [lo, hi], or -1.
inline double ray_box(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& lo,
               const Eigen::Vector3d& hi) {
  double t0 = 0.0, t1 = 1e9;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (o[k] < lo[k] || o[k] > hi[k]) return -1.0;
      continue;
    }
    double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1 && t0 > 0 ? t0 : -1.0;
}

// Distance along unit d from o to the upright cylinder of the given axis
// (x, y), radius and z range (side and both caps), or -1.
inline double ray_upright_cylinder(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector2d& axis,
                                   double radius, double z0, double z1) {
  double best = -1.0;
  auto take = [&](double t) {
    if (t > 0 && (best < 0 || t < best)) best = t;
  };
  const double ox = o.x() - axis.x(), oy = o.y() - axis.y();
  const double a = d.x() * d.x() + d.y() * d.y(), b = ox * d.x() + oy * d.y(), c = ox * ox + oy * oy - radius * radius;
  if (a > 1e-15 && b * b - a * c >= 0) {
    for (const double t : {(-b - std::sqrt(b * b - a * c)) / a, (-b + std::sqrt(b * b - a * c)) / a}) {
      const double z = o.z() + t * d.z();
      if (z >= z0 && z <= z1) take(t);
    }
  }
  if (std::abs(d.z()) > 1e-15) {
    for (const double zc : {z0, z1}) {
      const double t = (zc - o.z()) / d.z();
      const double x = ox + t * d.x(), y = oy + t * d.y();
      if (x * x + y * y <= radius * radius) take(t);
    }
  }
  return best;
}

struct TableScene {
  bool block = false;  // a 10 cm cube on the table at (1.0, 0.0)
  bool mug = false;    // the home scene's mug (radius 4 cm, 10 cm high) on the table at (1.2, 0.0)
  static constexpr double kMugRadius = 0.04, kMugHeight = 0.1;
  static Eigen::Vector2d mug_axis() { return {1.2, 0.0}; }
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = d.z() < 0 ? o.z() / -d.z() : -1.0;  // floor z = 0
    auto take = [&](double t) {
      if (t > 0 && (best < 0 || t < best)) best = t;
    };
    take(ray_box(o, d, {0.6, -0.5, 0.0}, {1.4, 0.5, kTableTop}));
    if (block) take(ray_box(o, d, {0.95, -0.05, kTableTop}, {1.05, 0.05, kTableTop + 0.1}));
    if (mug) take(ray_upright_cylinder(o, d, mug_axis(), kMugRadius, kTableTop, kTableTop + kMugHeight));
    return best;
  }
};

inline Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

// A depth frame of the scene (anything with cast(o, d) -> range or -1) with
// the camera's noise (sigma 1 mm + 1.5 mm/m^2 r^2) and 1 % dropouts, through
// the wire encoding into the map.
template <typename Scene>
bool observe(const Scene& scene, const Eigen::Isometry3d& T_W_S, std::uint32_t id, std::mt19937_64& rng,
             hm::LiveVoxmap* map) {
  hm::DepthImage img;
  img.cloud_id = id;
  img.K = hm::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  img.T_W_S = img.T_W_S_truth = T_W_S;
  img.depth.assign(80 * 60, 0.0f);
  img.status.assign(80 * 60, hm::DepthStatus::kDropout);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int v = 0; v < 60; ++v) {
    for (int u = 0; u < 80; ++u) {
      const auto i = static_cast<std::size_t>(v * 80 + u);
      const Eigen::Vector3d ray = hm::pixel_ray_z1(img.K, u, v);
      const double r = scene.cast(T_W_S.translation(), T_W_S.linear() * ray.normalized());
      if (uni(rng) < 0.01) continue;
      if (r < 0 || r > img.K.range_max) {
        img.status[i] = hm::DepthStatus::kNoReturn;
      } else if (r >= img.K.range_min) {
        const double m = r + (0.001 + 0.0015 * r * r) * noise(rng);
        img.status[i] = hm::DepthStatus::kValid;
        img.depth[i] = static_cast<float>(m / ray.norm());
      }
    }
  }
  std::vector<hemm::wire::DepthChunk> chunks;
  if (hm::encode_depth_chunks(img, "depth", {}, &chunks)) return false;
  for (const auto& c : chunks) {
    hm::DepthChunkData d;
    if (hm::decode_depth_chunk(c, 0, &d)) return false;
    map->integrate(d);
  }
  return true;
}

inline bool observe_table(const TableScene& scene, int frames, std::mt19937_64& rng, hm::LiveVoxmap* map) {
  // Three viewpoints of a camera held 0.7 m above the table, 0.5-0.9 m from the near edge.
  const Eigen::Vector3d target(1.0, 0.0, kTableTop);
  for (int f = 0; f < frames; ++f) {
    const double y = -0.3 + 0.3 * (f % 3);
    if (!observe(scene, look_at({0.15, y, 1.4}, target), static_cast<std::uint32_t>(f), rng, map)) return false;
  }
  return true;
}

// K times the volume of a sphere's cap of depth d: the exact force of a
// sphere of radius R pressed d into a half-space (pressure K p along n).
inline double cap_force(double K, double R, double d) { return K * std::numbers::pi * d * d * (3 * R - d) / 3.0; }

}  // namespace hemm::test
