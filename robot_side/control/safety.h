// Safety pieces of the robot station: the command watchdog and the collision
// guard that limits the base speed from the robot's own range data. Pure
// functions over explicit state; time stamps are int64 ns.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

namespace hemm::robot {

// No valid command for `timeout_ns` => expired. Before the first command it is
// expired too (nothing to follow). The watchdog judges a command's age, not
// its arrival: feed it the time the command was *sent*, on the watchdog's
// clock, as a command that took the least delay on the path would have
// arrived (the station passes arrival - the time the path held it, see
// net::judge_message_age). A command held on the path for longer than the
// timeout is expired on arrival; one held for t is followed for timeout - t.
// A time in the future (after `now`) would extend the timeout: the feed
// clamps it to now.
struct Watchdog {
  int64_t timeout_ns = 250'000'000;
  int64_t last_valid_ns = 0;
  bool has_command = false;
};
inline void watchdog_feed(Watchdog& w, int64_t sent_ns, int64_t now_ns) {
  w.last_valid_ns = sent_ns < now_ns ? sent_ns : now_ns;
  w.has_command = true;
}
// A command that took the least delay (sent_ns == now_ns).
inline void watchdog_feed(Watchdog& w, int64_t now_ns) { watchdog_feed(w, now_ns, now_ns); }
inline bool watchdog_expired(const Watchdog& w, int64_t now_ns) {
  return !w.has_command || now_ns - w.last_valid_ns > w.timeout_ns;
}

// The base's footprint in frame R and the guard's parameters.
struct CollisionGuardParams {
  double front_x = 0.245;      // m, foremost point of the robot (incl. the arm, updated live)
  double rear_x = -0.245;      // m, rearmost point
  double half_width = 0.25;    // m, half the corridor the base sweeps
  double margin = 0.15;        // m, distance kept to any obstacle (collision_margin_m)
  double max_decel = 1.0;      // m/s^2 the base can brake with
  double reaction_time = 0.05;  // s, actuation lag before braking starts
};

struct GuardLimit {
  double max_forward = 0.0;   // m/s, >= 0
  double max_backward = 0.0;  // m/s, >= 0 (magnitude)
  double free_ahead = 0.0;    // m, free length in front of the footprint (inf: none seen)
  double free_behind = 0.0;
};

// Largest speeds whose stopping distance v*t_r + v^2/(2a) plus the margin fits
// in the free length of the swept corridor, from obstacle points in frame R
// (x forward, y left). Points inside the footprint's x-extent are ignored (they
// are beside the robot, not in its path).
GuardLimit collision_guard(const CollisionGuardParams& params, std::span<const Eigen::Vector2d> points_R);

// The speed whose stopping distance (reaction + braking) equals `distance`.
double stoppable_speed(double distance, double decel, double reaction_time);

}  // namespace hemm::robot
