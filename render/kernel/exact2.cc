#include "render/kernel/exact2.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <utility>

#include "render/kernel/bezier.h"
#include "render/kernel/path2.h"
#include "render/kernel/segment_tree.h"

namespace gvd {

double SegmentDistance(Vec2 q, Vec2 a, Vec2 b, double* t) {
  Vec2 ab = b - a;
  double len2 = glm::dot(ab, ab);
  double u = len2 > 0 ? std::clamp(glm::dot(q - a, ab) / len2, 0.0, 1.0) : 0.0;
  if (t) *t = u;
  if (u == 0) return Distance(q, a);
  if (u == 1) return Distance(q, b);
  return Distance(q, a + u * ab);
}

namespace {

// The least distance from q to the geometry's segments (ForEachSegment: a Bezier's are its
// flattening's).
double SegmentsDistance(Vec2 q, const Geometry& g) {
  double best = INFINITY;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) { best = std::min(best, SegmentDistance(q, a, b)); });
  return best;
}

}  // namespace

double ExactDistance(Vec2 q, const Geometry& g) {
  if (const auto* p = std::get_if<PointSite>(&g)) return Distance(q, p->p);  // the hot path
  if (const auto* b = std::get_if<BezierSite>(&g)) return NearestOnBezier(q, b->control).distance;
  if (const auto* path = std::get_if<PathSite>(&g)) return PathDistance(q, *path);
  return SegmentsDistance(q, g);
}

double DrawnTolerance(const Geometry& g) {
  if (const auto* b = std::get_if<BezierSite>(&g)) return b->tolerance;
  const auto* path = std::get_if<PathSite>(&g);
  if (path == nullptr) return 0.0;
  return (path->curved ? path->tolerance : 0.0) + path->approximation;
}

Side SideOf(const Geometry& g) {
  if (const auto* poly = std::get_if<PolygonSite>(&g)) return poly->side;
  if (const auto* path = std::get_if<PathSite>(&g)) return path->side;
  return Side::kBoth;
}

bool InsideOf(Vec2 q, const Geometry& g) {
  if (const auto* poly = std::get_if<PolygonSite>(&g)) return InsidePolygon(q, poly->vertices);
  if (const auto* path = std::get_if<PathSite>(&g)) return InsidePath(q, *path);
  return false;
}

namespace {

// The ends of segment i of g, in ForEachSegment order.
std::pair<Vec2, Vec2> SegmentAt(const Geometry& g, uint32_t i) {
  if (const auto* p = std::get_if<PointSite>(&g)) return {p->p, p->p};
  if (const auto* s = std::get_if<SegmentSite>(&g)) return {s->a, s->b};
  if (const auto* l = std::get_if<PolylineSite>(&g)) return {l->points[i], l->points[i + 1]};
  if (const auto* poly = std::get_if<PolygonSite>(&g)) {
    const auto& v = poly->vertices;
    return {v[i], v[(i + 1) % v.size()]};
  }
  if (const auto* path = std::get_if<PathSite>(&g)) {  // of lines only: segment i is piece i
    return {path->pieces[i].control[0], path->pieces[i].control[1]};
  }
  const auto& flat = std::get<BezierSite>(g).flat;
  return {flat[i], flat[i + 1]};
}

// The feature of g that segment i (in ForEachSegment order) at parameter t is, at distance d.
FeatureHit FeatureOf(const Geometry& g, double d, uint32_t i, double t) {
  const auto [a, b] = SegmentAt(g, i);
  FeatureHit best = t == 0   ? FeatureHit{d, FeatureKind::kVertex, i, a}
                    : t == 1 ? FeatureHit{d, FeatureKind::kVertex, i + 1, b}
                             : FeatureHit{d, FeatureKind::kEdge, i, a + t * (b - a)};
  if (const auto* poly = std::get_if<PolygonSite>(&g)) {
    if (best.kind == FeatureKind::kVertex) best.index %= poly->vertices.size();
  } else if (const auto* path = std::get_if<PathSite>(&g)) {
    if (best.kind == FeatureKind::kVertex) {
      best.index = t == 0 ? path->pieces[i].first_joint : path->pieces[i].last_joint;
    }
  } else if (const auto* bez = std::get_if<BezierSite>(&g)) {
    uint32_t last = static_cast<uint32_t>(bez->flat.size() - 1);
    if (best.kind == FeatureKind::kVertex && best.index == 0) {
      best.index = 0;
    } else if (best.kind == FeatureKind::kVertex && best.index == last) {
      best.index = static_cast<uint32_t>(bez->control.size() - 1);
    } else {
      best.kind = FeatureKind::kCurve;
      best.index = 0;
    }
  }
  return best;
}

}  // namespace

FeatureHit NearestFeature(Vec2 q, const Geometry& g) {
  if (const auto* b = std::get_if<BezierSite>(&g)) {
    const CurvePoint c = NearestOnBezier(q, b->control);
    if (c.t == 0) return {c.distance, FeatureKind::kVertex, 0, c.point};
    if (c.t == 1) {
      return {c.distance, FeatureKind::kVertex, static_cast<uint32_t>(b->control.size() - 1),
              c.point};
    }
    return {c.distance, FeatureKind::kCurve, 0, c.point};
  }
  if (const auto* path = std::get_if<PathSite>(&g)) return PathNearestFeature(q, *path);
  double best = INFINITY, best_t = 0;
  uint32_t i = 0, best_i = 0;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) {
    double t = 0;
    double d = SegmentDistance(q, a, b, &t);
    if (d < best) {
      best = d;
      best_i = i;
      best_t = t;
    }
    ++i;
  });
  return FeatureOf(g, best, best_i, best_t);
}

namespace {

// Whether the segments of the site's tree are its geometry (not a curve's drawn polylines).
bool TreeIsExact(const Site& site) {
  if (site.segment_tree == nullptr || std::holds_alternative<BezierSite>(site.geometry)) {
    return false;
  }
  const auto* path = std::get_if<PathSite>(&site.geometry);
  return path == nullptr || !path->curved;
}

}  // namespace

// The segment tree of a Bezier or of a path with curves holds their drawn polylines; their
// distances are the curves'.
FeatureHit NearestFeature(Vec2 q, const Site& site) {
  if (!TreeIsExact(site)) return NearestFeature(q, site.geometry);
  const SegmentTree::Hit hit = site.segment_tree->Nearest(q);
  return FeatureOf(site.geometry, hit.distance, hit.index, hit.t);
}

double ExactDistance(Vec2 q, const Site& site) {
  return TreeIsExact(site) ? site.segment_tree->Nearest(q).distance
                           : ExactDistance(q, site.geometry);
}

double DrawnDistance(Vec2 q, const Site& site) {
  if (DrawnTolerance(site.geometry) == 0) return ExactDistance(q, site);
  return site.segment_tree ? site.segment_tree->Nearest(q).distance
                           : SegmentsDistance(q, site.geometry);
}

double FarthestDistance(const Window& rect, const Site& site) {
  if (site.segment_tree == nullptr) return FarthestDistance(rect, site.geometry);
  // A curve's drawn polyline is within its tolerance of it.
  return site.segment_tree->Farthest(rect) + DrawnTolerance(site.geometry);
}

bool InsidePolygon(Vec2 q, const std::vector<Vec2>& v) {
  bool inside = false;
  for (size_t i = 0, j = v.size() - 1; i < v.size(); j = i++) {
    if ((v[i].y > q.y) != (v[j].y > q.y)) {
      double x = v[i].x + (q.y - v[i].y) / (v[j].y - v[i].y) * (v[j].x - v[i].x);
      if (q.x < x) inside = !inside;
    }
  }
  return inside;
}

double SiteValue(Vec2 q, const Site& site) { return SiteValueAt(q, site, ExactDistance(q, site)); }

double SiteValueAt(Vec2 q, const Site& site, double d) {
  if (d > site.max_distance) return INFINITY;
  const Side side = SideOf(site.geometry);
  if (side != Side::kBoth && d > 0 && InsideOf(q, site.geometry) != (side == Side::kInside)) {
    return INFINITY;
  }
  return site.multiplicative * d + site.additive;
}

double FlattenBound(const std::vector<Vec2>& control) {
  const double deg = static_cast<double>(control.size() - 1);
  double m = 0;
  for (size_t i = 0; i + 2 < control.size(); ++i) {
    m = std::max(m, Length(control[i + 2] - 2.0 * control[i + 1] + control[i]));
  }
  return deg * (deg - 1) / 8 * m;
}

std::vector<Vec2> Flatten(const std::vector<Vec2>& control, double tolerance) {
  assert(control.size() == 3 || control.size() == 4);
  assert(tolerance > 0);
  double n = std::ceil(std::sqrt(FlattenBound(control) / tolerance));
  uint32_t pieces = !(n >= 1) ? 1 : n >= kMaxBezierPieces ? kMaxBezierPieces : uint32_t(n);
  std::vector<Vec2> flat(pieces + 1);
  for (uint32_t i = 0; i <= pieces; ++i) flat[i] = BezierPoint(control, double(i) / pieces);
  flat.front() = control.front();  // exactly
  flat.back() = control.back();
  return flat;
}

BezierSite MakeBezier(std::vector<Vec2> control, double tolerance) {
  if (!(tolerance > 0)) {
    // A thousandth of the control polygon's length, summed piece by piece: a huge curve's
    // polygon may be longer than a double holds while each of its pieces is not.
    double thousandth = 0;
    for (size_t i = 0; i + 1 < control.size(); ++i) thousandth += Distance(control[i], control[i + 1]) / 1000;
    tolerance = thousandth > 0 ? thousandth : 1e-9;
  }
  // Past kMaxBezierPieces the bound says how far the flattening may stray: state that.
  tolerance = std::max(tolerance, FlattenBound(control) / (double(kMaxBezierPieces) * kMaxBezierPieces));
  BezierSite b;
  b.flat = Flatten(control, tolerance);
  b.control = std::move(control);
  b.tolerance = tolerance;
  return b;
}

double TotalLength(const Geometry& g) {
  double length = 0;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) { length += Distance(a, b); });
  return length;
}

Window BoundingBox(const Geometry& g) {
  if (const auto* path = std::get_if<PathSite>(&g)) return PathBox(*path);
  Window w{INFINITY, INFINITY, -INFINITY, -INFINITY};
  auto add = [&](Vec2 p) {
    w.min_x = std::min(w.min_x, p.x);
    w.min_y = std::min(w.min_y, p.y);
    w.max_x = std::max(w.max_x, p.x);
    w.max_y = std::max(w.max_y, p.y);
  };
  ForEachSegment(g, [&](Vec2 a, Vec2 b) {
    add(a);
    add(b);
  });
  // The curve strays from its flattening by up to the tolerance.
  if (const auto* b = std::get_if<BezierSite>(&g)) {
    w = {w.min_x - b->tolerance, w.min_y - b->tolerance, w.max_x + b->tolerance,
         w.max_y + b->tolerance};
  }
  return w;
}

double FarthestDistance(const Window& rect, const Geometry& g) {
  if (const auto* p = std::get_if<PointSite>(&g)) return rect.FarthestDistance(p->p);
  if (const auto* path = std::get_if<PathSite>(&g)) return PathFarthestDistance(rect, *path);
  // d(., g) <= d(., s) for each segment s, and d(., s) is convex (s is convex), so its
  // maximum over the rectangle is at a corner.
  const Vec2 corners[4] = {{rect.min_x, rect.min_y}, {rect.max_x, rect.min_y},
                           {rect.min_x, rect.max_y}, {rect.max_x, rect.max_y}};
  double best = INFINITY;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) {
    double m = 0;
    for (Vec2 c : corners) m = std::max(m, SegmentDistance(c, a, b));
    best = std::min(best, m);
  });
  // A Bezier's segments are its flattening's, within its tolerance of the curve.
  if (const auto* b = std::get_if<BezierSite>(&g)) best += b->tolerance;
  return best;
}

}  // namespace gvd
