// Fuzz target: bytes as a model file, read as the CLI reads `sites add mesh --file`
// (client/cli/model.h: Assimp in a child process under a memory limit, the format found from
// the bytes). Whatever the input: no crash of this process; a refusal names the input; what
// is read is a mesh of whole triangles whose corners are among its vertices, every
// coordinate finite, and it is the mesh Assimp gives in this process for the same bytes
// (read here again, only once the child has shown that the bytes fit the limit).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "client/cli/model.h"
#include "tests/support/assimp_direct.h"

namespace {

const gvd::cli::ModelLimits kLimits{.memory_bytes = uint64_t{256} << 20, .cpu_seconds = 2};

void Check(bool ok) {
  if (!ok) std::abort();
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
  const auto direct = gvd::testing::AssimpTriangles("input", &bytes);
  Check(direct.size() * 3 == size_t(mesh.triangles_size()));
  for (int c = 0; c < mesh.triangles_size(); ++c) {
    const gvd::Vec3 corner = direct[size_t(c) / 3][size_t(c) % 3];
    for (int k = 0; k < 3; ++k) Check(corner[k] == mesh.xyz(3 * int(mesh.triangles(c)) + k));
  }
  return 0;
}
