// Skid-steer base control at 1 kHz: the (v, omega) setpoint slewed within the
// acceleration limits, left/right wheel speeds, and wheel odometry that drifts
// the way skid steer does. Pure functions; no clocks, no I/O.
#pragma once

#include <cstdint>

#include "common/math/workspace_maps.h"

namespace hemm::robot {

struct BaseLimits {
  double max_speed = 0.7;       // m/s
  double max_yaw_rate = 2.0;    // rad/s
  double max_accel = 1.0;       // m/s^2
  double max_yaw_accel = 4.0;   // rad/s^2
};

// Skid-steer geometry. A skid-steer base turns by slipping sideways, so its
// wheels must differ more than a differential drive's for the same yaw rate:
// the effective track is track_width * slip_factor (> 1). Odometry uses the
// same model, so it is right on straight lines and drifts when the real slip
// differs from the model (it always does a little).
struct SkidSteerGeometry {
  double wheel_radius = 0.1075;  // m
  double track_width = 0.40;     // m, left-right wheel centre distance
  double slip_factor = 1.5;      // effective track / track width

  double effective_track() const { return track_width * slip_factor; }
};

// The base's velocity setpoint (what the wheels are asked to do now).
struct BaseSetpoint {
  double v = 0.0;
  double omega = 0.0;
};

// Moves `current` toward (v_cmd, omega_cmd), clamped to the speed limits, by at
// most the acceleration limits times dt. Non-finite commands count as zero.
BaseSetpoint slew_setpoint(const BaseLimits& limits, const BaseSetpoint& current, double v_cmd, double omega_cmd,
                           double dt);

// Left/right wheel surface speeds (m/s) for a body motion: the same type the
// HEMM navigation map produces (common/math/workspace_maps.h).
using math::WheelSpeeds;
WheelSpeeds wheel_speeds(const SkidSteerGeometry& geometry, const BaseSetpoint& setpoint);
// Inverse: the body motion the model predicts from wheel surface speeds.
BaseSetpoint body_motion(const SkidSteerGeometry& geometry, const WheelSpeeds& wheels);

// Odometry pose in the world (odometry) frame and last body speeds.
struct Odometry {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;
  double v = 0.0;
  double omega = 0.0;
};
// Integrates one period of measured wheel speeds (exact arc for constant speeds).
void integrate_odometry(const SkidSteerGeometry& geometry, const WheelSpeeds& measured, double dt, Odometry& odometry);

}  // namespace hemm::robot
