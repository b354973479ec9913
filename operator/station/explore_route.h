// The 6-DoF exploration routes of a table scene, read from the directives in
// the MJCF file's header comment (deploy/scenes/README.md, "Exploration
// routes"), so a scene carries its own scripted path for the SIMULATED hand
// of the 6-DoF probe tool (tool6_explorer.h), the robot start the path
// assumes, and the truth region hemm-truth --tool6 voxelises:
//
//   explore-start:  X Y THETA                      robot pose in W (m, rad)
//   explore-region: XMIN YMIN ZMIN XMAX YMAX ZMAX  the truth region in W (m)
//   explore6: ROUTE T X Y Z TILT_X FEATURE         one key pose of ROUTE
//   explore3: ROUTE T X Y Z FEATURE                one key point of a 3-DoF route
//
// A key: at T s of the script the tool tip's centre is at (X, Y, Z) in R,
// the tool turned by TILT_X rad about R's x; the hand moves linearly (slerp)
// between keys. FEATURE names what the key explores ("block-top"), or "-"
// for a transit. A feature spans from its first key to its last; its keys
// are consecutive (transits may sit between them), so the per-feature error
// table of deploy/explore3d.sh comes from the route. explore3 routes are the
// 3-DoF point probe's (the SIMULATED Omni, probe_3d.tool "point"): a key
// puts the probe's device point at (X, Y, Z) in W (the robot standing at
// explore-start), linear between keys; their own names (an explore3 and an
// explore6 route may share one), the same rules. Any other header line
// is prose, except one whose first word starts with "explore" and ends with
// ':' (a misspelt directive is an error, not prose).
//
// Parsing is pure (text in, struct out); errors name the file and line and
// leave the output untouched.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "common/math/frames.h"
#include "common/math/workspace_maps.h"
#include "operator/device/haptic_device.h"

namespace hemm::op {

struct RouteKey {
  double t_s = 0.0;
  Eigen::Vector3d tip_R = Eigen::Vector3d::Zero();
  double tilt_x_rad = 0.0;
  std::string feature;  // "-": a transit
  int line = 0;         // 1-based line of the file
};

struct ExploreRoute {
  std::string name;
  std::vector<RouteKey> keys;  // times strictly increasing, the first at 0
};

struct RouteFeature {
  std::string name;
  double t0_s = 0.0, t1_s = 0.0;  // its first and last key
};

// One key of an explore3 route: the probe's device point in W at T s.
struct Route3Key {
  double t_s = 0.0;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  std::string feature;  // "-": a transit
  int line = 0;
};

struct ExploreRoute3 {
  std::string name;
  std::vector<Route3Key> keys;  // times strictly increasing, the first at 0
};

struct SceneExploration {
  math::Pose2 start_W;           // the robot pose the routes' R assumes
  Eigen::AlignedBox3d region_W;  // hemm-truth --tool6 / --probe3 --region
  std::vector<ExploreRoute> routes;    // explore6
  std::vector<ExploreRoute3> routes3;  // explore3
  const ExploreRoute* find(const std::string& name) const;
  const ExploreRoute3* find3(const std::string& name) const;
  std::string route_names() const;   // "a, b"
  std::string route3_names() const;
};

// Limits of the format (validated).
inline constexpr double kRouteMaxTip_m = 5.0;      // |tip_R|
inline constexpr double kRouteMaxTilt_rad = 1.5708;  // |TILT_X|: at most a quarter turn
inline constexpr double kRouteMaxTime_s = 3600.0;
inline constexpr double kRouteMaxWorld_m = 100.0;  // |start|, region corners

// The directives of `text` (an MJCF file's contents; `source` names it in
// errors): nullopt and *out set, or "SOURCE:LINE: reason" and *out
// untouched. A scene with no header comment or no directives has no routes;
// a scene with routes must give explore-start and explore-region.
std::optional<std::string> parse_scene_exploration(std::string_view text, const std::string& source,
                                                   SceneExploration* out);

// The features of a route in order, each over [first key, last key].
std::vector<RouteFeature> route_features(const ExploreRoute& r);
std::vector<RouteFeature> route_features(const ExploreRoute3& r);

// Whether a device whose H origin sits at origin_R in R, with end-effector
// limits `l`, follows the route: every key's tip inside the workspace box (H)
// and no segment faster than l.max_linear_speed (if set). nullopt if so, else
// "SOURCE:LINE: explore6 ROUTE at t = T s: reason".
std::optional<std::string> check_route_reach(const ExploreRoute& r, const Eigen::Vector3d& origin_R,
                                             const device::EndEffectorLimits& l, const std::string& source);

// Whether the SIMULATED Omni reaches an explore3 route with the robot at
// start_W and the probe's map `m` (B -> R: probe_3d's range and origin;
// p_H = R_B_H^T p_B): every key's point inside the device's workspace box.
// nullopt if so, else "SOURCE:LINE: explore3 ROUTE at t = T s: reason".
std::optional<std::string> check_route3_reach(const ExploreRoute3& r, const math::Pose2& start_W,
                                              const math::ScaledMap& m, const device::EndEffectorLimits& l,
                                              const std::string& source);

// An explore3 key's device point in H (the inverse of the task's probe map
// with no mode anchor: W -> R by start_W, R -> B by m, B -> H).
Eigen::Vector3d route3_point_H(const Eigen::Vector3d& p_W, const math::Pose2& start_W, const math::ScaledMap& m);

// Reads the file and parses it (the edge: file I/O); errors as above, or
// "PATH: cannot read".
std::optional<std::string> load_scene_exploration(const std::string& path, SceneExploration* out);

}  // namespace hemm::op
