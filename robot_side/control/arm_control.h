// Joint-space arm control at 1 kHz: the joint reference moves toward the goal
// (the IK solution of the commanded end-effector target) at no more than the
// joint speed limit; a PD law plus gravity/bias compensation tracks it, and the
// torque is clamped to the limit. Pure functions.
#pragma once

#include "common/kinematics/arm5.h"

namespace hemm::robot {

using kinematics::Arm5Vector;

struct ArmControlParams {
  double kp = 200.0;               // N m / rad
  double kd = 20.0;                // N m s / rad
  double max_joint_speed = 1.5;    // rad/s
  double max_joint_torque = 10.0;  // N m
};

struct ArmControlState {
  Arm5Vector q_goal = Arm5Vector::Zero();  // where the reference is heading (within limits)
  Arm5Vector q_ref = Arm5Vector::Zero();   // the rate-limited reference
  Arm5Vector qd_ref = Arm5Vector::Zero();
};

// Sets the goal, clamped to the model's limits. Returns true if it was clamped.
bool set_arm_goal(const kinematics::Arm5Model& model, ArmControlState& state, const Arm5Vector& q_goal);

// Hold: the goal and reference freeze at the current reference.
void hold_arm(ArmControlState& state);

// Starts (or restarts) the reference at the measured position.
void reset_arm(ArmControlState& state, const Arm5Vector& q);

// The path the reference takes from q_from to q_to: where it is after
// `travel` rad (max_joint_speed x time), each joint moving at the speed
// limit and stopping when it arrives. arm_control_step follows it; the robot
// checks the poses along it before it accepts a goal.
Arm5Vector arm_reference_after(const Arm5Vector& q_from, const Arm5Vector& q_to, double travel);

// One control period: advances the reference and returns the joint torques.
// `bias` is the generalized bias force (gravity + Coriolis) to compensate.
// `saturated` (optional) reports whether any torque hit the limit.
Arm5Vector arm_control_step(const ArmControlParams& params, ArmControlState& state, const Arm5Vector& q,
                            const Arm5Vector& qd, const Arm5Vector& bias, double dt, bool* saturated = nullptr);

}  // namespace hemm::robot
