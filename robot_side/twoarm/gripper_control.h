// Parallel-jaw gripper control of the two-arm robot (issue 25): position
// and force at once. Each finger runs a PD to half the commanded opening,
// its force saturated at the commanded grip force: in free space the fingers
// go to the opening; on an object narrower than it, the fingers squeeze it
// with the grip force (the PD saturates), whatever the object's width. The
// scene couples the fingers (a parallel gripper's rack): the two pads share
// the squeeze, their mean is the grip force.
// Until both pads touch, the fingers move at most max_speed_mps (a real
// parallel gripper's approach speed): the position error is capped at the
// one whose P force the damping balances at that speed. Once both touch,
// the whole error drives them (up to the grip force). Without the cap
// the pads hit a box at about 0.5 m/s (30 N against the 60 Ns/m damping),
// and a gripper not centred on it took the first pad's impact alone: 52-60 N
// on the wrist, beyond its 40 N limit. With it (0.08 m/s) the box's impact
// stays under the limit, but the first pad pushes a light bar on the bench
// round by 0.6 rad before the second arrives: so it is off unless asked for
// (RobotConfig twoarm.gripper_approach_speed_mps).
// Pure, allocation-free.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "robot_side/twoarm/twoarm_model.h"

namespace hemm::twoarm {

struct GripperGains {
  double kp_N_per_m = 4000.0;
  double kd_Ns_per_m = 60.0;
  double grasp_fraction = 0.5;  // pads pressed with >= this fraction of the grip force: holding
  // Per finger, until both pads touch (the opening changes at twice this);
  // <= 0: no cap (the default: a light bar yaws under the first pad, below).
  double max_speed_mps = 0.0;
  double contact_N = 0.5;       // a pad touches above this
};

struct GripperTarget {
  double opening_m = 0.0;  // distance between the pads, [0, 2 * stroke]
  double force_N = 0.0;    // the most each finger may press, [0, max_force]
};

// Empty when the target is usable for `spec` (finite, within those ranges).
std::optional<std::string> check_target(const GripperSpec& spec, const GripperTarget& t);

struct GripperSense {
  std::array<double, 2> finger_m{};
  std::array<double, 2> finger_mps{};
  std::array<double, 2> pad_force_N{};
};

struct GripperState {
  std::array<double, 2> finger_force_N{};  // the motors' command (+: opening)
  double opening_m = 0.0;
  double grip_force_N = 0.0;  // sensed: the mean of the pad forces (the squeeze)
  bool holding = false;       // both pads press with >= grasp_fraction of the grip force
};

// Both pads press with at least grasp_fraction of the target's grip force
// (GripperState::holding, from the sensing alone).
bool gripper_holding(const GripperSpec& spec, const GripperGains& g, const GripperTarget& target,
                     const GripperSense& sense) noexcept;

void gripper_control(const GripperSpec& spec, const GripperGains& g, const GripperTarget& target,
                     const GripperSense& sense, GripperState& out) noexcept;

}  // namespace hemm::twoarm
