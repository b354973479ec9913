#include "robot_side/sim/depth_camera.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace hemm::robot {

mapping::DepthIntrinsics SimDepthCameraParams::intrinsics() const {
  return mapping::intrinsics_from_hfov(width, height, hfov, range_min, range_max);
}

std::optional<std::string> check_params(const SimDepthCameraParams& p) {
  if (p.width < 1 || p.width > 1024 || p.height < 1 || p.height > 1024) return "depth camera: size not in 1..1024";
  if (!(p.hfov > 0.0 && p.hfov < 170.0 * std::numbers::pi / 180.0)) return "depth camera: hfov not in (0, 170) deg";
  if (!(p.range_min > 0.0 && p.range_min < p.range_max && p.range_max <= 100.0))
    return "depth camera: need 0 < range_min < range_max <= 100 m";
  if (!(p.sigma_0 >= 0.0 && p.sigma_2 >= 0.0 && p.sigma_0 < 1.0 && p.sigma_2 < 1.0))
    return "depth camera: noise sigmas not in [0, 1)";
  if (!(p.dropout_probability >= 0.0 && p.dropout_probability <= 1.0))
    return "depth camera: dropout probability not in [0, 1]";
  if (!(p.rate_hz > 0.0 && p.rate_hz <= 100.0)) return "depth camera: rate not in (0, 100] Hz";
  if (!std::isfinite(p.edge_jump_fraction)) return "depth camera: edge_jump_fraction not finite";
  return std::nullopt;
}

void SimPanTiltHead::step(const HeadParams& limits, double pan_sp, double tilt_sp, double dt) {
  const double a = params.time_constant > 0.0 ? 1.0 - std::exp(-dt / params.time_constant) : 1.0;
  pan = std::clamp(pan + (pan_sp - pan) * a, limits.pan_min, limits.pan_max);
  tilt = std::clamp(tilt + (tilt_sp - tilt) * a, limits.tilt_min, limits.tilt_max);
}

Eigen::Vector2d SimPanTiltHead::read_encoders(std::mt19937_64& rng) const {
  std::normal_distribution<double> n(0.0, 1.0);
  const double e_pan = params.encoder_sigma * n(rng), e_tilt = params.encoder_sigma * n(rng);
  return {pan + params.pan_bias + e_pan, tilt + params.tilt_bias + e_tilt};
}

std::optional<std::string> check(const SimPanTiltHeadParams& p) {
  if (!(p.time_constant >= 0.0 && p.time_constant <= 2.0)) return "pan-tilt head: time constant not in [0, 2] s";
  if (!(std::abs(p.pan_bias) < 0.2 && std::abs(p.tilt_bias) < 0.2)) return "pan-tilt head: encoder bias not finite or too large";
  if (!(p.encoder_sigma >= 0.0 && p.encoder_sigma < 0.1)) return "pan-tilt head: encoder sigma not in [0, 0.1) rad";
  return std::nullopt;
}

mapping::DepthImage simulate_depth_image(const SimDepthCameraParams& p, const RayCaster& caster,
                                         const Eigen::Isometry3d& T_W_S, std::mt19937_64& rng) {
  mapping::DepthImage img;
  img.K = p.intrinsics();
  const auto n = static_cast<std::size_t>(p.width) * static_cast<std::size_t>(p.height);
  img.depth.assign(n, 0.0f);
  img.status.assign(n, mapping::DepthStatus::kDropout);
  // True range along each unit ray first: the edge test needs the neighbours.
  std::vector<double> r_true(n), z_per_r(n);
  const Eigen::Vector3d o = T_W_S.translation();
  for (int v = 0; v < p.height; ++v) {
    for (int u = 0; u < p.width; ++u) {
      const Eigen::Vector3d ray = mapping::pixel_ray_z1(img.K, u, v);
      const double len = ray.norm();
      const auto i = static_cast<std::size_t>(v) * p.width + u;
      r_true[i] = caster.cast(o, T_W_S.linear() * (ray / len));
      z_per_r[i] = 1.0 / len;
    }
  }
  auto jump = [&](std::size_t i, std::size_t j) {
    const double a = r_true[i], b = r_true[j];
    if (a < 0.0 && b < 0.0) return false;
    if (a < 0.0 || b < 0.0) return true;  // one of them sees nothing: an edge
    return std::abs(a - b) > p.edge_jump_fraction * a;
  };
  for (int v = 0; v < p.height; ++v) {
    for (int u = 0; u < p.width; ++u) {
      const auto i = static_cast<std::size_t>(v) * p.width + u;
      const double r = r_true[i];
      bool edge = false;
      if (p.edge_jump_fraction > 0.0 && r >= 0.0) {
        edge = (u > 0 && jump(i, i - 1)) || (u + 1 < p.width && jump(i, i + 1)) ||
               (v > 0 && jump(i, i - p.width)) || (v + 1 < p.height && jump(i, i + p.width));
      }
      float m = 0.0f;
      bool none = false;
      const double sigma = r >= 0.0 ? p.sigma_0 + p.sigma_2 * r * r : 0.0;
      // The dropout draw happens for every pixel (measure_range), edges too,
      // so the noise sequence does not depend on the scene's edges.
      const bool ok = measure_range(r, p.range_min, p.range_max, sigma, p.dropout_probability, rng, &m, &none);
      if (ok && !edge) {
        img.status[i] = mapping::DepthStatus::kValid;
        img.depth[i] = static_cast<float>(m * z_per_r[i]);
      } else if (none) {
        img.status[i] = mapping::DepthStatus::kNoReturn;
      }
    }
  }
  return img;
}

}  // namespace hemm::robot
