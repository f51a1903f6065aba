// The 2D kernel's sites: an id, a geometry of one of the plane's kinds, weights and a reach.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "render/kernel/grid2.h"

namespace gvd {

struct PointSite {
  Vec2 p;
};

// A closed segment; a == b is allowed (it is then a point).
struct SegmentSite {
  Vec2 a, b;
};

// An open chain of segments through `points` (at least two; repeats allowed).
struct PolylineSite {
  std::vector<Vec2> points;
};

// Where a polygon's distance function is defined (paper sec. 4.3).
enum class Side : uint8_t { kBoth, kOutside, kInside };

// A closed chain: edge i runs from vertex i to vertex i + 1 (mod n); at least three
// vertices, repeats allowed. Its distance is the distance to that boundary. Inside and
// outside follow the even-odd rule, so a self-intersecting polygon is well defined; one of
// zero area has no inside. With kOutside (kInside) the polygon is a candidate only at points
// outside (inside) it, or on its boundary.
struct PolygonSite {
  std::vector<Vec2> vertices;
  Side side = Side::kBoth;
};

// A quadratic (3 control points) or cubic (4) Bezier curve. Its distances are the curve's
// own (NearestOnBezier, bezier.h); the rasterizer draws `flat`, a polyline through points of
// the curve within `tolerance` of it (Flatten in exact2.h).
struct BezierSite {
  std::vector<Vec2> control;
  double tolerance = 0;
  std::vector<Vec2> flat;
};

// How closed outlines bound an inside (SVG's fill-rule): a point is inside where their
// winding number around it is not 0, or is odd.
enum class FillRule : uint8_t { kNonZero, kEvenOdd };

// A path's subpath as given: its start, then each piece's points after the previous piece's
// end (1 for a line, 2 for a quadratic, 3 for a cubic), as `degrees` says.
struct Subpath {
  std::vector<Vec2> points;
  std::vector<uint8_t> degrees;
  // Closed: its last piece ends at its start. MakePath (path2.h) adds a line back to the
  // start where the last point is elsewhere (as SVG's Z does); that line is then its last
  // piece.
  bool closed = false;
};

// One piece of a path: degree + 1 control points (a line's are its ends).
struct PathPiece {
  std::array<Vec2, 4> control;
  uint8_t degree = 1;
  uint32_t first_joint = 0, last_joint = 0;  // the joints it starts and ends at
  uint32_t flat_begin = 0;  // its polyline in PathSite::flat: flat_begin .. next's - 1
  bool closed = false;      // of a closed subpath
};

// One object of lines and curves (an SVG <path>, a glyph's outline, a polygon with holes)
// as one site: path2.h says what it is and how its features are numbered; MakePath builds
// one. Its closed subpaths' drawn polylines bound an inside, by its fill rule; with kOutside
// (kInside) it is a candidate only outside (inside) it, or on its outline. A path with a
// side has only closed subpaths.
struct PathSite {
  std::vector<Subpath> subpaths;
  FillRule fill = FillRule::kNonZero;
  Side side = Side::kBoth;
  // How far the drawn polylines of the curves may stray from them (as a Bezier's).
  double tolerance = 0;
  // How far the pieces may be from the shape they stand for (an arc or ellipse written as
  // cubics, say): finite, 0 or more, given with the path and added to every bound of its
  // distances (DrawnTolerance, K::ShapeError). MakePath leaves it 0.
  double approximation = 0;
  // Derived by MakePath: the pieces in feature order, and the polyline drawn for each (a
  // line's two ends, a curve's flattening), piece after piece.
  std::vector<PathPiece> pieces;
  std::vector<Vec2> flat;
  uint32_t joints = 0;
  bool curved = false;  // whether a piece is a curve
};

// Every site kind; new kinds are added here, in exact2.cc and in the rasterizer's primitives.
using Geometry =
    std::variant<PointSite, SegmentSite, PolylineSite, PolygonSite, BezierSite, PathSite>;

// What a site's part nearest to a point is (NearestSite.feature_kind in the API); faces are
// the 3D kernel's (site3.h).
enum class FeatureKind : uint8_t { kVertex, kEdge, kCurve, kFace };

class SegmentTree;  // render/kernel/segment_tree.h

struct Site {
  std::string id;
  Geometry geometry;
  // The site's value at q is multiplicative * d + additive, d the Euclidean distance from q
  // to the geometry (paper sec. 4.4); beyond max_distance (in d) the site has no influence.
  // CONTRACT: additive >= 0 and multiplicative > 0, both finite; max_distance > 0.
  double additive = 0;
  double multiplicative = 1;
  double max_distance = INFINITY;
  // The geometry's segments in a tree, for sites of many segments (IndexSegments, which the
  // slot table calls as a site enters it); null otherwise. The exact functions taking a Site
  // (exact2.h) use it: it changes how fast they find a value, never the value.
  std::shared_ptr<const SegmentTree> segment_tree;

  bool weighted() const { return additive != 0 || multiplicative != 1; }
  // Whether the site is a candidate everywhere at its plain distance: unweighted, unbounded
  // and not restricted to a side.
  bool plain() const;
};

// A densely indexed list of sites; the id buffer holds index + 1.
using SiteTable = std::vector<Site>;

}  // namespace gvd
