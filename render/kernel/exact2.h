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
// degenerate segment, a polygon's last segment closes it, a Bezier's are its flattening's, a
// path's its pieces' drawn polylines, piece after piece.
template <class F>
void ForEachSegment(const Geometry& g, F&& f);

// The chains that ForEachSegment's segments form, in its order: f(begin, end, closed) for
// each run [begin, end) of segments each starting where the one before it ends; closed when
// the last ends where the first starts and they join there (a polygon's; a path's closed
// subpaths'). One chain but for a path, which has one a subpath.
template <class F>
void ForEachChain(const Geometry& g, F&& f);

// How far the geometry's segments (ForEachSegment) may stray from the shape it stands for: a
// Bezier's tolerance; a path's when it has curves, plus its approximation; else 0.
double DrawnTolerance(const Geometry& g);

// Where the site is restricted to: a polygon's or a path's side, else Side::kBoth.
Side SideOf(const Geometry& g);
// Whether q lies inside a polygon (even-odd) or a path (its fill rule, path2.h); false for
// the other kinds, which have no inside.
bool InsideOf(Vec2 q, const Geometry& g);

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
// The distance to the site as the rasterizer draws it: the segments of a Bezier or a path
// with curves (within DrawnTolerance of it), any other site's ExactDistance.
double DrawnDistance(Vec2 q, const Site& site);
FeatureHit NearestFeature(Vec2 q, const Site& site);
double FarthestDistance(const Window& rect, const Site& site);

// Whether q lies inside the polygon by the even-odd rule.
bool InsidePolygon(Vec2 q, const std::vector<Vec2>& vertices);

// The site's value at q: multiplicative * d + additive, or +infinity where the site is no
// candidate (beyond its max_distance, or on the side of a polygon or path it excludes; the
// boundary itself belongs to both sides).
double SiteValue(Vec2 q, const Site& site);
// The same from d, q's ExactDistance to the site, or NearestFeature's distance, which is the
// same number (one search of a curve or a tree for both the value and the feature).
double SiteValueAt(Vec2 q, const Site& site, double d);

// A polyline through points of the Bezier curve (3 or 4 control points) that stays within
// `tolerance` of it: uniform in the parameter, with n pieces where the bound
// FlattenBound(control) / n^2 <= tolerance.
// CONTRACT: 3 or 4 control points, finite; tolerance > 0.
std::vector<Vec2> Flatten(const std::vector<Vec2>& control, double tolerance);
// deg (deg - 1) / 8 * max |P[i+2] - 2 P[i+1] + P[i]|: how far the curve strays from a
// uniform polyline of one piece (of n pieces: this over n^2).
double FlattenBound(const std::vector<Vec2>& control);
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
  } else if (const auto* path = std::get_if<PathSite>(&g)) {
    const auto& pieces = path->pieces;
    for (size_t k = 0; k < pieces.size(); ++k) {
      const size_t end = k + 1 < pieces.size() ? pieces[k + 1].flat_begin : path->flat.size();
      for (size_t i = pieces[k].flat_begin; i + 1 < end; ++i) f(path->flat[i], path->flat[i + 1]);
    }
  }
}

template <class F>
void ForEachChain(const Geometry& g, F&& f) {
  if (const auto* path = std::get_if<PathSite>(&g)) {
    // Piece k's segments start at flat_begin - k (each piece's polyline has one point more).
    const auto& pieces = path->pieces;
    uint32_t k = 0;
    for (const Subpath& sub : path->subpaths) {
      const uint32_t first = k, last = k + static_cast<uint32_t>(sub.degrees.size());
      const uint32_t end = last < pieces.size() ? pieces[last].flat_begin - last
                                                : static_cast<uint32_t>(path->flat.size() - last);
      f(pieces[first].flat_begin - first, end, sub.closed);
      k = last;
    }
    return;
  }
  uint32_t count = 0;
  ForEachSegment(g, [&](Vec2, Vec2) { ++count; });
  f(0u, count, std::holds_alternative<PolygonSite>(g));
}

}  // namespace gvd
