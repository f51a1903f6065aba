// What a scene is made with: its id, its pixel grid, its error bound and how it is drawn.
#pragma once

#include <cstdint>
#include <string>

#include "render/kernel/diagram.h"
#include "render/kernel/grid2.h"

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
  Grid grid;
  double eps = 0;        // the distance meshes' error bound, scene units (never 0)
  uint32_t cone_triangles = 0;  // for sites inside the window
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;
};

}  // namespace gvd
