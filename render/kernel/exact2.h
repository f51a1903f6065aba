// Exact distance functions in double precision: the oracle for tests and for query answers.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "render/kernel/bezier.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"

namespace gvd {

// Distance from q to the closed segment ab (a == b allowed); *t, when given, receives the
// parameter of the nearest point, clamped to [0, 1].
double SegmentDistance(Vec2 q, Vec2 a, Vec2 b, double* t = nullptr);

// Calls f(a, b) for every segment of the geometry, in feature order: a point is one
// degenerate segment, a polygon's last segment closes it, a Bezier's are its flattening's.
template <class F>
void ForEachSegment(const Geometry& g, F&& f);

// The summed length of the geometry's segments (0 for a point).
double TotalLength(const Geometry& g);

// Euclidean distance from q to the nearest point of the geometry (of its boundary, for a
// polygon, whatever its side).
double ExactDistance(Vec2 q, const Geometry& g);

// The part of the geometry nearest to q (ties: the first in feature order). Vertices are
// numbered as given (a segment's a = 0, b = 1; a Bezier's endpoints by their control-point
// index); edge i of a polyline or polygon runs from vertex i to the next; a Bezier's interior
// is the curve 0.
struct FeatureHit {
  double distance = 0;
  FeatureKind kind = FeatureKind::kVertex;
  uint32_t index = 0;
  // The point of the feature nearest to q, at `distance` from it (a Bezier's: its
  // flattening's, as its distance is).
  Vec2 closest;
};
FeatureHit NearestFeature(Vec2 q, const Geometry& g);

// The same for a site, through its segment tree when it has one (the same values).
double ExactDistance(Vec2 q, const Site& site);
// The distance to the site as the rasterizer draws it: a Bezier's flattening (within its
// tolerance of the curve), any other site's ExactDistance.
double DrawnDistance(Vec2 q, const Site& site);
FeatureHit NearestFeature(Vec2 q, const Site& site);
double FarthestDistance(const Window& rect, const Site& site);

// Whether q lies inside the polygon by the even-odd rule.
bool InsidePolygon(Vec2 q, const std::vector<Vec2>& vertices);

// The site's value at q: multiplicative * d + additive, or +infinity where the site is no
// candidate (beyond its max_distance, or on the side of a polygon it excludes; the boundary
// itself belongs to both sides).
double SiteValue(Vec2 q, const Site& site);

// A polyline through points of the Bezier curve (3 or 4 control points) that stays within
// `tolerance` of it: uniform in the parameter, with n pieces where the bound
// deg (deg - 1) / 8 * max |P[i+2] - 2 P[i+1] + P[i]| / n^2 <= tolerance.
// CONTRACT: 3 or 4 control points, finite; tolerance > 0.
std::vector<Vec2> Flatten(const std::vector<Vec2>& control, double tolerance);
// The most pieces Flatten makes; a tolerance that would need more is widened to fit.
inline constexpr uint32_t kMaxBezierPieces = 4096;
// A Bezier site. tolerance 0 means a thousandth of the control polygon's length (or 1e-9 if
// that is 0).
BezierSite MakeBezier(std::vector<Vec2> control, double tolerance);

// The smallest axis-aligned rectangle holding the geometry.
Window BoundingBox(const Geometry& g);

// An upper bound on the distance from the geometry to any point of the rectangle, and the
// exact maximum for a point: max over p in rect of ExactDistance(p, g) <= result.
double FarthestDistance(const Window& rect, const Geometry& g);

// ---- implementation ----

template <class F>
void ForEachSegment(const Geometry& g, F&& f) {
  if (const auto* p = std::get_if<PointSite>(&g)) {
    f(p->p, p->p);
  } else if (const auto* s = std::get_if<SegmentSite>(&g)) {
    f(s->a, s->b);
  } else if (const auto* l = std::get_if<PolylineSite>(&g)) {
    for (size_t i = 0; i + 1 < l->points.size(); ++i) f(l->points[i], l->points[i + 1]);
  } else if (const auto* poly = std::get_if<PolygonSite>(&g)) {
    const auto& v = poly->vertices;
    for (size_t i = 0; i < v.size(); ++i) f(v[i], v[(i + 1) % v.size()]);
  } else if (const auto* b = std::get_if<BezierSite>(&g)) {
    for (size_t i = 0; i + 1 < b->flat.size(); ++i) f(b->flat[i], b->flat[i + 1]);
  }
}

}  // namespace gvd
