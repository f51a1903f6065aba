// A path: one object of lines and curves (an SVG <path>, a glyph's outline, a polygon with
// holes, a rounded rectangle) as one site. It is one or more subpaths, each a chain of
// pieces (lines, quadratic and cubic Beziers), open or closed; closed subpaths together bound
// an inside, by the even-odd or the nonzero rule (SVG's fill-rule), and `side` restricts the
// site to points outside or inside it as a polygon's does.
//
// Distances are to the true pieces (curves through NearestOnBezier, bezier.h); the inside is
// the true curves' too, to within the rounding of their control points: a ray's crossings of
// a curve are counted on pieces split until each is monotone in y and to one side of the
// point (or, after 48 splits, by its chord, some 2^-48 of the curve long).
//
// Features, as NearestSite names them: the pieces are numbered across the path, subpath
// after subpath, from 0, and piece k is EDGE k (a line) or CURVE k (a curve); the joints are
// numbered likewise, a subpath's start first, and VERTEX j is joint j. A closed subpath of m
// pieces has m joints (its last piece ends at its start), an open one m + 1. So in a path of
// an open subpath of 2 pieces then a closed one of 3, pieces 0-1 and joints 0-2 are the
// first subpath's, pieces 2-4 and joints 3-5 the second's.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "render/kernel/exact2.h"

namespace gvd {

enum class FillRule : uint8_t { kNonZero, kEvenOdd };

// A subpath as given: its start, then each piece's points after the previous piece's end
// (1 for a line, 2 for a quadratic, 3 for a cubic), as `degrees` says.
struct Subpath {
  std::vector<Vec2> points;
  std::vector<uint8_t> degrees;
  // Closed: its last piece ends at its start. MakePath adds a line back to the start where
  // the last point is elsewhere (as SVG's Z does); that line is then its last piece.
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

struct PathSite {
  std::vector<Subpath> subpaths;
  FillRule fill = FillRule::kNonZero;
  Side side = Side::kBoth;
  // How far the drawn polylines of the curves may stray from them (as a Bezier's).
  double tolerance = 0;
  // Derived by MakePath: the pieces in feature order, and the polyline drawn for each (a
  // line's two ends, a curve's flattening), piece after piece.
  std::vector<PathPiece> pieces;
  std::vector<Vec2> flat;
  uint32_t joints = 0;
};

// A path site from its subpaths. tolerance 0 means a thousandth of the control polygons'
// length (or 1e-9 if that is 0); a tolerance finer than a curve's flattening can reach
// (Flatten's kMaxBezierPieces) is widened to the coarsest that any of them needs.
// CONTRACT: at least one subpath; each has at least one piece, and as many points as its
// degrees (each 1, 2 or 3) take after its start; every point finite.
PathSite MakePath(std::vector<Subpath> subpaths, FillRule fill, Side side, double tolerance);

// The segments of piece k's drawn polyline: calls f(a, b) for each.
template <class F>
void ForEachPieceSegment(const PathSite& path, uint32_t k, F&& f) {
  const uint32_t end = k + 1 < path.pieces.size() ? path.pieces[k + 1].flat_begin
                                                  : static_cast<uint32_t>(path.flat.size());
  for (uint32_t i = path.pieces[k].flat_begin; i + 1 < end; ++i) f(path.flat[i], path.flat[i + 1]);
}

// The distance from q to the path (its pieces, whatever its side), and its nearest feature
// (ties: the first in feature order).
double PathDistance(Vec2 q, const PathSite& path);
FeatureHit PathNearestFeature(Vec2 q, const PathSite& path);

// The winding number of the path's closed subpaths around q (counter-clockwise positive, in
// axes with y up), and whether q is inside by the path's fill rule.
int PathWinding(Vec2 q, const PathSite& path);
bool InsidePath(Vec2 q, const PathSite& path);

// The smallest axis-aligned rectangle holding the pieces' control points (so the path).
Window PathBox(const PathSite& path);

// An upper bound on the distance from the path to any point of the rectangle.
double PathFarthestDistance(const Window& rect, const PathSite& path);

}  // namespace gvd
