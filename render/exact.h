// Exact distance functions in double precision: the oracle for tests and for query answers.
#pragma once

#include <cstddef>
#include <span>

#include "render/geometry.h"
#include "render/site.h"

namespace gvd {

// Euclidean distance from q to the nearest point of the geometry.
double ExactDistance(Vec2 q, const Geometry& g);

// The smallest axis-aligned rectangle holding the geometry.
Window BoundingBox(const Geometry& g);

// The largest distance from the geometry's nearest point to any point of the rectangle:
// max over p in rect of ExactDistance(p, g).
double FarthestDistance(const Window& rect, const Geometry& g);

struct ExactNearest {
  size_t index = 0;  // into the span; meaningless when the span is empty
  double distance = 0;
};

// The nearest site to q by brute force over all sites, O(n). Ties go to the lowest index.
// CONTRACT: sites is not empty.
ExactNearest NearestBruteForce(Vec2 q, std::span<const Site> sites);

}  // namespace gvd
