// Model files as the CLI reads them (client/cli/model.h), on Debian's assimp-testmodels: its
// invalid/ corpus and every model beside it. Each file is read, with a mesh that holds the
// file's surface, or refused with an error naming it (and the memory limit where that is
// the cause); nothing crashes the reader and nothing takes more than the limit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "client/cli/model.h"
#include "tests/support/assimp_direct.h"
#include "tests/support/oracle3.h"

namespace gvd {
namespace {

constexpr uint64_t kLimit = uint64_t{256} << 20;
const std::filesystem::path kModels = "/usr/share/assimp/models";

struct Triangle {
  Vec3 a, b, c;
};

std::vector<Triangle> Triangles(const v1::Mesh& mesh) {
  std::vector<Triangle> out;
  auto vertex = [&](uint32_t i) {
    return Vec3(mesh.xyz(3 * int(i)), mesh.xyz(3 * int(i) + 1), mesh.xyz(3 * int(i) + 2));
  };
  for (int t = 0; t + 2 < mesh.triangles_size(); t += 3) {
    out.push_back({vertex(mesh.triangles(t)), vertex(mesh.triangles(t + 1)), vertex(mesh.triangles(t + 2))});
  }
  return out;
}

oracle3::Real DistanceTo(Vec3 q, const std::vector<Triangle>& triangles) {
  oracle3::Real best = INFINITY;
  for (const Triangle& t : triangles) best = std::min(best, oracle3::ToTriangle(q, t.a, t.b, t.c));
  return best;
}

// The faces of an OBJ file as the test reads them, apart from Assimp: "v X Y Z" vertices and
// "f I J K ..." faces (1-based, negative from the end), each a fan of triangles; faces that
// name no vertex or one out of range are skipped.
std::vector<Triangle> ObjFaces(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<Vec3> v;
  std::vector<std::vector<long>> faces;
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string kind;
    words >> kind;
    if (kind == "v") {
      Vec3 p;
      words >> p.x >> p.y >> p.z;
      v.push_back(p);
    } else if (kind == "f") {
      faces.emplace_back();
      for (std::string w; words >> w;) faces.back().push_back(std::stol(w.substr(0, w.find('/'))));
    }
  }
  std::vector<Triangle> out;
  for (const auto& f : faces) {
    std::vector<Vec3> corners;
    for (long i : f) {
      const long k = i > 0 ? i - 1 : static_cast<long>(v.size()) + i;
      if (k >= 0 && k < static_cast<long>(v.size())) corners.push_back(v[k]);
    }
    if (corners.size() != f.size() || corners.size() < 3) continue;
    for (size_t k = 1; k + 1 < corners.size(); ++k) out.push_back({corners[0], corners[k], corners[k + 1]});
  }
  return out;
}

// Assimp's invalid/ files: each refused by name, OutOfMemory.off (353,535,235,358 vertices
// declared in 309 bytes) by the memory limit; the one that reads (malformed2.obj, a cube
// without one face and with a material that does not exist) holds the file's faces, at 500
// random points within 1e-6 of the distances to the faces as the test reads them.
TEST(ModelFiles, AssimpsInvalidFilesAreRefusedByNameOrReadWhole) {
  ASSERT_TRUE(std::filesystem::is_directory(kModels / "invalid"))
      << "install Debian's assimp-testmodels";
  int read = 0, files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kModels / "invalid")) {
    const std::string path = entry.path().string();
    ++files;
    v1::Mesh mesh;
    std::string error;
    if (!cli::ReadModel({.path = path}, {.memory_bytes = kLimit}, &mesh, &error)) {
      EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << error;
      if (entry.path().filename() == "OutOfMemory.off") {
        EXPECT_EQ(error, path + ": reading it takes more than the memory limit of 256 MiB "
                                "(--memory-limit)");
      }
      continue;
    }
    ++read;
    ASSERT_EQ(entry.path().extension(), ".obj") << path << " read; the test knows OBJ only";
    const std::vector<Triangle> faces = ObjFaces(entry.path()), got = Triangles(mesh);
    ASSERT_FALSE(faces.empty()) << path;
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 500; ++i) {
      const Vec3 q(u(rng), u(rng), u(rng));
      ASSERT_NEAR(double(DistanceTo(q, got)), double(DistanceTo(q, faces)), 1e-6) << path;
    }
  }
  EXPECT_EQ(files, 15);
  EXPECT_EQ(read, 1);
}

// 188 bytes of PLY (found by fuzzing, tests/fuzz/corpus/model/endless.ply) on which Assimp
// never finishes: the child's CPU time limit ends it, and the error names the limit.
TEST(ModelFiles, AnEndlessImportEndsAtTheCpuLimit) {
  const std::string path = GVD_MODEL_CORPUS "/endless.ply";
  v1::Mesh mesh;
  std::string error;
  EXPECT_FALSE(cli::ReadModel({.path = path}, {.memory_bytes = kLimit, .cpu_seconds = 1}, &mesh, &error));
  EXPECT_EQ(error, path + ": reading it takes more than 1 s of CPU time, the model importer's limit");
}

// Every file of assimp-testmodels beside invalid/: read into a mesh whose corners are its
// vertices and whose triangles are those Assimp gives in this process, or refused by name.
TEST(ModelFiles, EveryAssimpModelIsReadWholeOrRefusedByName) {
  ASSERT_TRUE(std::filesystem::is_directory(kModels)) << "install Debian's assimp-testmodels";
  int read = 0, refused = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(kModels)) {
    if (!entry.is_regular_file()) continue;
    const std::string path = entry.path().string();
    v1::Mesh mesh;
    std::string error;
    if (!cli::ReadModel({.path = path}, {.memory_bytes = kLimit}, &mesh, &error)) {
      ++refused;
      EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << error;
      continue;
    }
    ++read;
    const uint32_t vertices = static_cast<uint32_t>(mesh.xyz_size() / 3);
    ASSERT_EQ(mesh.triangles_size() % 3, 0) << path;
    for (uint32_t i : mesh.triangles()) ASSERT_LT(i, vertices) << path;
    const std::vector<Triangle> got = Triangles(mesh);
    const auto direct = testing::AssimpTriangles(path);
    ASSERT_EQ(got.size(), direct.size()) << path;
    for (size_t t = 0; t < got.size(); ++t) {
      ASSERT_TRUE(got[t].a == direct[t][0] && got[t].b == direct[t][1] && got[t].c == direct[t][2])
          << path << " triangle " << t;
    }
  }
  std::printf("%d model files read, %d refused\n", read, refused);
  EXPECT_GT(read, 300);
}

}  // namespace
}  // namespace gvd
