// What the operator's live view draws, as plain primitives and text (no
// OpenGL here; operator/view/live_view.cpp hands them to MuJoCo): what the
// operator station KNOWS, never the simulation's truth --
//  - the local map: each piece of the model snapshot's 2D map extruded to a
//    wall of wall_height, standing behind its surface (the face the normal
//    points out of is where the map has it), laser pieces orange, sonar
//    pieces (arcs, bridges) purple, shadow edges (unseen, held solid) grey;
//  - the robot at the pose the servo task rendered with (predicted, solid
//    blue box of the base's footprint) and at the last received pose
//    (odometry of the newest RobotState: a cyan outline);
//  - the proxy (green), the device point mapped into W (the proxy's goal,
//    yellow), the spring between them, and the rendered force as an arrow
//    (magenta) from the proxy;
//  - the live voxmap (when the station builds one from depth clouds): its
//    surface voxels as sand-coloured cubes, merged to a geom budget;
//  - text: mode and workspace scale, robot pose and state age, force and
//    contacts, map and model age, link (RTT, loss, link down), the servo
//    loop's period and misses; banners for LINK DOWN, E-STOP, NO ROBOT STATE.
// Markers are drawn at marker_z above the walls, so a view from above always
// shows them.
#pragma once

#include <cstdint>
#include <string>

#include "common/net/link_stats.h"
#include "common/view/primitives.h"
#include "operator/view/view_feed.h"

namespace hemm::op {

namespace view_colours {
inline constexpr view::Rgba kMapLaser{0.95f, 0.45f, 0.05f, 1.0f};
inline constexpr view::Rgba kMapSonar{0.60f, 0.25f, 0.85f, 1.0f};
// Shadow edges: unseen space the proxy treats as solid, not a seen surface.
inline constexpr view::Rgba kMapShadow{0.55f, 0.55f, 0.60f, 0.45f};
// Shape completion: a fitted circle's outline or a wall bridged through dropouts.
inline constexpr view::Rgba kMapFitted{0.15f, 0.70f, 0.65f, 0.85f};
// The live voxmap's surface (built from the robot's depth clouds).
inline constexpr view::Rgba kVoxmap{0.85f, 0.80f, 0.50f, 0.9f};
inline constexpr view::Rgba kVoxmapInferred{0.55f, 0.35f, 0.85f, 0.55f};  // surfaces nobody saw: violet, see-through
inline constexpr view::Rgba kRobot{0.10f, 0.30f, 0.95f, 1.0f};
inline constexpr view::Rgba kRobotReceived{0.20f, 0.90f, 0.95f, 1.0f};
inline constexpr view::Rgba kProxy{0.10f, 0.85f, 0.15f, 1.0f};
inline constexpr view::Rgba kDevicePoint{0.95f, 0.90f, 0.10f, 1.0f};
inline constexpr view::Rgba kForce{0.95f, 0.10f, 0.65f, 1.0f};
inline constexpr view::Rgba kAlarm{0.85f, 0.05f, 0.05f, 1.0f};
inline constexpr view::Rgba kWarning{0.85f, 0.45f, 0.05f, 1.0f};
}  // namespace view_colours

struct OperatorSceneStyle {
  double wall_height = 0.25;     // m, extrusion of the 2D map
  double wall_thickness = 0.04;  // m
  // The base's footprint (Pioneer 3-AT-sized: chassis with wheels) and height.
  Eigen::Vector3d robot_half{0.25, 0.2475, 0.13};
  double marker_z = 0.35;        // m: the proxy (the smaller device point 2 cm lower: under it when they meet)
  double proxy_radius = 0.06;    // m, drawn (the probe itself is smaller)
  double device_radius = 0.045;  // m
  double force_scale = 0.4;      // m of arrow per N
  std::size_t voxmap_cubes = 1500;  // geoms for the live voxmap's surface
};

// The scene's primitives in W. tick may be null (no servo tick yet).
void build_operator_scene(const ViewModel& model, const StationLogRecord* tick, const OperatorSceneStyle& style,
                          view::PrimitiveList& out);

// "exploration", "navigation", "manipulation", "idle", or "?" (wire::Mode number).
const char* mode_name(std::uint32_t wire_mode);

struct OverlayInputs {
  const ViewModel* model = nullptr;
  const StationLogRecord* tick = nullptr;  // null: none yet
  const net::LinkStatistics* link = nullptr;
  const ServoHealth* servo = nullptr;
  std::int64_t now_ns = 0;
  bool estop_requested = false;  // the e-stop key was pressed
};
view::Overlay make_operator_overlay(const OverlayInputs& in);

// printf into a string (an overlay line; at most 255 characters).
std::string overlay_text(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace hemm::op
