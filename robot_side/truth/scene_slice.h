#pragma once
// SIMULATION ONLY. The ground truth for the operator's haptic rendering: the
// simulated scene's STATIC geometry cut by a horizontal plane at height z,
// as the exact 2D geometry of common/haptics/proxy/reference_scene.h.
//
// The range sensors scan a horizontal plane, so the operator's local model is
// (at best) this slice at the sensor's height; the proxy extrudes it
// vertically, and so does ExactScene.
//
// What is static: every geom whose body is welded to the world body
// (body_weldid == 0, no joint between it and the world) and is not a mocap
// body. The robot hangs from a free joint, so none of it is included.
// Shapes: a box with one local axis vertical (any yaw) gives its footprint
// rectangle; a vertical cylinder a disc; a vertical capsule a disc (smaller in
// its end caps); a sphere the disc of radius sqrt(r^2 - dz^2). Anything else
// that reaches the slice height (tilted shapes, ellipsoids, meshes, height
// fields, non-horizontal planes) is reported in `skipped`, never dropped
// silently. Horizontal planes (floors) are ignored.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "common/haptics/proxy/reference_scene.h"
#include "common/mesh/triangle_mesh.h"

// MuJoCo's types, forward-declared so its header stays out of ours.
struct mjModel_;
struct mjData_;

namespace hemm::robot {

struct SliceEntry {
  std::string name;    // geom name, or "geom#<id>" when unnamed
  std::string kind;    // box, cylinder, capsule, sphere, ellipsoid, mesh, ...
  std::string detail;  // what was added, or why it was skipped
};

struct SceneSlice {
  double height = 0.0;                 // z of the slice, m in W
  haptics::ExactScene scene;           // frame W
  std::vector<SliceEntry> included;    // in the scene
  std::vector<SliceEntry> skipped;     // reach the slice but cannot be represented
  std::vector<SliceEntry> off_slice;   // static, but entirely above/below z (or a floor)
  std::size_t moving_geoms = 0;        // on bodies with joints or mocap (the robot): excluded
};

// Slices a model whose world poses are current (mj_forward has run on d).
SceneSlice slice_scene(const mjModel_* m, const mjData_* d, double z);

// Loads an MJCF file (includes resolve relative to it), runs mj_forward at
// qpos0 and slices it. On error returns false, sets *error (names the file)
// and leaves *out untouched.
bool load_scene_slice(const std::string& path, double z, SceneSlice* out, std::string* error);

// The ground truth for the 3D probe on the live voxmap: the static geometry
// inside a region of W as triangle meshes (frame W), one closed mesh per
// geom, to be voxelised exactly (vps::build_voxmap) and probed along the
// same path as the live model. Static as above. Boxes (any orientation) are
// meshed exactly, cylinders and spheres within 0.03 % of their radius; other
// shapes that reach the region are reported in
// `skipped`, never dropped silently; planes (the floor) and geoms outside the
// region go to `off_region`.
struct SceneMeshPart {
  std::string name;
  mesh::TriangleMesh mesh;  // closed, frame W
};

struct SceneMeshes {
  std::vector<SceneMeshPart> parts;
  std::vector<SliceEntry> skipped;     // reach the region but cannot be meshed
  std::vector<SliceEntry> off_region;  // static but outside it, or planes
};

// Loads an MJCF file, runs mj_forward at qpos0 and meshes its static geoms
// whose bounding box meets region_W. False with *error (names the file) on
// failure; *out untouched then.
bool load_scene_meshes(const std::string& path, const Eigen::AlignedBox3d& region_W, SceneMeshes* out,
                       std::string* error);

}  // namespace hemm::robot
