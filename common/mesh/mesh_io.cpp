#include "common/mesh/mesh_io.h"

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <filesystem>
#include <memory>

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

std::optional<MeshError> save_mesh(const std::string& path, const TriangleMesh& mesh) {
  const std::string ext = std::filesystem::path(path).extension().string();
  const char* format = ext == ".stl" ? "stlb" : ext == ".obj" ? "obj" : ext == ".ply" ? "plyb" : nullptr;
  if (format == nullptr) return MeshError{path + ": unknown mesh format (use .stl, .obj or .ply)"};
  if (mesh.triangles.empty() || mesh.vertices.empty()) return MeshError{path + ": empty mesh"};
  for (const auto& t : mesh.triangles)
    for (const std::uint32_t i : t)
      if (i >= mesh.vertices.size()) return MeshError{path + ": triangle index out of range"};
  // One mesh, one material (the exporters need one), one root node; the
  // scene owns and frees the arrays.
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode();
  scene->mRootNode->mNumMeshes = 1;
  scene->mRootNode->mMeshes = new unsigned[1]{0};
  scene->mNumMaterials = 1;
  scene->mMaterials = new aiMaterial*[1]{new aiMaterial()};
  scene->mNumMeshes = 1;
  scene->mMeshes = new aiMesh*[1]{new aiMesh()};
  aiMesh* am = scene->mMeshes[0];
  am->mMaterialIndex = 0;
  am->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  am->mNumVertices = static_cast<unsigned>(mesh.vertices.size());
  am->mVertices = new aiVector3D[am->mNumVertices];
  for (unsigned i = 0; i < am->mNumVertices; ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    am->mVertices[i] = aiVector3D(static_cast<ai_real>(v.x()), static_cast<ai_real>(v.y()), static_cast<ai_real>(v.z()));
  }
  am->mNumFaces = static_cast<unsigned>(mesh.triangles.size());
  am->mFaces = new aiFace[am->mNumFaces];
  for (unsigned f = 0; f < am->mNumFaces; ++f) {
    am->mFaces[f].mNumIndices = 3;
    am->mFaces[f].mIndices = new unsigned[3]{mesh.triangles[f][0], mesh.triangles[f][1], mesh.triangles[f][2]};
  }
  Assimp::Exporter exporter;
  if (exporter.Export(scene.get(), format, path) != aiReturn_SUCCESS)
    return MeshError{path + ": cannot write mesh: " + exporter.GetErrorString()};
  return std::nullopt;
}

}  // namespace hemm::mesh
