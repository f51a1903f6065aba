// Exact distance functions in double precision: the oracle for tests and for query answers.
#pragma once

#include <cstddef>
#include <span>

#include "render/geometry.h"
#include "render/site.h"

namespace gvd {

// Euclidean distance from q to the nearest point of the geometry.
double ExactDistance(Vec2 q, const Geometry& g);

// Distance from q to the farthest point of the window that a site's distance function
// must cover: an upper bound on the distance from the site to any sample of the window.
double FarthestWindowDistance(const Window& window, const Geometry& g);

struct ExactNearest {
  size_t index = 0;  // into the span; meaningless when the span is empty
  double distance = 0;
};

// The nearest site to q by brute force over all sites, O(n). Ties go to the lowest index.
// CONTRACT: sites is not empty.
ExactNearest NearestBruteForce(Vec2 q, std::span<const Site> sites);

}  // namespace gvd
