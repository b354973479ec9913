// A plain triangle mesh value type and its pure validator. Loading from files
// lives in mesh_io.h (assimp); this header has no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hemm::mesh {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;           // metres
  std::vector<std::array<std::uint32_t, 3>> triangles;  // indices into vertices, CCW seen from outside
};

// Limits a mesh must respect to be accepted.
struct MeshLimits {
  double max_extent = 1000.0;       // metres; larger is treated as a unit error
  double min_extent = 1e-6;         // metres; a zero-extent mesh is rejected
  double degenerate_area = 1e-16;   // m^2; triangles with less area are dropped (and counted)
  std::size_t max_triangles = 50'000'000;
};

// What the validator found. `closed` means every edge has exactly two
// triangles; `consistently_oriented` that each directed edge occurs once
// (so the winding is coherent). Open or non-manifold meshes are accepted with
// these flags: the voxmap then falls back to an unsigned (surface-shell) field.
struct MeshReport {
  std::size_t input_triangles = 0;
  std::size_t degenerate_dropped = 0;      // zero area or repeated index
  std::size_t unused_vertices = 0;
  std::size_t boundary_edges = 0;          // edges used by one triangle
  std::size_t nonmanifold_edges = 0;       // edges used by three or more triangles
  std::size_t inconsistent_edges = 0;      // directed edge used twice (flipped neighbour)
  bool closed = false;
  bool consistently_oriented = false;
  bool flipped = false;                    // closed mesh wound inside-out: windings were reversed
  double area = 0.0;
  double signed_volume = 0.0;              // after any flip (positive for a closed, outward mesh)
  Eigen::AlignedBox3d bounds;

  // closed && consistently oriented && no non-manifold edge: inside/outside is defined.
  bool watertight() const { return closed && consistently_oriented && nonmanifold_edges == 0; }
};

struct MeshError {
  std::string message;
};

// Checks `in` and writes a cleaned copy to `*out` (degenerate triangles dropped,
// an inside-out closed mesh re-wound). On error `*out` and `*report` are not touched.
// Errors: empty mesh, index out of range, NaN/inf coordinates, extent outside the
// limits, too many triangles, no triangle left after dropping degenerates.
std::optional<MeshError> validate_mesh(const TriangleMesh& in, const MeshLimits& limits,
                                       TriangleMesh* out, MeshReport* report);

// Rigid-body properties of a closed, outward-wound mesh of uniform density
// (divergence theorem over tetrahedra from the origin).
struct MassProperties {
  double volume = 0.0;
  double mass = 0.0;
  Eigen::Vector3d centre_of_mass = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia_com = Eigen::Matrix3d::Zero();  // about the centre of mass, mesh axes
};
MassProperties compute_mass_properties(const TriangleMesh& mesh, double density);

double mesh_area(const TriangleMesh& mesh);
Eigen::AlignedBox3d mesh_bounds(const TriangleMesh& mesh);

// Merges vertices with identical coordinates (STL stores each facet's
// corners separately) and remaps the triangles; returns how many were merged.
std::size_t weld_identical_vertices(TriangleMesh* m);

// Appends `b` (transformed by T) to `a`.
void append_mesh(TriangleMesh* a, const TriangleMesh& b,
                 const Eigen::Isometry3d& T = Eigen::Isometry3d::Identity());

}  // namespace hemm::mesh
