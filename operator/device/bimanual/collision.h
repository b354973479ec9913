// Collision avoidance of the bimanual interface (paper Sec. 3.3) from the
// arms' partial forward kinematics: each link (and each handle) is a capsule
// between consecutive joint origins; wherever a capsule comes within
// `activation_m` of the other arm's capsules or of the table/column, a
// spring-like force (plus damping of the approach speed) pushes its closest
// point away, and reaches the joints through the partial Jacobian of that
// point. Pure functions over the rig geometry; allocation-free.
#pragma once

#include <array>

#include <Eigen/Core>

#include "common/kinematics/arm7.h"
#include "common/math/geometry3.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/rig.h"

namespace hemm::device::bimanual {

// A capsule in D: the segment a-b swept by a sphere of `radius`, fixed to
// `link` (1..7; the handle is on link 7).
struct Capsule {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double radius = 0.0;
  int link = 1;
};
inline constexpr int kArmCapsules = 8;  // links 1..7 and the handle
using ArmCapsules = std::array<Capsule, kArmCapsules>;

// The capsules of one arm in D, from its joint frames (in A). Link i runs
// from joint i's origin to joint i+1's (link 7: the 2 cm behind the flange),
// as the plant's MuJoCo geoms do; the handle runs along z7 from the flange.
ArmCapsules arm_capsules(const RigGeometry& rig, ArmSide side, const HandleSpec& handle,
                         const kinematics::Arm7Frames& frames_A);

using math::ClosestPoints;
using math::segment_segment;
// Segment to axis-aligned box (0 if they intersect; p then lies inside the box).
ClosestPoints segment_box(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Box& box);

struct CollisionParams {
  double activation_m = 0.10;  // surface gap at which the repulsion starts
  double stiffness = 5000.0;   // [N/m] per pair, on the gap's shortfall
  double damping = 40.0;       // [N s/m] on the approach speed, inside the activation zone
  double max_force = 600.0;    // [N] per pair
  bool column = true;          // also keep links 3..7 and the handle off the column
};

// One active pair: the force on the first arm's capsule (the second arm's,
// for arm-arm pairs, gets the opposite force at its own closest point).
struct Repulsion {
  int arm = 0;         // ArmSide index of the capsule pushed
  int capsule = 0;     // 0..7
  int other_arm = -1;  // -1: the table or column
  int other_capsule = -1;
  Eigen::Vector3d point_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d other_point_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_D = Eigen::Vector3d::Zero();
  double gap_m = 0.0;  // surface distance
};
inline constexpr int kMaxRepulsions = kArmCapsules * kArmCapsules + 2 * 2 * kArmCapsules;

struct CollisionResult {
  std::array<Repulsion, kMaxRepulsions> pairs;
  int count = 0;
  double min_arm_arm_m = 0.0;    // smallest surface gap between the arms (all pairs)
  double min_arm_table_m = 0.0;  // smallest gap of either arm to the table or column
  std::array<kinematics::Arm7Vector, kArms> tau{};  // joint torques of all the repulsions
};

// Capsule point velocities come from the joint rates (for the damping).
void collision_avoidance(const RigGeometry& rig, const CollisionParams& params,
                         const std::array<ArmCapsules, kArms>& capsules,
                         const std::array<kinematics::Arm7Frames, kArms>& frames_A,
                         const std::array<kinematics::Arm7Vector, kArms>& qd, CollisionResult& out);

}  // namespace hemm::device::bimanual
