// Choosing where the robot's depth camera looks (issue 24): the operator's
// side of the active gaze. Pure computation over explicit state; the command
// sender (network thread) calls it once per command and sends the result in
// hemm.wire.Command.gaze (robot_side/control/head_control.h turns it into
// the head's joint goals).
//
// The point: the tool's predicted position -- its goal position plus its
// velocity (a finite difference of the goal positions, smoothed by a first-
// order filter of time constant velocity_tau_s) times lookahead_s, the step
// capped at max_lookahead_m -- pulled toward what the model marks unseen
// near it: candidates (plain data: points in W with weights, e.g. the centres
// of unseen / unknown cells from the live voxmap's free-space record) within
// unseen_radius_m of the predicted position. Their weighted centroid c with
// total weight w moves the point to p + a (c - p), a = k w / (1 + k w), k =
// unseen_gain: a few unseen cells nudge it, many bring it most of the way.
// The point is kept in the region of interest when one is given.
//
// Hysteresis: the chosen point is sent unchanged until the new choice is
// more than hysteresis_m away from it, so a hand trembling on a surface does
// not make the head dither (a camera's view barely changes for a few cm at
// arm's reach: 5 cm at 1 m is 3 degrees of a 60 degree image). Without a
// tool position (no tool, its pose not finite, or the tool inactive) the gaze
// is inactive: the head goes home.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace hemm::op {

struct GazeParams {
  double lookahead_s = 0.4;       // s ahead of the tool's goal
  double max_lookahead_m = 0.25;  // cap on the look-ahead step
  double velocity_tau_s = 0.1;    // smoothing of the goal's velocity
  double unseen_radius_m = 0.25;  // unseen candidates this near the predicted point count
  double unseen_gain = 0.05;      // k per unit of weight (a = k w / (1 + k w))
  double hysteresis_m = 0.05;     // the sent point moves only for a change beyond this
};

// A reason if unusable (all finite, non-negative; tau and radius positive).
std::optional<std::string> check(const GazeParams& p);

// Something the model would like seen, in W (e.g. an unseen cell's centre).
struct GazeCandidate {
  Eigen::Vector3d point_W = Eigen::Vector3d::Zero();
  double weight = 1.0;  // non-finite or <= 0: ignored
};

struct GazeChooserState {
  bool have_tool = false;
  Eigen::Vector3d last_tool_W = Eigen::Vector3d::Zero();
  std::int64_t last_t_ns = 0;
  Eigen::Vector3d velocity_W = Eigen::Vector3d::Zero();
  bool have_gaze = false;
  Eigen::Vector3d gaze_W = Eigen::Vector3d::Zero();  // the point being sent
  std::uint64_t moves = 0;                           // times the sent point moved
};

struct GazeChoice {
  bool active = false;
  Eigen::Vector3d point_W = Eigen::Vector3d::Zero();  // what to send (the held point)
  Eigen::Vector3d predicted_W = Eigen::Vector3d::Zero();  // the tool's look-ahead position
  Eigen::Vector3d wanted_W = Eigen::Vector3d::Zero();     // before the hysteresis
};

// One choice at t_ns from the tool's goal position (nullopt: no tool).
GazeChoice choose_gaze(const GazeParams& p, GazeChooserState& s, const std::optional<Eigen::Vector3d>& tool_W,
                       std::int64_t t_ns, std::span<const GazeCandidate> unseen,
                       const std::optional<Eigen::AlignedBox3d>& roi_W = std::nullopt);

}  // namespace hemm::op
