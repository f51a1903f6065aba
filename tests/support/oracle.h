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
// (No hypot: the squares of differences of doubles neither overflow nor underflow in Real.)
inline Real ToSegment(Vec2 q, Vec2 a, Vec2 b, Real* t_out = nullptr) {
  const Real dx = Real(b.x) - a.x, dy = Real(b.y) - a.y;
  const Real len2 = dx * dx + dy * dy;
  Real t = 0;
  if (len2 > 0) t = std::clamp(((Real(q.x) - a.x) * dx + (Real(q.y) - a.y) * dy) / len2, Real(0), Real(1));
  if (t_out) *t_out = t;
  const Real ex = Real(q.x) - (a.x + t * dx), ey = Real(q.y) - (a.y + t * dy);
  return std::sqrt(ex * ex + ey * ey);
}

// Calls f(a, b) for each segment of a geometry in feature order. A point is one degenerate
// segment; a polygon closes; a Bezier's are its flattening's, a path's its pieces' drawn
// polylines (what the rasterizer draws; their distances are the curves': CurveDistance).
template <typename F>
void EachSegment(const Geometry& g, F&& f) {
  auto chain = [&f](const std::vector<Vec2>& v, bool closed) {
    for (size_t i = 0; i + 1 < v.size(); ++i) f(v[i], v[i + 1]);
    if (closed && v.size() > 1) f(v.back(), v.front());
  };
  if (auto* p = std::get_if<PointSite>(&g)) f(p->p, p->p);
  if (auto* s = std::get_if<SegmentSite>(&g)) f(s->a, s->b);
  if (auto* l = std::get_if<PolylineSite>(&g)) chain(l->points, false);
  if (auto* poly = std::get_if<PolygonSite>(&g)) chain(poly->vertices, true);
  if (auto* b = std::get_if<BezierSite>(&g)) chain(b->flat, false);
  if (auto* path = std::get_if<PathSite>(&g)) {
    for (size_t k = 0; k < path->pieces.size(); ++k) {
      const size_t end = k + 1 < path->pieces.size() ? path->pieces[k + 1].flat_begin : path->flat.size();
      for (size_t i = path->pieces[k].flat_begin; i + 1 < end; ++i) f(path->flat[i], path->flat[i + 1]);
    }
  }
}

// The segments of a geometry in feature order (EachSegment): (a, b).
inline std::vector<std::pair<Vec2, Vec2>> Segments(const Geometry& g) {
  std::vector<std::pair<Vec2, Vec2>> out;
  EachSegment(g, [&out](Vec2 a, Vec2 b) { out.push_back({a, b}); });
  return out;
}

// Distance from q to the geometry as the rasterizer draws it: a Bezier's flattening.
inline double DrawnDistance(Vec2 q, const Geometry& g) {
  Real best = std::numeric_limits<Real>::infinity();
  EachSegment(g, [&](Vec2 a, Vec2 b) { best = std::min(best, ToSegment(q, a, b)); });
  return static_cast<double>(best);
}

// The Bezier curve (3 or 4 control points) at t: its Bernstein polynomials written out.
inline void CurveAt(std::span<const Vec2> c, Real t, Real* x, Real* y) {
  const Real s = 1 - t;
  const Real w3[3] = {s * s, 2 * s * t, t * t};
  const Real w4[4] = {s * s * s, 3 * s * s * t, 3 * s * t * t, t * t * t};
  const Real* w = c.size() == 3 ? w3 : w4;
  *x = *y = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    *x += w[i] * c[i].x;
    *y += w[i] * c[i].y;
  }
}

// Distance from q to the true curve, and the parameter of a nearest point: its least over the
// ends, the roots of the derivative of the squared distance (found by bisection between the
// signs it takes at 1,024 even steps) and the least of the squared distance near each
// sampled local minimum (golden-section search over the two steps around it).
inline Real CurveDistance(Vec2 q, std::span<const Vec2> c, Real* t_out = nullptr) {
  // B - q in the power basis, a[0] + a[1] t + ... (the Bernstein form expanded: for a
  // cubic, P0 - q, 3 (P1 - P0), 3 (P2 - 2 P1 + P0), P3 - 3 P2 + 3 P1 - P0).
  Real ax[4] = {0, 0, 0, 0}, ay[4] = {0, 0, 0, 0};
  const size_t n = c.size() - 1;
  for (size_t i = 0; i <= n; ++i) {
    // The coefficient of t^j in binomial(n, i) t^i (1 - t)^(n - i): binomial(n, j)
    // binomial(j, i) (-1)^(j - i), for j >= i.
    static constexpr int kBinomial[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
    for (size_t j = i; j <= n; ++j) {
      const Real k = kBinomial[n][j] * kBinomial[j][i] * ((j - i) % 2 ? -1 : 1);
      ax[j] += k * c[i].x;
      ay[j] += k * c[i].y;
    }
  }
  ax[0] -= q.x;
  ay[0] -= q.y;
  // The squared distance from q at t, and half its derivative: (B - q) . B' (Horner's rule;
  // a quadratic's a[3] is 0, which adds exact zeros).
  auto measure = [x0 = ax[0], x1 = ax[1], x2 = ax[2], x3 = ax[3], y0 = ay[0], y1 = ay[1],
                  y2 = ay[2], y3 = ay[3], dx2 = 2 * ax[2], dx3 = 3 * ax[3], dy2 = 2 * ay[2],
                  dy3 = 3 * ay[3]](Real t, Real* slope) {
    const Real x = ((x3 * t + x2) * t + x1) * t + x0, y = ((y3 * t + y2) * t + y1) * t + y0;
    if (slope) *slope = x * ((dx3 * t + dx2) * t + x1) + y * ((dy3 * t + dy2) * t + y1);
    return x * x + y * y;
  };
  auto squared = [&](Real t) { return measure(t, nullptr); };
  auto slope = [&](Real t) {
    Real v;
    measure(t, &v);
    return v;
  };
  constexpr int kSteps = 1024;
  Real best_t = 0, best = squared(0);
  auto consider = [&](Real t) {
    const Real v = squared(t);
    if (v < best) {
      best = v;
      best_t = t;
    }
  };
  consider(1);
  // The squared distance g and the slope f at steps k - 1, k and k + 1.
  Real g_before = 0, f_here, f_next;
  Real g_here = measure(0, &f_here);
  for (int k = 0; k < kSteps; ++k) {
    const Real g_next = measure(Real(k + 1) / kSteps, &f_next);
    if (f_here < 0 && f_next >= 0) {
      Real lo = Real(k) / kSteps, hi = Real(k + 1) / kSteps;
      for (int i = 0; i < 100; ++i) {
        const Real mid = (lo + hi) / 2;
        if (mid == lo || mid == hi) break;  // as close as Real can tell
        (slope(mid) < 0 ? lo : hi) = mid;
      }
      consider(lo);
      consider(hi);
    }
    if (k > 0 && g_here <= g_before && g_here <= g_next) {
      const Real ratio = (std::sqrt(Real(5)) - 1) / 2;
      Real lo = Real(k - 1) / kSteps, hi = Real(k + 1) / kSteps;
      for (int i = 0; i < 120; ++i) {
        const Real a = hi - ratio * (hi - lo), b = lo + ratio * (hi - lo);
        if (!(a < b)) break;
        if (squared(a) < squared(b)) {
          hi = b;
        } else {
          lo = a;
        }
      }
      consider(lo);
      consider(hi);
    }
    g_before = g_here, g_here = g_next, f_here = f_next;
  }
  if (t_out) *t_out = best_t;
  return std::sqrt(best);
}

// The box of some points, and its distance from q.
struct Box {
  Real lo_x = std::numeric_limits<Real>::infinity(), hi_x = -lo_x, lo_y = lo_x, hi_y = -lo_x;
  void Add(std::span<const Vec2> points) {
    for (Vec2 p : points) {
      lo_x = std::min<Real>(lo_x, p.x), hi_x = std::max<Real>(hi_x, p.x);
      lo_y = std::min<Real>(lo_y, p.y), hi_y = std::max<Real>(hi_y, p.y);
    }
  }
  Real Distance(Vec2 q) const {
    const Real dx = std::max<Real>({lo_x - q.x, Real(q.x) - hi_x, 0});
    const Real dy = std::max<Real>({lo_y - q.y, Real(q.y) - hi_y, 0});
    return std::sqrt(dx * dx + dy * dy);
  }
};

// A path's piece as given: its control points.
inline std::span<const Vec2> PieceControl(const PathPiece& p) { return {p.control.data(), p.degree + 1u}; }
inline Real PieceDistance(Vec2 q, const PathPiece& p) {
  return p.degree == 1 ? ToSegment(q, p.control[0], p.control[1]) : CurveDistance(q, PieceControl(p));
}

// Euclidean distance from q to the geometry (a polygon's boundary, whatever its side; a
// Bezier's true curve; a path's true pieces).
inline double Distance(Vec2 q, const Geometry& g) {
  if (auto* b = std::get_if<BezierSite>(&g)) return static_cast<double>(CurveDistance(q, b->control));
  if (auto* path = std::get_if<PathSite>(&g)) {
    // A piece lies within its control points' box: one whose box is farther than the best
    // distance found cannot be nearer. Taken nearest box first, that spares most curves.
    std::vector<std::pair<Real, size_t>> order;
    for (size_t k = 0; k < path->pieces.size(); ++k) {
      Box box;
      box.Add(PieceControl(path->pieces[k]));
      order.push_back({box.Distance(q), k});
    }
    std::sort(order.begin(), order.end());
    Real best = std::numeric_limits<Real>::infinity();
    for (const auto& [box, k] : order) {
      if (box > best) break;
      best = std::min(best, PieceDistance(q, path->pieces[k]));
    }
    return static_cast<double>(best);
  }
  return DrawnDistance(q, g);
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

// Whether q is inside a path: the winding number of its closed subpaths' drawn polylines
// (the API's Path: the inside is theirs), counted along a ray towards +x, by its fill rule.
inline bool InsidePath(Vec2 q, const PathSite& path) {
  int winding = 0;
  for (size_t k = 0; k < path.pieces.size(); ++k) {
    if (!path.pieces[k].closed) continue;
    const size_t end = k + 1 < path.pieces.size() ? path.pieces[k + 1].flat_begin : path.flat.size();
    for (size_t i = path.pieces[k].flat_begin; i + 1 < end; ++i) {
      const Vec2 a = path.flat[i], b = path.flat[i + 1];
      if ((a.y > q.y) == (b.y > q.y)) continue;
      const Real x = Real(a.x) + (Real(q.y) - a.y) * (Real(b.x) - a.x) / (Real(b.y) - a.y);
      if (Real(q.x) < x) winding += b.y > a.y ? 1 : -1;
    }
  }
  return path.fill == FillRule::kEvenOdd ? winding % 2 != 0 : winding != 0;
}

// The side a polygon or path is restricted to, and whether q is inside it.
inline Side SideOf(const Geometry& g) {
  if (auto* poly = std::get_if<PolygonSite>(&g)) return poly->side;
  if (auto* path = std::get_if<PathSite>(&g)) return path->side;
  return Side::kBoth;
}
inline bool InsideOf(Vec2 q, const Geometry& g) {
  if (auto* poly = std::get_if<PolygonSite>(&g)) return Inside(q, poly->vertices);
  if (auto* path = std::get_if<PathSite>(&g)) return oracle::InsidePath(q, *path);
  return false;
}

// The site's value at q, or +infinity where it is no candidate: beyond max_distance, or on
// the side of a polygon or path it excludes (the boundary belongs to both sides). drawn: of
// the geometry as the rasterizer draws it (DrawnDistance), for what a raster shows.
inline double Value(Vec2 q, const Site& s, bool drawn = false) {
  const double d = drawn ? DrawnDistance(q, s.geometry) : Distance(q, s.geometry);
  if (d > s.max_distance) return INFINITY;
  const Side side = oracle::SideOf(s.geometry);
  if (side != Side::kBoth && d > 0 && oracle::InsideOf(q, s.geometry) != (side == Side::kInside)) {
    return INFINITY;
  }
  return static_cast<double>(Real(s.multiplicative) * d + s.additive);
}

struct Best {
  size_t index = 0;
  double value = 0;
  bool found = false;
};

// The best site at q by brute force: least (nearest) or greatest (farthest) finite value
// (drawn: of the geometry as drawn, as Value).
inline Best BestSite(Vec2 q, std::span<const Site> sites, Diagram diagram = Diagram::kNearest,
                     bool drawn = false) {
  Best best;
  auto consider = [&](size_t i) {
    const double v = Value(q, sites[i], drawn);
    if (!std::isfinite(v)) return;
    // Ties: the lowest index, whatever the order sites are taken in.
    if (!best.found || (diagram == Diagram::kNearest ? v < best.value : v > best.value) ||
        (v == best.value && i < best.index)) {
      best = {i, v, true};
    }
  };
  // A curve lies within its control points' box: one whose box is farther than the best value
  // found cannot beat it. Curves taken last, nearest box first, that spares measuring most.
  std::vector<std::pair<Real, size_t>> curves;
  for (size_t i = 0; i < sites.size(); ++i) {
    const auto* b = std::get_if<BezierSite>(&sites[i].geometry);
    const auto* path = std::get_if<PathSite>(&sites[i].geometry);
    if (!(b || path) || drawn) {
      consider(i);
      continue;
    }
    Box box;
    if (b) box.Add(b->control);
    if (path) {
      for (const PathPiece& p : path->pieces) box.Add(PieceControl(p));
    }
    // And one whose box is beyond its max_distance is no candidate at all.
    const Real distance = box.Distance(q);
    if (distance > sites[i].max_distance) continue;
    curves.push_back({diagram == Diagram::kNearest ? sites[i].multiplicative * distance + sites[i].additive : -1, i});
  }
  std::stable_sort(curves.begin(), curves.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [bound, i] : curves) {
    if (bound >= 0 && best.found && bound > best.value) break;
    consider(i);
  }
  return best;
}

// How far a production distance or value may be from the oracle's: a few units in the last
// place of the larger of the value and the coordinates it came from.
inline double Tolerance(Vec2 q, double value, double weight = 1) {
  const double scale = std::max({1.0, std::abs(value), weight * std::abs(q.x), weight * std::abs(q.y)});
  return 16 * std::numeric_limits<double>::epsilon() * scale;
}

// How far the service's measure of a site's value may be from the oracle's beyond Tolerance:
// the API's limit on the rounding of measuring a curve (Bezier in the API: 2^-41 of the
// value and the curve's largest |control point|, times its weight), 0 for other kinds.
inline double CurveRounding(double value, const Site& s) {
  double extent = 0;
  bool curved = false;
  if (const auto* b = std::get_if<BezierSite>(&s.geometry)) {
    curved = true;
    for (Vec2 p : b->control) extent = std::max(extent, std::hypot(p.x, p.y));
  } else if (const auto* path = std::get_if<PathSite>(&s.geometry)) {
    for (const PathPiece& piece : path->pieces) {
      if (piece.degree == 1) continue;
      curved = true;
      for (Vec2 p : PieceControl(piece)) extent = std::max(extent, std::hypot(p.x, p.y));
    }
  }
  return curved ? 0x1p-41 * (std::abs(value) + s.multiplicative * extent) : 0;
}

// Distance from q to one named feature of the geometry, or NaN when the geometry has no such
// feature. Vertices: a point's 0; a segment's a = 0, b = 1; a polyline's or polygon's vertex
// i; a Bezier's endpoints by their control-point index; a path's joints. Edges: a segment's
// 0; edge i of a polyline or polygon from vertex i to the next; a path's line pieces. Curves:
// a Bezier's 0; a path's curve pieces.
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
  if (auto* path = std::get_if<PathSite>(&g)) {
    // Joints as the API's Path numbers them, from the subpaths as given: each piece's
    // start, and an open subpath's end; pieces in order.
    std::vector<Vec2> joints;
    for (const Subpath& sub : path->subpaths) {
      size_t at = 0;
      for (uint8_t d : sub.degrees) {
        joints.push_back(sub.points[at]);
        at += d;
      }
      if (!sub.closed) joints.push_back(sub.points[at]);
    }
    if (kind == FeatureKind::kVertex) return index < joints.size() ? at(joints[index]) : nan;
    if (index >= path->pieces.size()) return nan;
    const PathPiece& piece = path->pieces[index];
    if (kind != (piece.degree == 1 ? FeatureKind::kEdge : FeatureKind::kCurve)) return nan;
    return static_cast<double>(PieceDistance(q, piece));
  }
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
