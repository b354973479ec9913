// Generated meshes for tests, reports and scenes (pure, no I/O). All are
// closed and wound outward unless said otherwise.
#pragma once

#include <functional>
#include <vector>

#include "common/mesh/triangle_mesh.h"

namespace hemm::mesh {

// Icosahedron subdivided `subdivisions` times, projected to the sphere:
// 20 * 4^subdivisions triangles.
TriangleMesh make_icosphere(double radius, int subdivisions);

// Latitude/longitude sphere: 2 * slices * (stacks - 1) triangles.
TriangleMesh make_uv_sphere(double radius, int slices, int stacks);

// Axis-aligned box centred at the origin, each face an n x n grid:
// 12 n^2 triangles.
TriangleMesh make_box(const Eigen::Vector3d& half_extents, int n = 1);

// Cylinder of the given radius about the z axis from z = -half_height to
// +half_height: a `slices`-sided prism with its vertices on the circle, capped
// by fans: 4 * slices triangles. The side lies within r (1 - cos(pi/slices))
// of the true cylinder (12 um at r = 4 cm, 128 slices).
TriangleMesh make_cylinder(double radius, double half_height, int slices);

// The boundary of a union of cells of a rectilinear grid (cell (i,j,k) spans
// [xs[i],xs[i+1]] x [ys[j],ys[j+1]] x [zs[k],zs[k+1]], filled where `filled`
// says so). Closed and manifold when no two filled cells touch only along an
// edge or a corner. Used for pegs, holes and thin walls.
TriangleMesh make_rectilinear_solid(const std::vector<double>& xs, const std::vector<double>& ys,
                                    const std::vector<double>& zs,
                                    const std::function<bool(int, int, int)>& filled);

// An open square sheet in the z = 0 plane, n x n cells (2 n^2 triangles), normal +z.
TriangleMesh make_open_sheet(double half_size, int n);

}  // namespace hemm::mesh
