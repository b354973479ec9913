// The depth camera's pan-tilt head controller (issue 24): pure functions
// over explicit state, MuJoCo-free. The operator sends a gaze target (a
// point in the odometry world frame W, hemm.wire.Gaze); the controller turns
// it into joint goals, checks it, and slews its joint setpoints toward the
// goal at a rate limit (a real head does not jump; the joints' own lag is
// the plant's, robot_side/sim/depth_camera.h SimPanTiltHead).
//
// Geometry: the head's optical centre sits on both axes at head_R (frame R).
// Pan turns about z_R (0: looking along +x_R, CCW positive); tilt lowers
// the optical axis below the horizontal (down positive), so pan 0, tilt p
// is the fixed mast camera pitched down by p (SimDepthCameraParams::
// mast_mount). A target p_R is looked at with pan = atan2(d_y, d_x), tilt =
// atan2(-d_z, |d_xy|), d = p_R - head_R.
//
// Checks, in order (GazeRefusal): a non-finite target, one nearer than
// min_range or farther than max_range from the head, one that needs a pan
// or tilt beyond the joint limits is refused: counted, its sequence number
// kept, and the head holds where its setpoint is (no new goal). Only
// accepted targets feed the gaze watchdog: without one for gaze_timeout_ns,
// with an inactive gaze, without an operator in control or with the link
// lost, the head returns to home; with the e-stop engaged it holds. A target
// in W is re-aimed every step from the current odometry, so the head keeps
// looking at it while the base turns (clamped to the limits then).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>

#include "robot_side/control/watchdog.h"

namespace hemm::robot {

// Values are hemm.wire.GazeRefusalReason's (static_assert in simulated_robot.cpp).
enum class GazeRefusal : int { kNone = 0, kNotFinite = 1, kTooNear = 2, kTooFar = 3, kPanLimit = 4, kTiltLimit = 5 };

struct HeadParams {
  Eigen::Vector3d head_R = Eigen::Vector3d(0.10, 0.0, 1.10);  // optical centre, frame R
  double pan_min = -100.0 * std::numbers::pi / 180.0, pan_max = 100.0 * std::numbers::pi / 180.0;  // rad
  double tilt_min = -10.0 * std::numbers::pi / 180.0, tilt_max = 80.0 * std::numbers::pi / 180.0;  // rad
  double home_pan = 0.0, home_tilt = 35.0 * std::numbers::pi / 180.0;  // rad: the mast camera's view
  double max_rate = 90.0 * std::numbers::pi / 180.0;  // rad/s, setpoint slew per joint
  double min_range = 0.3, max_range = 4.0;             // m from head_R
  std::int64_t gaze_timeout_ns = 500'000'000;
};

// A reason if unusable: finite, min < max limits with home inside, rate > 0,
// 0 <= min_range < max_range, timeout > 0.
std::optional<std::string> check(const HeadParams& p);

// The sensor frame S (optical: z forward, x right, y down) in R at (pan, tilt).
Eigen::Isometry3d head_T_R_S(const Eigen::Vector3d& head_R, double pan, double tilt);

struct HeadAim {
  GazeRefusal refusal = GazeRefusal::kNone;
  double pan = 0.0, tilt = 0.0;  // rad; meaningful (also when refused for a limit) unless kNotFinite / kTooNear
};
// The joint angles that put the optical axis through point_R, with the checks above.
HeadAim aim_head(const HeadParams& p, const Eigen::Vector3d& point_R);

struct HeadControlState {
  double pan_sp = 0.0, tilt_sp = 0.0;  // rate-limited setpoints, rad
  bool following = false;              // an accepted target is in force (until the watchdog expires)
  Eigen::Vector3d target_W = Eigen::Vector3d::Zero();
  Watchdog gaze_watchdog;
  std::uint64_t refusals = 0;
  GazeRefusal last_refusal = GazeRefusal::kNone;
  std::uint64_t last_refused_seq = 0;
  bool holding = false;                // a refusal or the e-stop holds the setpoints where they are
};

// At home, no target.
HeadControlState head_control_init(const HeadParams& p);

// A gaze command (the operator's, received at now_ns; seq: its datagram's
// sequence number) with the odometry pose T_W_R. Active and accepted: the
// new target. Inactive: no target (home). Refused: counted, the head holds.
GazeRefusal head_gaze_command(const HeadParams& p, HeadControlState& s, const Eigen::Vector3d& point_W, bool active,
                              const Eigen::Isometry3d& T_W_R, std::uint64_t seq, std::int64_t now_ns);

// One control period of dt seconds: the goal (the target re-aimed from T_W_R
// and clamped to the limits; home when there is none, the watchdog expired
// or `may_follow` is false; the setpoints themselves while holding or with
// `estop`), and the setpoints slewed toward it by at most max_rate * dt.
void head_control_step(const HeadParams& p, HeadControlState& s, const Eigen::Isometry3d& T_W_R, bool may_follow,
                       bool estop, std::int64_t now_ns, double dt);

}  // namespace hemm::robot
