// Safety pieces of the robot station: the command watchdog, the collision
// guard that limits the base's speeds from the robot's own range data, and
// the keep-out check of arm targets. Pure functions over explicit state;
// time stamps are int64 ns.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mapping/depth_image.h"

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

// ---------------------------------------------------------------- collision guard
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

// ---------------------------------------------------------------- arm targets
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

// The robot's own sparse set of seen voxels, from its depth frames: each
// valid pixel's point (placed with the frame's odometry pose T_P_S) marks
// its voxel seen at the frame's time, the voxel keeping the newest frame's
// point (not its centre: no quantisation added). Bounded: only recent
// frames count (a voxel not seen for keep_ns is forgotten: odometry drifts
// and things move), at most max_voxels (the oldest go first), and only what
// the arm could touch: points within max_range of the sensor and above the
// floor band (the floor keep-out covers the floor itself). Voxels are not
// cleared by free space seen through them (a thing that moved away stays
// forbidden until keep_ns passes: conservative). Not thread-safe; the robot
// keeps it on its depth worker thread and publishes points() snapshots.
struct SeenVoxelParams {
  double voxel_size = 0.02;               // m: the depth samples' spacing at arm's reach (1.3-2.8 cm)
  std::int64_t keep_ns = 10'000'000'000;  // 10 s
  std::size_t max_voxels = 20'000;        // ~0.5 MB with the hash index
  double min_z = 0.03;                    // m in P: points below are floor
  double max_range = 2.5;                 // m from the sensor
};
std::optional<std::string> validate(const SeenVoxelParams& p);

class SeenVoxels {
 public:
  explicit SeenVoxels(const SeenVoxelParams& p = {});
  // Adds one frame (its stamp_ns and depth, placed with T_P_S); forgets
  // voxels older than stamp_ns - keep_ns. Returns the valid pixels used.
  std::size_t add_frame(const mapping::DepthImage& img, const Eigen::Isometry3d& T_P_S);
  std::size_t size() const { return voxels_.size(); }
  std::size_t memory_bytes() const;
  // The seen points (one per voxel), in P.
  void points(std::vector<Eigen::Vector3f>* out) const;
  const SeenVoxelParams& params() const { return p_; }

 private:
  struct Voxel {
    Eigen::Vector3f point;
    std::int64_t stamp_ns;
  };
  SeenVoxelParams p_;
  std::unordered_map<std::uint64_t, Voxel> voxels_;
  std::uint64_t key_of(const Eigen::Vector3d& p) const;
  void forget_before(std::int64_t t_ns);
};

}  // namespace hemm::robot
