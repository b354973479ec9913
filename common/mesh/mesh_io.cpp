#include "common/mesh/mesh_io.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <filesystem>

namespace hemm::mesh {

namespace {
void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, double scale, TriangleMesh* m,
             std::size_t* skipped_faces) {
  const aiMatrix4x4 T = parent * node->mTransformation;
  for (unsigned i = 0; i < node->mNumMeshes; ++i) {
    const aiMesh* am = scene->mMeshes[node->mMeshes[i]];
    const auto base = static_cast<std::uint32_t>(m->vertices.size());
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D p = T * am->mVertices[v];
      m->vertices.push_back(scale * Eigen::Vector3d(p.x, p.y, p.z));
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices != 3) {  // points and lines left after triangulation
        ++*skipped_faces;
        continue;
      }
      m->triangles.push_back({base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) collect(scene, node->mChildren[c], T, scale, m, skipped_faces);
}
}  // namespace

std::optional<MeshError> load_mesh(const std::string& path, const LoadOptions& options, TriangleMesh* out,
                                   MeshReport* report) {
  if (!(options.scale > 0.0) || !std::isfinite(options.scale)) return MeshError{path + ": scale must be positive"};
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return MeshError{path + ": no such file"};
  Assimp::Importer importer;
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_Triangulate | aiProcess_SortByPType);
  if (scene == nullptr || scene->mRootNode == nullptr || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0)
    return MeshError{path + ": cannot read mesh: " + importer.GetErrorString()};
  TriangleMesh m;
  std::size_t skipped = 0;
  collect(scene, scene->mRootNode, aiMatrix4x4(), options.scale, &m, &skipped);
  if (m.triangles.empty()) return MeshError{path + ": the file holds no triangles"};
  weld_identical_vertices(&m);
  TriangleMesh valid;
  MeshReport r;
  if (auto err = validate_mesh(m, options.limits, &valid, &r)) return MeshError{path + ": " + err->message};
  *out = std::move(valid);
  *report = r;
  return std::nullopt;
}

}  // namespace hemm::mesh
