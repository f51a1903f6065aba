// The tests' oracle for the CLI's model reader (client/cli/model.h): what Assimp reads in the
// test's own process, with the reader's steps (triangulated, identical vertices joined, points
// and lines dropped, the scene graph's transforms applied), as each triangle's corners in
// order. Call it only once the reader has shown that the input fits its memory limit.
#pragma once

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <array>
#include <string>
#include <vector>

#include "render/kernel/vec.h"

namespace gvd::testing {

// A file by its path, or (bytes != nullptr) bytes whose format Assimp finds from them.
inline std::vector<std::array<Vec3, 3>> AssimpTriangles(const std::string& path,
                                                        const std::string* bytes = nullptr) {
  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const unsigned steps = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_SortByPType | aiProcess_PreTransformVertices;
  const aiScene* scene = bytes ? importer.ReadFileFromMemory(bytes->data(), bytes->size(), steps, "")
                               : importer.ReadFile(path, steps);
  std::vector<std::array<Vec3, 3>> out;
  if (scene == nullptr) return out;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* part = scene->mMeshes[m];
    auto at = [&](unsigned i) {
      const aiVector3D& p = part->mVertices[i];
      return Vec3(p.x, p.y, p.z);
    };
    for (unsigned f = 0; f < part->mNumFaces; ++f) {
      const aiFace& face = part->mFaces[f];
      if (face.mNumIndices == 3) out.push_back({at(face.mIndices[0]), at(face.mIndices[1]), at(face.mIndices[2])});
    }
  }
  return out;
}

}  // namespace gvd::testing
