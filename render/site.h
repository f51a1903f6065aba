// Voronoi sites as the render layer sees them: an id and a geometry.
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "render/geometry.h"

namespace gvd {

struct PointSite {
  Vec2 p;
};

// Every site kind; new kinds are added here and in exact.cc and the mesh builders.
using Geometry = std::variant<PointSite>;

struct Site {
  std::string id;
  Geometry geometry;
};

// An immutable, densely indexed set of sites; a frame's id buffer holds index + 1.
using SiteTable = std::vector<Site>;

}  // namespace gvd
