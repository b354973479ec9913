// SIMULATION ONLY. What the two-arm station's live view draws over the
// workbench scene MuJoCo renders from the frame's qpos (twoarm_view.h), as
// plain primitives and text (no OpenGL, no MuJoCo here), in W:
//  - each arm's target (what its impedance works to: the commanded pose or
//    the hold) as a sphere with its x/y/z axes, and a line from the true
//    grasp frame G to it (the spring's stretch); right arm green, left orange;
//  - each wrist's external wrench as a force arrow from G (5 mm per N; red
//    while the wrist force limit makes the arm yield);
//  - the simulation's contacts as points with force arrows (5 mm per N);
//  - text: robot time, safety, armed / following, per arm the wrist force
//    and the gripper (opening, squeeze, holding), the task judge's look
//    (lifted, on its goal, tilt, squeeze), the link; banners for the e-stop,
//    a lost link, a yielding wrist and a dropped object.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "common/view/primitives.h"
#include "robot_side/view/twoarm_view_feed.h"

namespace hemm::robot {

namespace twoarm_view_colours {
inline constexpr view::Rgba kArm[2] = {{0.10f, 0.80f, 0.20f, 1.0f}, {0.95f, 0.50f, 0.05f, 1.0f}};
inline constexpr view::Rgba kWrench{0.95f, 0.10f, 0.65f, 1.0f};
inline constexpr view::Rgba kYielding{0.95f, 0.05f, 0.05f, 1.0f};
inline constexpr view::Rgba kContact{0.20f, 0.20f, 0.95f, 1.0f};
}  // namespace twoarm_view_colours

struct TwoArmSceneStyle {
  double force_scale = 0.005;  // m of arrow per N
  double target_radius = 0.012;
  double axis_length = 0.06;
  double contact_radius = 0.008;
};

// The primitives of frame f; T_W_A: the torso frame A in W (the arms'
// targets and wrenches are in A).
void build_twoarm_scene(const TwoArmViewFrame& f, const Eigen::Isometry3d& T_W_A, const TwoArmSceneStyle& style,
                        view::PrimitiveList& out);

// The text beside the picture; t0_ns: the first frame's robot time.
view::Overlay twoarm_overlay(const TwoArmViewFrame& f, std::int64_t t0_ns);

// The safety flags (wire::SafetyFlags) as words: "ok", or e.g. "watchdog link-lost".
std::string safety_text(std::uint32_t flags);

}  // namespace hemm::robot
