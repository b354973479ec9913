// Mesh files through assimp (STL, OBJ, PLY, OFF, ...). The loaded mesh is
// then run through validate_mesh(); nothing is returned unvalidated.
#pragma once

#include <optional>
#include <string>

#include "common/mesh/triangle_mesh.h"

namespace hemm::mesh {

struct LoadOptions {
  double scale = 1.0;  // file units -> metres (e.g. 0.001 for millimetre files)
  MeshLimits limits;
};

// Reads every mesh of the file (node transforms applied), welds vertices with
// identical coordinates, triangulates polygons, then validates. On error `*out`/`*report`
// are untouched and the message names the file.
std::optional<MeshError> load_mesh(const std::string& path, const LoadOptions& options, TriangleMesh* out,
                                   MeshReport* report);

// Writes `mesh` through assimp's exporters, the format from the extension
// (.stl binary STL, .obj, .ply binary PLY). Coordinates in metres.
std::optional<MeshError> save_mesh(const std::string& path, const TriangleMesh& mesh);

}  // namespace hemm::mesh
