// The operator's VPS local model (bimanual paper, Sec. 4): a static scene
// (voxmap) and one virtual object per end-effector (pointshell, and a voxmap
// for the object the other one can hit), loaded from mesh files through the
// .vps cache or built from meshes in memory. Built off the servo thread,
// immutable afterwards, published through VpsModelSnapshot.
//
// The cache: one .vps file per mesh and resolution, named after both, next to
// the mesh or in a given directory. It is used when it is newer than the mesh
// and holds the resolution asked for; otherwise the mesh is voxelized and the
// cache rewritten (a cache that cannot be written is reported, not fatal).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/haptics/vps/contact.h"
#include "common/mesh/triangle_mesh.h"
#include "operator/device/haptic_device.h"
#include "operator/servo/servo_loop.h"

namespace hemm::op {

// One mesh file and how to voxelize it.
struct VpsMeshSpec {
  std::string mesh_path;
  double scale = 1.0;          // file units -> metres
  double voxel_size = 0.002;   // voxmap [m]
  double shell_voxel = 0.0;    // pointshell [m]; 0: voxel_size
  int layers = 4;              // distance layers in and out
  double density = 1000.0;     // [kg/m^3] for the object's centre of mass, mass and inertia
  // A held object's virtual mass [kg] (its inertia scaled with it); 0: from
  // the density. The coupling's stiffness is capped by the mass (discrete
  // stability), so a small tool on a stiff device wants more than its own.
  double mass = 0.0;
};

struct VpsModelSpec {
  VpsMeshSpec scene;  // static: its voxmap only
  // Object of end-effector k (0 right, 1 left); an end-effector without one
  // renders nothing. Object 0 needs a voxmap only if object 1 exists (the
  // third pair is object 0's pointshell in object 1's voxmap).
  std::array<std::optional<VpsMeshSpec>, device::kMaxEndEffectors> objects;
  std::string cache_dir;  // "" : next to each mesh
  vps::ContactParams contact;
};

// A virtual object held by one end-effector, in its mesh frame M.
struct VpsObjectModel {
  vps::Voxmap voxmap;
  vps::PointShell shell;  // reference point = centre of mass
  mesh::MassProperties mass;
  std::size_t triangles = 0;
};

struct VpsLocalModel {
  VpsLocalModel() = default;
  VpsLocalModel(const VpsLocalModel&) = delete;  // bimanual points into this object
  VpsLocalModel& operator=(const VpsLocalModel&) = delete;

  vps::Voxmap scene;
  std::size_t scene_triangles = 0;
  int object_count = 0;  // objects[0..object_count) are present
  std::array<VpsObjectModel, device::kMaxEndEffectors> objects;
  vps::BimanualModel bimanual;  // the three pairs over the members above
  std::size_t memory_bytes() const;
};

// The model as a servo snapshot (for readers of the model channel, e.g. a view).
struct VpsModelSnapshot final : servo::ModelSnapshot {
  std::shared_ptr<const VpsLocalModel> model;
};

// What loading did, for the caller to log.
struct VpsLoadReport {
  std::vector<std::string> lines;  // one per mesh: source (cache or built), size, time
  std::vector<std::string> warnings;
};

// From meshes already in memory (tests, generated scenes). Throws
// std::invalid_argument with a one-line message on a bad spec or a mesh that
// cannot be voxelized.
std::shared_ptr<VpsLocalModel> make_vps_model(const mesh::TriangleMesh& scene, const VpsMeshSpec& scene_spec,
                                              const std::vector<std::pair<mesh::TriangleMesh, VpsMeshSpec>>& objects,
                                              const vps::ContactParams& contact);

// From the spec's mesh files through the cache. Throws std::runtime_error
// with a one-line message (file named) on a missing or bad mesh, a bad spec
// or a corrupt cache that cannot be rebuilt.
std::shared_ptr<VpsLocalModel> load_vps_model(const VpsModelSpec& spec, VpsLoadReport* report = nullptr);

// nullptr if the spec's numbers are usable, else the first problem.
const char* check_mesh_spec(const VpsMeshSpec& s);

// File helpers shared with hemm-vps: whole-file read (bounded) and the .vps
// cache file. Errors name the file.
bool read_file_bytes(const std::string& path, std::vector<std::uint8_t>* out, std::string* error);
bool load_vps_file(const std::string& path, vps::Voxmap* vm, vps::PointShell* ps, std::string* error);
bool save_vps_file(const std::string& path, const vps::Voxmap& vm, const vps::PointShell& ps, std::string* error);

}  // namespace hemm::op
