// Arm-arm and arm-bench avoidance of the two-arm robot (issue 25), as a
// repulsive term: each arm is a chain of capsules (links 3..7 between joint
// origins as the scene's geoms, and the gripper's palm); wherever a capsule
// comes within activation_m of the other arm's capsules, or a link capsule
// within activation_m of the bench top, a spring on the shortfall plus
// damping of the approach speed pushes its closest point away, reaching the
// joints through that point's partial Jacobian. The two grippers do not repel
// each other (a hand-over brings them together) and the grippers do not
// repel the bench (they work on it). Pure, allocation-free.
#pragma once

#include <array>

#include "common/kinematics/arm7.h"
#include "robot_side/twoarm/twoarm_model.h"

namespace hemm::twoarm {

struct AvoidanceParams {
  double activation_m = 0.06;  // surface gap at which the repulsion starts
  double stiffness_N_per_m = 2000.0;
  double damping_Ns_per_m = 40.0;  // on the approach speed, inside the zone
  double max_force_N = 300.0;      // per pair
};

struct ArmCapsule {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // in A
  double radius = 0.0;
  int link = 7;  // 3..7; the palm is on link 7
};
inline constexpr int kCapsulesPerArm = 6;  // links 3..7 and the palm
using ArmCapsules = std::array<ArmCapsule, kCapsulesPerArm>;
inline constexpr int kPalm = kCapsulesPerArm - 1;

ArmCapsules arm_capsules_A(const ArmMount& mount, const kinematics::Arm7Frames& frames_Ar);

struct AvoidanceResult {
  std::array<kinematics::Arm7Vector, kArms> tau{kinematics::Arm7Vector::Zero(), kinematics::Arm7Vector::Zero()};
  double min_arm_arm_m = 0.0;    // smallest surface gap between the arms' capsules
  double min_arm_bench_m = 0.0;  // smallest gap of a link capsule to the bench top
  int active_pairs = 0;
};

void avoidance(const TwoArmModel& model, const AvoidanceParams& p,
               const std::array<kinematics::Arm7Frames, kArms>& frames_Ar,
               const std::array<kinematics::Arm7Vector, kArms>& qd, AvoidanceResult& out) noexcept;

}  // namespace hemm::twoarm
