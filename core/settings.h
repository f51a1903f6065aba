// What a scene is made with: its id, its pixel grid, its error bound and how it is drawn.
#pragma once

#include <cstdint>
#include <string>

#include "core/frame.h"
#include "geometry/exact.h"
#include "geometry/geometry.h"

namespace gvd {

struct SceneSettings {
  std::string id;
  Grid grid;
  double eps = 0;        // the distance meshes' error bound, scene units (never 0)
  uint32_t cone_triangles = 0;  // for sites inside the window
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;
};

}  // namespace gvd
