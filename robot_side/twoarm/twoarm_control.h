// One 1 kHz tick of the two-arm robot's control (issue 25): from both arms'
// readings and targets, the arm-arm / arm-bench repulsion (avoidance.h),
// each arm's Cartesian impedance (arm_impedance.h) and each gripper's
// position-and-force control (gripper_control.h), into joint torques and
// finger forces. Pure and allocation-free: the station's control thread calls
// it on what the hardware (here the SIMULATED plant, workbench_sim.h) reports.
#pragma once

#include <array>

#include "robot_side/twoarm/arm_impedance.h"
#include "robot_side/twoarm/avoidance.h"
#include "robot_side/twoarm/gripper_control.h"
#include "robot_side/twoarm/twoarm_model.h"

namespace hemm::twoarm {

// What an arm's hardware reports each tick.
struct ArmReading {
  kinematics::Arm7Vector q = kinematics::Arm7Vector::Zero();
  kinematics::Arm7Vector qd = kinematics::Arm7Vector::Zero();
  // The wrist sensor: the wrench the flange exerts on the gripper (force,
  // torque about the flange), in J7 axes. At rest in free space it carries
  // the gripper's weight.
  kinematics::Wrench6 ft_J7 = kinematics::Wrench6::Zero();
  GripperSense gripper;
};

// What it is told.
struct ArmCommand {
  kinematics::Arm7Vector tau = kinematics::Arm7Vector::Zero();  // joint torques [N m]
  std::array<double, 2> finger_force_N{};                        // along each finger's opening direction
};

struct TwoArmTargets {
  std::array<Eigen::Isometry3d, kArms> T_A_G{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  std::array<GripperTarget, kArms> gripper{};
};

struct TwoArmParams {
  std::array<ImpedanceParams, kArms> arm{};
  AvoidanceParams avoidance{};
  bool avoid = true;
  GripperGains gripper{};
  // Both grippers holding (taken as one object in both hands, as in the
  // bench's tasks): each arm's position error e_a = p_d,a - p_a is split
  // into the common part e_c = (e_0 + e_1) / 2 and what differs, and the
  // arm works to e_c + relative_stiffness_ratio (e_a - e_c). The object
  // still follows the hands' mean at the full stiffness, but a mismatch
  // between the two hands (one moving first, a hand's tremor through the
  // mapping) squeezes or shears it at that share of it. 1: independent arms.
  double relative_stiffness_ratio = 1.0;
};

struct TwoArmOutput {
  std::array<ArmCommand, kArms> command{};
  std::array<ImpedanceOutput, kArms> arm{};
  std::array<GripperState, kArms> gripper{};
  AvoidanceResult avoidance{};
  // The external wrench at G in A from the wrist sensor, the gripper's own
  // weight taken out (dynamics of the gripper neglected).
  std::array<kinematics::Wrench6, kArms> wrench_ext_A{};
  bool coupled = false;  // this tick's position errors were coupled (relative_stiffness_ratio)
};

void twoarm_control(const TwoArmModel& model, const TwoArmParams& p, const std::array<ArmReading, kArms>& in,
                    const TwoArmTargets& targets, TwoArmOutput& out) noexcept;

// The targets that hold both arms where they are (G's current pose) and the
// grippers at their current opening with grip force `hold_force_N` (what a
// grasp keeps when the link is lost).
TwoArmTargets hold_targets(const TwoArmModel& model, const std::array<ArmReading, kArms>& in,
                           const std::array<double, kArms>& hold_force_N);

}  // namespace hemm::twoarm
