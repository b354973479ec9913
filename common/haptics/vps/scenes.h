// The two VR scenes of the bimanual paper (section 4.2), generated, with
// scripted hand paths that perform each task (pure: meshes and poses, no I/O).
//
//  * Peg-in-hole: a pins object (right hand: an 80 x 40 x 10 mm plate with
//    two 10 x 10 x 25 mm pins) inserted into a holes object (left hand: an
//    80 x 40 x 30 mm block with two 12 x 12 mm through holes, 1 mm clearance
//    per side), over a static table.
//  * Assembly: a static part of over a million triangles (a floor slab with a
//    pocket for the tank, and spherical bosses of 81,920 triangles each) and
//    two tools standing for the paper's coolant tank (a 100 x 60 x 40 mm box,
//    25,392 triangles) and electric drill (a 40 mm ball of 20,480 triangles on
//    a 20 x 20 x 120 mm handle of 14,700 triangles: 35,180). The boss at the
//    origin is where the engine report's exact references are taken.
//
// Frames: scene W (z up); each object's mesh frame is its own (the paths give
// the pose of each mesh frame in W, which is also where the hand holds it).
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "common/mesh/triangle_mesh.h"

namespace hemm::vps {

struct BimanualScene {
  std::string name;
  mesh::TriangleMesh scene;  // static, in W
  mesh::TriangleMesh right;  // right-hand object, its mesh frame
  mesh::TriangleMesh left;   // left-hand object, its mesh frame
};

// Poses of the two hand-held objects' mesh frames in W.
struct BimanualPoses {
  Eigen::Isometry3d right = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d left = Eigen::Isometry3d::Identity();
};

// ---- peg-in-hole
inline constexpr double kPegClearance = 0.001;  // per side (m)
BimanualScene make_peg_in_hole_scene();
// Scripted hands: the left holds the holes object still just above the
// table; the right brings the pins down at 30 mm/s, the pin tips from 10 mm
// above the holes, 0.4 mm off-axis and tilted 0.4 degrees, drifting sideways
// by 1.2 mm (more than the clearance: the hole walls guide the pins), until
// the plate presses 2 mm into the block, then holds. The poses are where the
// hands are: the objects follow them through the coupling and stop at
// contacts.
BimanualPoses peg_in_hole_hands(double t);
inline constexpr double kPegInHoleDuration = 1.8;  // s

// ---- assembly
struct AssemblyLayout {
  double boss_radius = 0.08;                  // the bosses (icospheres, 81,920 triangles)
  double boss_spacing = 0.25;                 // grid spacing; boss 0 is at the origin
  double slab_top = -0.12;                    // floor slab top (z); the pocket is cut into it
  Eigen::Vector3d pocket_centre{-0.45, 0.0, -0.12};  // top centre of the pocket
  Eigen::Vector3d pocket_half{0.052, 0.032, 0.015};  // 2 mm clearance around the tank, 30 mm deep
  Eigen::Vector3d tank_half{0.05, 0.03, 0.02};       // the right tool (box)
  double drill_ball_radius = 0.04;                    // the left tool's ball, centred at its mesh origin
  Eigen::Vector3d handle_half{0.01, 0.01, 0.06};      // its handle, 1 mm above the ball along +z
};
// `bosses` >= 1; 13 give 1,065,000+ triangles, 41 the paper's scale (3.36 M).
BimanualScene make_assembly_scene(int bosses, const AssemblyLayout& layout = {});
// Scripted hands: the right lowers the tank into the pocket (starting 1 mm
// and 1 degree off), presses it 2 mm onto the pocket floor and holds; the
// left brings the drill's ball onto the flank of boss 0, slides it along the
// boss and leaves.
BimanualPoses assembly_hands(double t, const AssemblyLayout& layout = {});
inline constexpr double kAssemblyDuration = 6.0;  // s

}  // namespace hemm::vps
