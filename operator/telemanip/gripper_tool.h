// The remote parallel-jaw gripper as a VPS tool (issue 25, part 3): the
// palm and the two fingers at an opening, as a pointshell in the grasp frame
// G, for model-mediated rendering of what each remote gripper touches in the
// operator's live voxmap. Sizes and masses are deploy/scenes/workbench.xml's
// (r_palm, r_finger_a/b: a 70 x 250 x 40 mm palm box, 36 x 12 x 100 mm
// finger boxes whose pads face each other across the opening, G between the
// pads 12 cm along the flange's z).
//
// The pointshell changes with the opening; building one allocates, so a set
// of shells at fixed openings is built at start and the servo tick takes the
// one nearest the gripper's opening (GripperToolSet::nearest).
#pragma once

#include <string>
#include <vector>

#include "common/haptics/vps/probe_tool.h"
#include "common/mesh/triangle_mesh.h"

namespace hemm::op::telemanip {

struct GripperGeometry {
  Eigen::Vector3d palm_half{0.035, 0.125, 0.020};    // box half extents [m]
  double palm_centre_z = -0.095;                     // in G (J7 z 0.025, G at J7 z 0.12)
  double palm_mass = 0.6;
  Eigen::Vector3d finger_half{0.018, 0.006, 0.050};
  double finger_centre_z = -0.025;                   // in G (J7 z 0.045 + 0.05)
  double finger_mass = 0.1;
  double max_opening_m = 0.22;                       // 2 x the finger stroke 0.11
  double spacing = 0.0025;  // pointshell spacing: a quarter of the live voxmap's 1 cm voxel
  int levels = 3;
  double opening_step_m = 0.02;  // shells every this much, from 0 to max_opening_m
};
// Empty when usable.
std::string validate(const GripperGeometry& g);

// The palm and fingers at `opening_m` as one mesh (three closed boxes), in G;
// without the fingers, the palm alone.
mesh::TriangleMesh gripper_mesh(const GripperGeometry& g, double opening_m, bool fingers = true);

// Pointshell, mass and inertia about the centre of mass (G's axes) at one
// opening; fingers false: the palm's pointshell alone, the mass and inertia
// still the whole gripper's. Allocates. Fails with a message on a bad geometry.
std::string make_gripper_tool(const GripperGeometry& g, double opening_m, vps::ProbeTool* out, bool fingers = true);

struct GripperToolSet {
  std::vector<double> opening_m;        // ascending
  std::vector<vps::ProbeTool> tools;    // one per opening
  // The palm's shell alone (at half the stroke), for a gripper that holds
  // something: its fingers are on the held object, whose own voxels the live
  // voxmap keeps (the head camera sees it) and would push them.
  vps::ProbeTool palm;
  // Index of the shell nearest `opening` (clamped; a non-finite one: the widest). No allocation.
  int nearest(double opening) const noexcept;
};
// Shells at 0, step, 2 step, ... max_opening_m (the last at max), and the
// palm's. Allocates.
std::string make_gripper_tool_set(const GripperGeometry& g, GripperToolSet* out);

}  // namespace hemm::op::telemanip
