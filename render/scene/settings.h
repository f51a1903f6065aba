// What a scene is made with: its id, its pixel grid, its error bound and how it is drawn.
#pragma once

#include <cstdint>
#include <string>

#include "render/kernel/diagram.h"
#include "render/kernel/grid2.h"
#include "render/kernel/grid3.h"

namespace gvd {

// How distance functions are drawn. kMesh: the paper's bounded-error meshes (a fan of
// triangles within eps for every vertex, two exact planes per edge), interpolated by the
// rasterizer. kExact: one quad per site whose fragments compute the site's distance
// analytically and write it as depth (no meshing error; no early depth test either).
// Some sites are drawn as in kExact whatever the mode, because one depth test cannot draw
// them from pieces: polygons restricted to one side (the fragment tests the side), and every
// site but a point in a kFarthest diagram (the site's value is the least over its pieces,
// the diagram's the greatest over sites).
enum class RenderMode { kMesh, kExact };

struct SceneSettings {
  std::string id;
  // The window and its pixels; in a 3D scene, the box's x and y and its voxels a slice.
  Grid grid;
  // A 3D scene's slices, one per z in [min_z, max_z]: depth > 0 (a 2D scene has none).
  uint32_t depth = 0;
  double min_z = 0, max_z = 0;
  double eps = 0;        // the distance meshes' error bound, scene units (never 0)
  uint32_t cone_triangles = 0;  // for sites inside the window
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;

  bool three_d() const { return depth > 0; }
  // A 3D scene's box and voxels.
  Grid3 grid3() const {
    const Window& w = grid.window;
    return {{w.min_x, w.min_y, min_z, w.max_x, w.max_y, max_z}, grid.width, grid.height, depth};
  }
};

}  // namespace gvd
