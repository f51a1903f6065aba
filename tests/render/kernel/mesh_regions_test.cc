// A mesh's distances over boxes of voxels, feature by feature (render/kernel/mesh_regions.h),
// against the tests' own oracle (tests/support/oracle3.h) at every voxel centre: closed and
// open meshes, and the meshes whose regions are hard: a triangle soup (each edge bounding one
// triangle, so the regions are wide and the boxes fall back on the tree), an edge shared by
// four triangles, slivers, collinear and coincident triangles, an edge of length zero, a
// vertex used by no triangle, and a mesh far from the origin; boxes inside, across and
// outside the mesh, and cut by the grid's end.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "render/kernel/mesh_regions.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"

namespace gvd {
namespace {

// Each triangle of `m` with vertices of its own: no two triangles share an edge.
MeshSite3 Soup(const MeshSite3& m) {
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  for (const auto& t : m.triangles) {
    for (uint32_t v : t) {
      tri.push_back(static_cast<uint32_t>(xyz.size() / 3));
      xyz.insert(xyz.end(), {m.vertices[v].x, m.vertices[v].y, m.vertices[v].z});
    }
  }
  return Mesh(xyz, tri);
}

// Every voxel centre of every box of up to 5^3 voxels tiling `grid` (the last ones cut by
// its end), against the oracle and against the mesh's search through its tree.
void CheckEveryBox(const MeshSite3& mesh, const Grid3& grid, const std::string& what) {
  int failures = 0;
  std::vector<double> out;
  constexpr uint32_t kStep = 5;
  for (uint32_t z = 0; z < grid.depth; z += kStep) {
    for (uint32_t y = 0; y < grid.height; y += kStep) {
      for (uint32_t x = 0; x < grid.width; x += kStep) {
        const VoxelBox box{x, y, z, std::min(x + kStep, grid.width), std::min(y + kStep, grid.height),
                           std::min(z + kStep, grid.depth)};
        out.assign(box.volume(), -1);
        MeshRegions::Distances(mesh, grid, box, out.data());
        size_t n = 0;
        for (uint32_t k = box.z0; k < box.z1; ++k) {
          for (uint32_t j = box.y0; j < box.y1; ++j) {
            for (uint32_t i = box.x0; i < box.x1; ++i, ++n) {
              const Vec3 p = grid.Center(i, j, k);
              const double truth = double(oracle3::ToGeometry(p, mesh));
              const double tree = MeshDistance(p, mesh);
              const double scale = 1 + std::abs(p.x) + std::abs(p.y) + std::abs(p.z);
              if (!(std::abs(out[n] - truth) <= 1e-12 * scale) ||
                  !(std::abs(out[n] - tree) <= 1e-14 * scale)) {
                if (++failures < 10) {
                  ADD_FAILURE() << what << " voxel " << i << "," << j << "," << k << ": "
                                << out[n] << ", oracle " << truth << ", tree " << tree;
                }
              }
            }
          }
        }
      }
    }
  }
  EXPECT_EQ(failures, 0) << what;
}

TEST(MeshRegions, ClosedAndOpenMeshesAgainstTheOracle) {
  const Grid3 grid{{-2, -2, -1.5, 2, 2, 1.5}, 23, 21, 17};
  CheckEveryBox(Icosphere(2), grid, "icosphere");
  CheckEveryBox(Torus(1.2, 0.4, 24, 12), grid, "torus");
  CheckEveryBox(Placed(Patch(8), {-1, -1, -0.3}, 2), grid, "patch");
  // Mostly outside the grid, and a grid far from the origin around a mesh far from it.
  CheckEveryBox(Placed(Icosphere(1), {2.5, 0, 0}, 1), grid, "outside");
  const Vec3 far(1e6, -3e6, 2e6);
  CheckEveryBox(Placed(Torus(1.2, 0.4, 16, 8), far, 1),
                {{far.x - 2, far.y - 2, far.z - 1.5, far.x + 2, far.y + 2, far.z + 1.5}, 19, 17, 13},
                "far");
}

TEST(MeshRegions, SoupsSliversAndDegenerateTrianglesAgainstTheOracle) {
  const Grid3 grid{{-2, -2, -1.5, 2, 2, 1.5}, 21, 19, 15};
  // Wide regions: many boxes test too many features and are searched through the tree.
  CheckEveryBox(Soup(Torus(1.2, 0.4, 24, 12)), grid, "soup");
  CheckEveryBox(Soup(Icosphere(1)), grid, "small soup");
  // Four triangles about one edge (a non-manifold edge), two of them coincident.
  CheckEveryBox(Mesh({0, 0, -1, 0, 0, 1, 1, 0, 0, -1, 0.2, 0, 0.3, -1, 0.1},
                     {0, 1, 2, 0, 1, 3, 1, 0, 4, 0, 1, 2}),
                grid, "fan");
  // A sliver (an angle of 1e-9), a collinear triangle, a triangle with two corners at one
  // point (an edge of length zero), a triangle whose corner repeats an index, and a vertex
  // no triangle uses.
  CheckEveryBox(Mesh({-1, -1, 0, 1, 1, 0.5, 1, 1 + 1e-9, 0.5,       // sliver
                      -1, 1, -1, 0, 1, 0, 1, 1, 1,                  // collinear
                      0.5, -1, 0, 0.5, -1, 0, 1, -0.5, -0.5,        // two corners coincide
                      -0.5, 0, 1, 0.5, 0.5, 0.5, 9, 9, 9},          // last: unused
                     {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 9}),
                grid, "degenerate");
  // Random triangles, some crossing others.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  for (uint32_t i = 0; i < 90; ++i) {
    xyz.insert(xyz.end(), {u(rng), u(rng), u(rng)});
    if (i >= 2) tri.insert(tri.end(), {i - 2, i - 1, i});
  }
  CheckEveryBox(Mesh(xyz, tri), grid, "random strip");
}

}  // namespace
}  // namespace gvd
