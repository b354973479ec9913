// SIMULATED range sensors: a planar laser range finder and a ring of sonars,
// each ray cast through an abstract RayCaster (MuJoCo's mj_ray in the
// simulation, anything in tests), with Gaussian range noise and random
// dropouts. A dropout or a missing return is flagged invalid, never reported
// as a range of zero; no_return tells them apart (nothing up to range_max is
// free space the operator's map clears through; a dropout says nothing).
#pragma once

#include <cstdint>
#include <numbers>
#include <random>
#include <string>

#include "robot_side/sim/sim_types.h"

namespace hemm::robot {

// Distance along the unit direction `dir_W` from `origin_W` to the first
// surface the sensor can see, or a negative value for no hit.
class RayCaster {
 public:
  virtual ~RayCaster() = default;
  virtual double cast(const Eigen::Vector3d& origin_W, const Eigen::Vector3d& dir_W) const = 0;
};

struct SimLaserParams {
  std::string name = "laser";
  int beams = 181;
  double fov = std::numbers::pi;  // rad
  double range_min = 0.05;
  double range_max = 10.0;
  double sigma = 0.01;
  double rate_hz = 30.0;
  double dropout_probability = 0.01;
  Eigen::Isometry3d T_R_S = Eigen::Isometry3d::Identity();
};

// The sonar ring: `count` transducers evenly spaced around the base, beam i at
// angle i * 2 pi / count (beam 0 forward). Each beam's cone is sampled by
// `rays_per_cone` rays; the nearest echo wins. S is the ring centre; the
// transducer of beam i sits `ring_radius(i)` out along its axis, and its
// range limits apply from there (the reported range is from S).
struct SimSonarParams {
  std::string name = "sonar";
  int count = 16;
  double cone = 15.0 * std::numbers::pi / 180.0;  // rad, full angle
  int rays_per_cone = 5;
  double range_min = 0.1;
  double range_max = 5.0;
  double sigma = 0.01;
  double rate_hz = 10.0;
  double dropout_probability = 0.02;
  double ring_half_length = 0.245;  // transducers on the rectangle +-half_length x +-half_width
  double ring_half_width = 0.15;
  Eigen::Isometry3d T_R_S = Eigen::Isometry3d::Identity();

  double ring_radius(int beam) const;
};

// A measured range from a true one: returns false (invalid) for no hit, out of
// [range_min, range_max], or a dropout; else adds N(0, sigma) noise, clamped
// into the limits. *no_return (optional) is set when the beam is invalid
// because nothing lies within range_max (no hit or beyond it, and no
// dropout); a dropout, a hit below range_min or a NaN leave it false.
bool measure_range(double true_range, double range_min, double range_max, double sigma, double dropout_probability,
                   std::mt19937_64& rng, float* out, bool* no_return = nullptr);

// Casts one scan. T_W_S is the true sensor pose used to cast; the poses that
// the scan reports (odometry, truth) and the stamp are filled in by the caller.
RangeScanData simulate_laser_scan(const SimLaserParams& params, const RayCaster& caster,
                                  const Eigen::Isometry3d& T_W_S, std::mt19937_64& rng);
RangeScanData simulate_sonar_scan(const SimSonarParams& params, const RayCaster& caster,
                                  const Eigen::Isometry3d& T_W_S, std::mt19937_64& rng);

}  // namespace hemm::robot
