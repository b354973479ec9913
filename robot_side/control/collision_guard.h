// The robot station's collision guard: limits the base's speeds from the
// robot's own range data. Pure functions over explicit state.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/Core>

namespace hemm::robot {

// The guard limits the base's speeds from the robot's own range data (frame
// R: x forward, y left; the base turns about the R origin):
//  * straight motion: the forward (backward) speed whose stopping distance
//    v t_r + v^2 / (2 a) plus `margin` fits in the free length of the corridor
//    the swept footprint covers ahead (behind);
//  * unknown space is not free: the corridor counts as free only as far as
//    the sensors saw it free (KnownFree below); beyond that the guard allows
//    at most `unknown_speed` (a crawl whose stopping distance is ~1 cm), so
//    reversing with no data behind, or driving at what the laser drops out
//    on, is slow, not blind;
//  * turning in place: the yaw rate (each way) whose stopping angle
//    w t_r + w^2 / (2 a_yaw) fits in the angle the footprint (with the arm,
//    when it is out) can turn before it meets a return, the footprint grown
//    by `turn_margin`; a return already inside the grown footprint stops
//    turning;
//  * a return inside the base's own body (shrunk by inside_tolerance, the
//    range noise): something is in contact or inside the robot: everything
//    stops.
// Combined motion is guarded by both limits, each for its own motion (arcs
// are not swept exactly). Turning into space no sensor has seen is not
// limited (the sonar ring sees all round).
struct CollisionGuardParams {
  // The swept footprint (the base, grown by the arm when it reaches out).
  double front_x = 0.245;      // m, foremost point of the robot (incl. the arm, updated live)
  double rear_x = -0.245;      // m, rearmost point
  double half_width = 0.25;    // m, half the corridor the base sweeps
  // The base's own body (chassis and wheels, robot.xml).
  double body_front_x = 0.245;
  double body_rear_x = -0.245;
  double body_half_width = 0.25;
  double inside_tolerance = 0.02;  // m: a return this close inside the body is range noise, not a contact
  double margin = 0.15;        // m, distance kept to any obstacle (collision_margin_m)
  double turn_margin = 0.05;   // m, the footprint grows by this for turning
  double max_decel = 1.0;      // m/s^2 the base can brake with
  double max_yaw_decel = 4.0;  // rad/s^2 the base can stop turning with
  double reaction_time = 0.05;  // s, actuation lag before braking starts
  double unknown_speed = 0.1;  // m/s at most into space no sensor has seen free
};

struct GuardLimit {
  double max_forward = 0.0;   // m/s, >= 0
  double max_backward = 0.0;  // m/s, >= 0 (magnitude)
  double max_yaw_ccw = 0.0;   // rad/s, >= 0 (turning left)
  double max_yaw_cw = 0.0;    // rad/s, >= 0 (magnitude, turning right)
  double free_ahead = 0.0;    // m, free length in front of the footprint (inf: none seen)
  double free_behind = 0.0;
  double known_ahead = 0.0;   // m, how far the corridor ahead was seen free (inf: not limited)
  double known_behind = 0.0;
  double free_turn_ccw = 0.0;  // rad the footprint can turn left before it meets a return (inf: none)
  double free_turn_cw = 0.0;
  bool inside = false;        // a return inside the body: all limits 0
};

// What the sensors saw free, by bearing around the R origin: sector k covers
// bearings [-pi + k w, -pi + (k + 1) w), w = 2 pi / kGuardSectors, and holds
// the distance up to which a sensor saw it free (0: never seen).
inline constexpr int kGuardSectors = 360;
using KnownFree = std::array<double, kGuardSectors>;

// The guard's limits from the returns (obstacle points, frame R) and, if
// given, what is known free (nullptr: everything is, as with full coverage).
GuardLimit collision_guard(const CollisionGuardParams& params, std::span<const Eigen::Vector2d> points_R,
                           const KnownFree* known = nullptr);

// The speed whose stopping distance (reaction + braking) equals `distance`
// (also angular: a yaw rate from an angle and an angular deceleration).
double stoppable_speed(double distance, double decel, double reaction_time);

// Per beam of a scan, the range up to which it shows free space: a valid
// return its own; an invalid beam (a dropout or no echo) in a run of at most
// max_run between two valid ones the nearer of those two (a dropout is not
// free space, but its neighbours bound it); any other invalid beam -1
// (unknown). `ring`: the beams go all round (the last neighbours the first).
void known_beam_ranges(std::span<const float> ranges, std::span<const uint8_t> valid, int max_run, bool ring,
                       std::span<float> out);

// Adds one scan's knowledge. ends_R: each beam's end at its known range
// (frame R), known: whether it has one. The wedge between two neighbouring
// known beams is free up to the nearer end (the space between their rays);
// a cone (cone_half_angle > 0, sonar) is free up to its end's range.
void add_known_free(std::span<const Eigen::Vector2d> ends_R, std::span<const uint8_t> known, double cone_half_angle,
                    bool ring, KnownFree& out);

}  // namespace hemm::robot
