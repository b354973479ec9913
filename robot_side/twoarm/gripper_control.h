// Parallel-jaw gripper control of the two-arm robot (issue 25): position
// and force at once. Each finger runs a PD to half the commanded opening,
// its force saturated at the commanded grip force: in free space the fingers
// go to the opening; on an object narrower than it, the fingers squeeze it
// with the grip force (the PD saturates), whatever the object's width. The
// scene couples the fingers (a parallel gripper's rack): the two pads share
// the squeeze, their mean is the grip force.
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

void gripper_control(const GripperSpec& spec, const GripperGains& g, const GripperTarget& target,
                     const GripperSense& sense, GripperState& out) noexcept;

}  // namespace hemm::twoarm
