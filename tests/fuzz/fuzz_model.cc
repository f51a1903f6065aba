// Fuzz target: bytes as a model file, read as the CLI reads `sites add mesh --file`
// (client/cli/model.h: Assimp in a child process under a memory limit, the format found from
// the bytes). Whatever the input: no crash of this process; a refusal names the input; what
// is read is a mesh of whole triangles whose corners are among its vertices, every
// coordinate finite, and it is the mesh Assimp gives in this process for the same bytes
// (read here again, only once the child has shown that the bytes fit the limit).
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "client/cli/model.h"

namespace {

const gvd::cli::ModelLimits kLimits{.memory_bytes = uint64_t{256} << 20, .cpu_seconds = 2};

void Check(bool ok) {
  if (!ok) std::abort();
}

// The triangles of the scene Assimp reads in this process, with the import's steps of
// model.cc, as vertex coordinates three by three: the oracle of what the child sent back.
std::vector<double> Direct(const std::string& bytes) {
  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFileFromMemory(
      bytes.data(), bytes.size(),
      aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
          aiProcess_PreTransformVertices,
      "");
  std::vector<double> corners;
  if (scene == nullptr) return corners;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* part = scene->mMeshes[m];
    for (unsigned f = 0; f < part->mNumFaces; ++f) {
      if (part->mFaces[f].mNumIndices != 3) continue;
      for (unsigned k = 0; k < 3; ++k) {
        const aiVector3D& p = part->mVertices[part->mFaces[f].mIndices[k]];
        corners.insert(corners.end(), {p.x, p.y, p.z});
      }
    }
  }
  return corners;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  gvd::v1::Mesh mesh;
  std::string error;
  if (!gvd::cli::ReadModel({.path = "input", .bytes = &bytes}, kLimits, &mesh, &error)) {
    Check(error.rfind("input: ", 0) == 0 && error.size() > 7);
    return 0;
  }
  Check(mesh.xyz_size() % 3 == 0 && mesh.triangles_size() % 3 == 0 && mesh.triangles_size() > 0);
  const uint32_t vertices = static_cast<uint32_t>(mesh.xyz_size() / 3);
  for (double c : mesh.xyz()) Check(std::isfinite(c));
  for (uint32_t i : mesh.triangles()) Check(i < vertices);
  const std::vector<double> direct = Direct(bytes);
  Check(direct.size() == size_t(mesh.triangles_size()) * 3);
  for (int t = 0; t < mesh.triangles_size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      Check(direct[3 * size_t(t) + k] == mesh.xyz(3 * int(mesh.triangles(t)) + k));
    }
  }
  return 0;
}
