// A path: one object of lines and curves (an SVG <path>, a glyph's outline, a polygon with
// holes, a rounded rectangle) as one site (PathSite, site2.h). It is one or more subpaths,
// each a chain of pieces (lines, quadratic and cubic Beziers), open or closed; closed
// subpaths together bound an inside, by the even-odd or the nonzero rule (SVG's fill-rule),
// and `side` restricts the site to points outside or inside it as a polygon's does.
//
// Distances are to the true pieces (curves through NearestOnBezier, bezier.h). The inside is
// bounded by the drawn outline, the curves' polylines, which the rasterizer tests as well:
// the true curves' inside but within `tolerance` of a curve, where a point may fall on
// either side.
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
#include <string>
#include <vector>

#include "render/kernel/exact2.h"

namespace gvd {

// Why the subpaths break MakePath's contract (with `side`, whose restriction needs closed
// subpaths), naming the subpath and what is wrong, relative to the path; empty when they
// keep it.
std::string PathContractError(const std::vector<Subpath>& subpaths, Side side);

// A path site from its subpaths. tolerance 0 means a thousandth of the control polygons'
// length (or 1e-9 if that is 0); a tolerance finer than a curve's flattening can reach
// (Flatten's kMaxBezierPieces) is widened to the coarsest that any of them needs, and one
// that would draw more than max_points points (two a line, a curve's pieces and one) to
// one that draws no more.
// CONTRACT: at least one subpath; each has at least one piece, and as many points as its
// degrees (each 1, 2 or 3) take after its start; every point finite; closed where `side` is
// not kBoth (PathContractError says which); max_points more than 2 a line and 3 a curve.
PathSite MakePath(std::vector<Subpath> subpaths, FillRule fill, Side side, double tolerance,
                  size_t max_points = SIZE_MAX);

// The segments of piece k's drawn polyline: calls f(a, b) for each. Piece after piece, they
// are the path's ForEachSegment (exact2.h); piece k's first is segment
// path.pieces[k].flat_begin - k there.
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

// The winding number of the path's closed subpaths' drawn outline around q
// (counter-clockwise positive, in axes with y up), and whether q is inside by the path's fill
// rule.
int PathWinding(Vec2 q, const PathSite& path);
bool InsidePath(Vec2 q, const PathSite& path);

// The smallest axis-aligned rectangle holding the pieces' control points (so the path).
Window PathBox(const PathSite& path);

// An upper bound on the distance from the path to any point of the rectangle.
double PathFarthestDistance(const Window& rect, const PathSite& path);

}  // namespace gvd
