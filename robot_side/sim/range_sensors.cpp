#include "robot_side/sim/range_sensors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace hemm::robot {

double SimSonarParams::ring_radius(int beam) const {
  const double a = beam * 2 * std::numbers::pi / std::max(1, count);
  const double c = std::abs(std::cos(a)), s = std::abs(std::sin(a));
  // Where the beam axis leaves the rectangle +-half_length x +-half_width.
  const double rx = c > 1e-12 ? ring_half_length / c : std::numeric_limits<double>::infinity();
  const double ry = s > 1e-12 ? ring_half_width / s : std::numeric_limits<double>::infinity();
  return std::min(rx, ry);
}

bool measure_range(double r, double rmin, double rmax, double sigma, double p_drop, std::mt19937_64& rng,
                   float* out, bool* no_return) {
  *out = static_cast<float>(rmax);
  if (no_return != nullptr) *no_return = false;
  // The dropout is drawn first, for every beam: a dropout hides "nothing
  // there" as much as it hides a surface.
  if (p_drop > 0 && std::uniform_real_distribution<double>(0.0, 1.0)(rng) < p_drop) return false;
  if (!(r >= rmin && r <= rmax)) {  // no hit (negative), NaN, or out of limits
    if (no_return != nullptr) *no_return = r < 0.0 || r > rmax;
    return false;
  }
  double m = r;
  if (sigma > 0) m += std::normal_distribution<double>(0.0, sigma)(rng);
  *out = static_cast<float>(std::clamp(m, rmin, rmax));
  return true;
}

RangeScanData simulate_laser_scan(const SimLaserParams& p, const RayCaster& caster, const Eigen::Isometry3d& T_W_S,
                                  std::mt19937_64& rng) {
  RangeScanData s;
  s.kind = RangeSensorKind::kLaser;
  s.sensor_name = p.name;
  s.T_R_S = p.T_R_S;
  const int n = std::max(2, p.beams);
  s.angle_min = -0.5 * p.fov;
  s.angle_step = p.fov / (n - 1);
  s.range_min = p.range_min;
  s.range_max = p.range_max;
  s.beam_width = 0.0;
  s.ranges.resize(static_cast<size_t>(n));
  s.valid.resize(static_cast<size_t>(n));
  s.no_return.resize(static_cast<size_t>(n));
  const Eigen::Vector3d o = T_W_S.translation();
  for (int i = 0; i < n; ++i) {
    const double a = s.angle_min + i * s.angle_step;
    const Eigen::Vector3d d = T_W_S.linear() * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
    const double r = caster.cast(o, d);
    const auto k = static_cast<size_t>(i);
    bool none = false;
    s.valid[k] =
        measure_range(r, p.range_min, p.range_max, p.sigma, p.dropout_probability, rng, &s.ranges[k], &none) ? 1 : 0;
    s.no_return[k] = none ? 1 : 0;
  }
  return s;
}

RangeScanData simulate_sonar_scan(const SimSonarParams& p, const RayCaster& caster, const Eigen::Isometry3d& T_W_S,
                                  std::mt19937_64& rng) {
  RangeScanData s;
  s.kind = RangeSensorKind::kSonar;
  s.sensor_name = p.name;
  s.T_R_S = p.T_R_S;
  const int n = std::max(1, p.count);
  s.angle_min = 0.0;
  s.angle_step = 2 * std::numbers::pi / n;
  s.beam_width = p.cone;
  double rho_min = std::numeric_limits<double>::infinity(), rho_max = 0.0;
  for (int i = 0; i < n; ++i) {
    rho_min = std::min(rho_min, p.ring_radius(i));
    rho_max = std::max(rho_max, p.ring_radius(i));
  }
  s.range_min = p.range_min + rho_min;
  s.range_max = p.range_max + rho_max;
  s.ranges.resize(static_cast<size_t>(n));
  s.valid.resize(static_cast<size_t>(n));
  s.no_return.resize(static_cast<size_t>(n));
  const Eigen::Vector3d o = T_W_S.translation();
  const int rays = std::max(1, p.rays_per_cone);
  for (int i = 0; i < n; ++i) {
    const double axis = s.angle_min + i * s.angle_step;
    double nearest = -1.0;
    for (int k = 0; k < rays; ++k) {
      const double off = rays == 1 ? 0.0 : p.cone * (static_cast<double>(k) / (rays - 1) - 0.5);
      const Eigen::Vector3d d = T_W_S.linear() * Eigen::Vector3d(std::cos(axis + off), std::sin(axis + off), 0.0);
      const double r = caster.cast(o, d);
      if (r >= 0 && (nearest < 0 || r < nearest)) nearest = r;
    }
    const double rho = p.ring_radius(i);
    const auto k = static_cast<size_t>(i);
    float m = 0.0f;
    bool none = false;
    const bool ok = measure_range(nearest < 0 ? -1.0 : nearest - rho, p.range_min, p.range_max, p.sigma,
                                  p.dropout_probability, rng, &m, &none);
    s.valid[k] = ok ? 1 : 0;
    s.no_return[k] = none ? 1 : 0;
    s.ranges[k] = ok ? static_cast<float>(m + rho) : static_cast<float>(s.range_max);
  }
  return s;
}

}  // namespace hemm::robot
