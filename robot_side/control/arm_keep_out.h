// The robot station's keep-out check of arm targets: the arm pose's chain
// against the floor, the base and what the robot's sensors have seen.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mapping/depth_image.h"

namespace hemm::robot {

// The robot refuses an arm target whose arm pose (the IK solution) would
// reach into the floor, into the base, or into what its own sensors have
// seen. The arm is the chain shoulder -> joints -> tool tip (frame R), each
// link a capsule of link_radius (+ clearance). Seen geometry is of two kinds:
//  * 2D returns (laser, sonar): vertical columns, as a 2D scan gives no
//    height. Without a depth camera a column is infinite, so the arm is never
//    sent through, over or under anything the robot has seen in 2D.
//  * 3D points from the robot's own depth camera (SeenVoxels below). With
//    them, a column whose space above the laser plane the camera sees (the
//    vertical segment from column_top_z up to the arm's highest reach lies
//    in the camera's view, column_seen_from_above) is CAPPED at column_top_z
//    (the laser plane + column_cap_margin): above it the camera, not the 2D
//    scan, says what is there, so the arm may reach over a table or a seat
//    the laser sees only the legs or the front of, but not into what the
//    camera saw on it. A column the camera does not see above stays
//    infinite. (The camera sees what is not occluded: a thing hidden behind
//    another at the moment of the frames is not in the seen set.)
struct ArmKeepOut {
  double floor_z = 0.0;          // m, the floor in R (R's origin is on the ground)
  // The base's solid parts in R: the body (chassis and wheels) and the laser head.
  Eigen::AlignedBox3d body{Eigen::Vector3d(-0.245, -0.25, 0.0), Eigen::Vector3d(0.245, 0.25, 0.26)};
  Eigen::AlignedBox3d laser_head{Eigen::Vector3d(0.14, -0.04, 0.26), Eigen::Vector3d(0.22, 0.04, 0.32)};
  double link_radius = 0.02;     // m, robot.xml's arm capsules (and the tool's payload sphere)
  double clearance = 0.01;       // m kept beyond the radius
  // Added for seen 3D points: neighbouring depth samples on a surface lie up
  // to ~1.5 voxels (2-3 cm) apart, so a capsule between two of them is
  // nearer to the surface than to either sample by up to ~1 cm.
  double seen_pad = 0.01;
  // How far above the laser plane a capped column is taken to extend (the
  // top of what the 2D return may belong to that the camera could miss).
  double column_cap_margin = 0.10;
};
enum class ArmRefusal { kNone = 0, kFloor, kBase, kScene };
const char* to_string(ArmRefusal r);
// Short name for logs and the wire: "floor", "base", "scene" ("none").
const char* short_name(ArmRefusal r);

// What the robot has seen, for check_arm_chain.
struct SeenScene {
  std::span<const Eigen::Vector2d> columns_R;  // 2D returns (frame R)
  // Per column: 1 = capped at column_top_z; empty: no column is capped.
  std::span<const std::uint8_t> column_capped;
  double column_top_z = 0.0;
  // 3D points seen by the depth camera, in frame P (the odometry frame the
  // depth frames are placed in), and the base pose there now.
  std::span<const Eigen::Vector3f> points_P;
  Eigen::Isometry3d T_P_R = Eigen::Isometry3d::Identity();
};

// The first keep-out the chain violates (kNone: the pose is allowed). A
// seen 3D point refuses when it lies within link_radius + clearance +
// seen_pad of a link's axis; a column within link_radius + clearance.
ArmRefusal check_arm_chain(const ArmKeepOut& keep_out, std::span<const Eigen::Vector3d> chain_R,
                           const SeenScene& seen);

// Whether point p_R is inside a depth camera's view: in front of it, inside
// the image and between its range limits along the ray (T_S_R: the camera
// pose inverted, R -> S).
bool in_camera_view(const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_S_R, const Eigen::Vector3d& p_R);
// Whether the camera sees the whole vertical segment from (q_R, z0) to
// (q_R, z1) (the view is convex: both ends suffice).
bool column_seen_from_above(const mapping::DepthIntrinsics& K, const Eigen::Isometry3d& T_S_R,
                            const Eigen::Vector2d& q_R, double z0, double z1);

}  // namespace hemm::robot
