#pragma once
// Test helper: SIMULATED range scans, generated analytically by casting rays
// against exact geometry (the caller supplies the ray cast).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/mapping/range_scan.h"
#include "common/math/geometry2.h"

namespace hemm::test {

struct SynthScanSpec {
  mapping::SensorKind kind = mapping::SensorKind::kLaser;
  int beams = 181;
  double angle_min = -std::numbers::pi / 2;
  double angle_step = std::numbers::pi / 180;
  double range_min = 0.05;
  double range_max = 10.0;
  double sigma = 0.0;             // range noise, m
  double dropout_probability = 0.0;
  double beam_width = 0.0;        // sonar cone
  int rays_per_cone = 1;          // sonar: nearest echo over this many rays across the cone
  std::uint32_t seed = 1;
  // As the operator's scan conversion reports a beam that saw nothing up to
  // range_max (wire no_return): valid at range_max, free space, not a return.
  // false: flagged invalid like a dropout (senders without no_return).
  bool no_return_valid = false;
};

// Exact test geometry in W: thin segments and solid circles, with the ray
// cast synth_scan needs and the exact distance to the nearest surface.
struct Shapes2D {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segs;
  std::vector<std::pair<Eigen::Vector2d, double>> circles;

  std::optional<double> ray(const Eigen::Vector2d& o, const Eigen::Vector2d& u, double max_range) const {
    double best = max_range;
    bool hit = false;
    for (const auto& [a, b] : segs) {
      const Eigen::Vector2d e = b - a;
      const double den = math::cross2(u, e);
      if (std::abs(den) < 1e-15) continue;
      const Eigen::Vector2d w = a - o;
      const double t = math::cross2(w, e) / den, q = math::cross2(w, u) / den;
      if (t >= 0 && q >= 0 && q <= 1 && t < best) best = t, hit = true;
    }
    for (const auto& [c, r] : circles) {
      const Eigen::Vector2d f = o - c;
      const double b = f.dot(u), disc = b * b - (f.squaredNorm() - r * r);
      if (disc < 0) continue;
      const double t = -b - std::sqrt(disc);
      if (t >= 0 && t < best) best = t, hit = true;
    }
    return hit ? std::optional<double>(best) : std::nullopt;
  }
  double distance(const Eigen::Vector2d& p) const {
    double d = 1e300;
    for (const auto& [a, b] : segs) d = std::min(d, math::distance_to_segment(a, b, p));
    for (const auto& [c, r] : circles) d = std::min(d, std::abs((p - c).norm() - r));
    return d;
  }
  auto rayfn() const {
    return [this](const Eigen::Vector2d& o, const Eigen::Vector2d& u, double m) { return ray(o, u, m); };
  }
};

// ray(origin_W, unit_dir_W, max_range) -> optional distance.
template <class RayFn>
mapping::RangeScan2D synth_scan(const RayFn& ray, const math::Pose2& T_W_R, const math::Pose2& T_R_S,
                                std::int64_t stamp_ns, const SynthScanSpec& spec) {
  mapping::RangeScan2D s;
  s.stamp_ns = stamp_ns;
  s.T_W_R = T_W_R;
  s.T_R_S = T_R_S;
  s.kind = spec.kind;
  s.angle_min = spec.angle_min;
  s.angle_step = spec.angle_step;
  s.range_min = spec.range_min;
  s.range_max = spec.range_max;
  s.beam_width = spec.beam_width;
  std::mt19937 rng(spec.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const math::Pose2 T_W_S = math::compose(T_W_R, T_R_S);
  const Eigen::Vector2d o = math::translation(T_W_S);
  for (int i = 0; i < spec.beams; ++i) {
    const double a = spec.angle_min + i * spec.angle_step;
    std::optional<double> best;
    const int rays = spec.kind == mapping::SensorKind::kSonar ? std::max(1, spec.rays_per_cone) : 1;
    for (int k = 0; k < rays; ++k) {
      const double off = rays == 1 ? 0.0 : spec.beam_width * (static_cast<double>(k) / (rays - 1) - 0.5);
      const Eigen::Vector2d dir = math::rotate(T_W_S, Eigen::Vector2d(std::cos(a + off), std::sin(a + off)));
      const std::optional<double> r = ray(o, dir, spec.range_max);
      if (r && (!best || *r < *best)) best = r;
    }
    const bool drop = uni(rng) < spec.dropout_probability;
    if (!best || drop) {
      s.ranges.push_back(drop ? 0.0f : static_cast<float>(spec.range_max));  // a dropout reads 0: must not matter
      s.valid.push_back(!drop && spec.no_return_valid ? 1 : 0);
      continue;
    }
    const double r = *best + spec.sigma * noise(rng);
    s.ranges.push_back(static_cast<float>(r));
    s.valid.push_back(r >= spec.range_min && r < spec.range_max ? 1 : 0);
  }
  return s;
}

}  // namespace hemm::test
