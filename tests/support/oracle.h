// The tests' own oracle for distances, sides, site values, best sites and nearest features:
// written apart from render/kernel/exact2.h (which answers queries) so that a test cannot agree
// with the code it judges by construction. It computes in long double (64-bit mantissa,
// 15-bit exponent: no overflow or underflow of squares for any finite double input) with
// the plainest formulas, and rounds once at the end; production answers are compared with
// it within Tolerance().
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "render/kernel/diagram.h"
#include "render/kernel/exact2.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"

namespace gvd::oracle {

using Real = long double;

// Distance from q to the closed segment ab, and the clamped parameter of its nearest point.
inline Real ToSegment(Vec2 q, Vec2 a, Vec2 b, Real* t_out = nullptr) {
  const Real dx = Real(b.x) - a.x, dy = Real(b.y) - a.y;
  const Real len2 = dx * dx + dy * dy;
  Real t = 0;
  if (len2 > 0) t = std::clamp(((Real(q.x) - a.x) * dx + (Real(q.y) - a.y) * dy) / len2, Real(0), Real(1));
  if (t_out) *t_out = t;
  const Real px = a.x + t * dx, py = a.y + t * dy;
  return std::hypot(Real(q.x) - px, Real(q.y) - py);
}

// The segments of a geometry in feature order: (a, b, edge index). A point is one degenerate
// segment; a polygon closes; a Bezier's are its flattening's.
inline std::vector<std::pair<Vec2, Vec2>> Segments(const Geometry& g) {
  std::vector<std::pair<Vec2, Vec2>> out;
  auto chain = [&out](const std::vector<Vec2>& v, bool closed) {
    for (size_t i = 0; i + 1 < v.size(); ++i) out.push_back({v[i], v[i + 1]});
    if (closed && v.size() > 1) out.push_back({v.back(), v.front()});
  };
  if (auto* p = std::get_if<PointSite>(&g)) out.push_back({p->p, p->p});
  if (auto* s = std::get_if<SegmentSite>(&g)) out.push_back({s->a, s->b});
  if (auto* l = std::get_if<PolylineSite>(&g)) chain(l->points, false);
  if (auto* poly = std::get_if<PolygonSite>(&g)) chain(poly->vertices, true);
  if (auto* b = std::get_if<BezierSite>(&g)) chain(b->flat, false);
  return out;
}

// Euclidean distance from q to the geometry (a polygon's boundary, whatever its side).
inline double Distance(Vec2 q, const Geometry& g) {
  Real best = std::numeric_limits<Real>::infinity();
  for (auto [a, b] : Segments(g)) best = std::min(best, ToSegment(q, a, b));
  return static_cast<double>(best);
}

// Even-odd rule by counting the edges that a ray from q towards +x crosses.
inline bool Inside(Vec2 q, const std::vector<Vec2>& v) {
  bool inside = false;
  for (size_t i = 0, j = v.size() - 1; i < v.size(); j = i++) {
    const Vec2 a = v[i], b = v[j];
    if ((a.y > q.y) == (b.y > q.y)) continue;
    const Real x = Real(a.x) + (Real(q.y) - a.y) * (Real(b.x) - a.x) / (Real(b.y) - a.y);
    if (Real(q.x) < x) inside = !inside;
  }
  return inside;
}

// The site's value at q, or +infinity where it is no candidate: beyond max_distance, or on
// the side of a polygon it excludes (the boundary belongs to both sides).
inline double Value(Vec2 q, const Site& s) {
  const double d = Distance(q, s.geometry);
  if (d > s.max_distance) return INFINITY;
  if (auto* poly = std::get_if<PolygonSite>(&s.geometry)) {
    if (poly->side != Side::kBoth && d > 0 &&
        Inside(q, poly->vertices) != (poly->side == Side::kInside)) {
      return INFINITY;
    }
  }
  return static_cast<double>(Real(s.multiplicative) * d + s.additive);
}

struct Best {
  size_t index = 0;
  double value = 0;
  bool found = false;
};

// The best site at q by brute force: least (nearest) or greatest (farthest) finite value.
inline Best BestSite(Vec2 q, std::span<const Site> sites, Diagram diagram = Diagram::kNearest) {
  Best best;
  for (size_t i = 0; i < sites.size(); ++i) {
    const double v = Value(q, sites[i]);
    if (!std::isfinite(v)) continue;
    if (!best.found || (diagram == Diagram::kNearest ? v < best.value : v > best.value)) {
      best = {i, v, true};
    }
  }
  return best;
}

// How far a production distance or value may be from the oracle's: a few units in the last
// place of the larger of the value and the coordinates it came from.
inline double Tolerance(Vec2 q, double value, double weight = 1) {
  const double scale = std::max({1.0, std::abs(value), weight * std::abs(q.x), weight * std::abs(q.y)});
  return 16 * std::numeric_limits<double>::epsilon() * scale;
}

// Distance from q to one named feature of the geometry, or NaN when the geometry has no such
// feature. Vertices: a point's 0; a segment's a = 0, b = 1; a polyline's or polygon's vertex
// i; a Bezier's endpoints by their control-point index. Edges: a segment's 0; edge i of a
// polyline or polygon from vertex i to the next. Curve 0: a Bezier's flattening.
inline double FeatureDistance(Vec2 q, const Geometry& g, FeatureKind kind, uint32_t index) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto at = [&](Vec2 p) { return static_cast<double>(ToSegment(q, p, p)); };
  auto edge = [&](Vec2 a, Vec2 b) { return static_cast<double>(ToSegment(q, a, b)); };
  if (auto* p = std::get_if<PointSite>(&g)) {
    return kind == FeatureKind::kVertex && index == 0 ? at(p->p) : nan;
  }
  if (auto* s = std::get_if<SegmentSite>(&g)) {
    if (kind == FeatureKind::kVertex && index < 2) return at(index == 0 ? s->a : s->b);
    return kind == FeatureKind::kEdge && index == 0 ? edge(s->a, s->b) : nan;
  }
  auto chain = [&](const std::vector<Vec2>& v, bool closed) {
    if (kind == FeatureKind::kVertex && index < v.size()) return at(v[index]);
    const size_t edges = closed ? v.size() : v.size() - 1;
    if (kind == FeatureKind::kEdge && index < edges) return edge(v[index], v[(index + 1) % v.size()]);
    return nan;
  };
  if (auto* l = std::get_if<PolylineSite>(&g)) return chain(l->points, false);
  if (auto* poly = std::get_if<PolygonSite>(&g)) return chain(poly->vertices, true);
  const auto& b = std::get<BezierSite>(g);
  if (kind == FeatureKind::kVertex && (index == 0 || index + 1 == b.control.size())) {
    return at(b.control[index]);
  }
  return kind == FeatureKind::kCurve && index == 0 ? Distance(q, g) : nan;
}

// Whether `closest` is a point of the geometry nearest to q, on the feature (kind, index):
// it lies on that feature, and is as near q as the whole geometry is.
inline bool IsClosestPoint(Vec2 q, const Geometry& g, FeatureKind kind, uint32_t index,
                           Vec2 closest) {
  const double on = FeatureDistance(closest, g, kind, index);
  if (std::isnan(on) || on > Tolerance(closest, 0)) return false;
  const double d = Distance(q, g);
  return std::abs(static_cast<double>(ToSegment(q, closest, closest)) - d) <= Tolerance(q, d);
}

// Whether (kind, index) names a part of the geometry nearest to q: it exists, and it is as
// near as the whole geometry (ties between features: any of them).
inline bool IsNearestFeature(Vec2 q, const Geometry& g, FeatureKind kind, uint32_t index) {
  const double f = FeatureDistance(q, g, kind, index);
  if (std::isnan(f)) return false;
  const double d = Distance(q, g);
  return std::abs(f - d) <= Tolerance(q, d);
}

}  // namespace gvd::oracle
