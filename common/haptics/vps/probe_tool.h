// The robot's probe tool as a 6-DoF VPS tool against a static voxmap (issue
// 13, 6-DoF exploration through the live voxmap): a pointshell of the tool,
// pulled by the 6-DoF virtual coupling (coupling.h) towards where the hand
// wants it, with the VPS contact wrench (contact.h) of one pair (tool against
// the voxmap, both in W) acting on it; the coupling's reaction is the wrench
// to display. Pure: the operator's servo task runs it per tick against the
// newest snapshot's voxmap, and the SIMULATION-ONLY truth replays the same
// hand path against an exact voxmap of the scene (replay_tool_path): one
// piece of code for both, so the two forces differ only by the voxmap.
//
// Tool frame P: origin at the centre of the rounded tip, +z along the rod
// (the tip is the tool's lowest point when P's z is W's z). Geometry from
// deploy/scenes/robot.xml's last arm link: the link capsule (radius 15 mm,
// 0.10 m long) ending in the 150 g payload sphere (radius 20 mm) at the tool
// tip; rod and tip together 0.21 kg.
//
// Real time: probe_tool_tick allocates nothing and takes no lock; its work is
// bounded by ToolParams::budget (the time-critical mode, coarse to fine
// levels); the pair's state (which caches where each point was last outside a
// sheet of the voxmap) is reset when the voxmap changes (a new snapshot: the
// pointer differs); with no voxmap the tool follows the hand and the wrench
// is zero.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/coupling.h"

namespace hemm::vps {

struct ProbeToolGeometry {
  double tip_radius = 0.020;  // payload sphere at the tool tip (robot.xml "payload")
  double rod_radius = 0.015;  // arm_link5 capsule
  double rod_length = 0.12;   // tip centre to the rod's end (link5 from 0.02 to 0.14 m, tip at 0.14)
  double tip_mass = 0.15, rod_mass = 0.06;  // kg
  double spacing = 0.0025;    // pointshell spacing (m): a quarter of the live voxmap's 1 cm voxels
  int levels = 3;             // time-critical levels
};

// Empty when usable.
std::string validate(const ProbeToolGeometry& g);

struct ProbeTool {
  PointShell shell;                // frame P, reference point = centre of mass
  double mass = 0.0;
  Eigen::Matrix3d inertia_com = Eigen::Matrix3d::Identity();  // about the centre of mass, P axes
};

// The tool's surface sampled analytically (equal-area points on the tip
// sphere below the rod, rings on the rod, a disc on its end), inward normals,
// area weights; mass properties of a solid sphere and a solid cylinder.
std::optional<VpsError> make_probe_tool(const ProbeToolGeometry& g, ProbeTool* out);

struct ToolParams {
  ContactParams contact;
  CouplingParams coupling;  // design_coupling(tool.mass, tool.inertia_com, device limits)
  std::int64_t budget = kUnlimitedWork;  // work per tick (sphere nodes + points): time-critical mode
};

struct ToolState {
  PairState pair;                  // sized by init_tool_state
  RigidBodyState body;             // the tool's centre of mass
  const Voxmap* voxmap = nullptr;  // the voxmap the pair state belongs to (null: none this tick)
  bool started = false;
  Eigen::Isometry3d goal_prev = Eigen::Isometry3d::Identity();  // the hand's previous target (twist)
  PairResult contact;              // last tick's
  Wrench device;                   // last tick's wrench to display, W, about the goal's centre of mass
  std::uint64_t voxmap_changes = 0, ticks = 0;
};

// Allocates (call off the servo thread).
void init_tool_state(const ProbeTool& tool, ToolState* s);

// One tick: the hand wants the tool's frame P at T_W_goal (W). The hand's
// twist is the goal's change since the previous tick over dt (both the live
// task and the replay see only the goal path). vm may be null (no model yet:
// the tool is put at the goal, zero wrench). A non-finite goal keeps the tool
// and outputs zero.
void probe_tool_tick(const ToolParams& p, const ProbeTool& tool, const Voxmap* vm, const Eigen::Isometry3d& T_W_goal,
                     ToolState* s) noexcept;

// The tool's frame P in W.
Eigen::Isometry3d tool_pose_W(const ProbeTool& tool, const ToolState& s);

// The same hand path replayed against a voxmap (SIMULATION-ONLY truth, and
// the tests): goals[i] per tick, gain[i] the live run's stale-model fade (may
// be empty: 1), has_model[i] whether the live tick had a voxmap (may be
// empty: all had; without one the tool follows the hand, as live). Writes the displayed wrench (force, torque) and the tool's
// P-frame origin per tick.
struct ToolReplay {
  std::vector<Wrench> wrench;
  std::vector<Eigen::Vector3d> tool_W;
  std::vector<int> contacts;
};
void replay_tool_path(const ToolParams& p, const ProbeTool& tool, const Voxmap& vm,
                      const std::vector<Eigen::Isometry3d>& goals, const std::vector<double>& gain,
                      const std::vector<std::uint8_t>& has_model, ToolReplay* out);

}  // namespace hemm::vps
