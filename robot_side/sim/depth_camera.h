// SIMULATED depth camera (time-of-flight class): one ray per pixel cast
// through a RayCaster (MuJoCo's mj_ray on the robot, closed-form scenes in
// tests), with the failure modes such sensors have: range limits, noise that
// grows with range, random dropouts, and "flying pixels" at depth
// discontinuities dropped as camera drivers drop them.
//
// Default resolution and rate, and why: 80 x 60 pixels over a 60 degree
// horizontal field of view is 0.75 degree per pixel, 1.3 cm between samples
// at 1 m -- about one sample per voxel of the 1-2 cm voxmap the tool needs at
// arm's reach (0.4-1.5 m), so finer images would mostly be averaged away by
// the voxel grid. 15 Hz matches the robot's arm speed during exploration
// (it stands still) and keeps the stream near 1.5 Mbit/s (depth_stream.h);
// 4800 mj_ray calls per frame fit the station's budget at that rate.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <string>

#include "common/mapping/depth_image.h"
#include "robot_side/control/head_control.h"
#include "robot_side/sim/range_sensors.h"

namespace hemm::robot {

// The SIMULATED pan-tilt head's joints and encoders. Each joint follows its
// rate-limited setpoint (head_control.h) with a first-order lag of
// time_constant (exact for a setpoint held over the step: x += (sp - x)(1 -
// exp(-dt / tau)); 0: it is the setpoint), within the joint limits. The
// encoders read the true angle plus a fixed bias plus white Gaussian noise
// of sigma per reading (a small servo with a 12-bit magnetic encoder: a few
// tenths of a degree of mounting offset, 0.05 degree of noise), so the pose
// the frames are reported with is not the truth.
struct SimPanTiltHeadParams {
  double time_constant = 0.08;  // s
  double pan_bias = 0.3 * std::numbers::pi / 180.0, tilt_bias = -0.2 * std::numbers::pi / 180.0;  // rad
  double encoder_sigma = 0.05 * std::numbers::pi / 180.0;                                         // rad
};
struct SimDepthCameraParams {
  std::string name = "depth";
  int width = 80;
  int height = 60;
  double hfov = 60.0 * std::numbers::pi / 180.0;  // rad; vfov follows from square pixels (46.8 deg)
  double range_min = 0.2;   // m along the ray (ToF modules: 0.1-0.5 m)
  double range_max = 3.0;   // m along the ray
  // Range noise sigma(r) = sigma_0 + sigma_2 r^2 (m), the quadratic growth of
  // triangulating and phase-based sensors: 2.5 mm at 1 m, 1.5 cm at 3 m.
  double sigma_0 = 0.001;
  double sigma_2 = 0.0015;
  double dropout_probability = 0.01;  // per pixel, independent
  // A pixel whose true range differs from a 4-neighbour's by more than this
  // fraction of its own range straddles an edge (a mixed / flying pixel) and
  // is dropped; also drops most grazing returns. <= 0 disables.
  double edge_jump_fraction = 0.05;
  double rate_hz = 15.0;
  // Mount: sensor frame S (optical: z forward, x right, y down) in the frame
  // it is attached to. On the robot that is the end-effector frame E (x_E
  // along the tool): the camera looks along the tool from 6 cm behind and
  // 4 cm above the tip, so the tool's workspace ahead is in view (the tip
  // itself is nearer than range_min). The wrist, not a mast, because the
  // arm then aims the camera at tops and sides of what it explores (HEMM's
  // robot carries its camera there) and the tool's own region of interest
  // is always the best seen.
  Eigen::Isometry3d T_mount_S = default_wrist_mount();
  // True: T_mount_S is in the base frame R (a mast), not in E. The station
  // mounts it there by default (config depth_camera.mount): in exploration
  // the robot and its arm stand still (HEMM Fig. 9), so a wrist camera would
  // hold one view anyway, and from 1.1 m a mast sees the tops of table-high
  // objects the folded arm's wrist cannot; its pose at acquisition is the
  // odometry's alone (no arm kinematics error).
  bool mount_on_base = false;

  // A mast at (x, 0, z) in R looking along +x_R, pitched down by pitch (rad):
  // the pan-tilt head's pose at pan 0, tilt pitch.
  static Eigen::Isometry3d mast_mount(double x, double z, double pitch) {
    return head_T_R_S(Eigen::Vector3d(x, 0.0, z), 0.0, pitch);
  }

  static Eigen::Isometry3d default_wrist_mount() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = Eigen::Vector3d(0, -1, 0);  // x_S: right of the tool
    T.linear().col(1) = Eigen::Vector3d(0, 0, -1);  // y_S: down
    T.linear().col(2) = Eigen::Vector3d(1, 0, 0);   // z_S: along the tool
    T.translation() << -0.06, 0.0, 0.04;
    return T;
  }

  // True: a SIMULATED pan-tilt head carries the camera (mount "pan-tilt"):
  // mount_on_base is true too and T_mount_S is the head's home pose; the
  // frame's pose follows the head (head, head_plant).
  bool pan_tilt = false;
  HeadParams head;
  SimPanTiltHeadParams head_plant;

  mapping::DepthIntrinsics intrinsics() const;
};

struct SimPanTiltHead {
  SimPanTiltHeadParams params;
  double pan = 0.0, tilt = 0.0;  // the truth, rad
  void step(const HeadParams& limits, double pan_sp, double tilt_sp, double dt);
  // One encoder reading of each joint (pan, tilt).
  Eigen::Vector2d read_encoders(std::mt19937_64& rng) const;
};
std::optional<std::string> check(const SimPanTiltHeadParams& p);

// Casts one image from the true sensor pose T_W_S. Fills depth, status and K;
// stamp, cloud id and the reported poses are the caller's.
mapping::DepthImage simulate_depth_image(const SimDepthCameraParams& params, const RayCaster& caster,
                                         const Eigen::Isometry3d& T_W_S, std::mt19937_64& rng);

// Validates params (sizes 1..1024, fov in (0, 170 deg), 0 < range_min <
// range_max <= 100, noise and probabilities in range); a reason or nothing.
std::optional<std::string> check_params(const SimDepthCameraParams& params);

}  // namespace hemm::robot
