// The point of a quadratic or cubic Bezier curve nearest to a point, exact to the curve up to
// a proven rounding error (not to a flattening of it).
//
// The distance's minimum over the curve is at an end or at a root of the derivative
// polynomial f(t) = (B(t) - q) . B'(t), a cubic for a quadratic curve and a quintic for a
// cubic one. Its roots are isolated by subdividing the curve at parameter 1/2 and reading the
// signs of f's Bernstein coefficients on each piece (Descartes' rule of signs in the Bernstein
// basis): a piece whose coefficients all have one sign holds no root, and its least distance
// is at an end; a piece with a single change of sign from + to - holds one root, a maximum
// of the distance, and its least distance is at an end too; a piece with a single change
// from - to + holds exactly one root, the minimum, which Newton's method finds within a
// bracket whose ends keep certain signs. Other pieces are split further. Each piece also has
// a lower bound on its distance from its control points (the curve lies within the largest
// distance of its inner control points from the chord, so its distance is at least the
// chord's less that), and pieces whose bound exceeds the best distance found are dropped;
// a piece whose bounds meet within 64 ulps needs no more splitting. A coefficient or value
// of f within its rounding error counts as of either sign, so no root is lost to rounding.
#pragma once

#include <vector>

#include "render/kernel/vec.h"

namespace gvd {

struct CurvePoint {
  double t = 0;      // the curve's parameter there, in [0, 1]: 0 and 1 are its ends
  Vec2 point;        // B(t), evaluated by de Casteljau from the control points
  double distance = 0;  // Distance(q, point)
};

// A point of the Bezier curve (3 or 4 control points) at parameter t, by de Casteljau.
Vec2 BezierPoint(const std::vector<Vec2>& control, double t);

// The curve's point nearest to q (where two are equally near, either).
// CONTRACT: 3 or 4 control points, finite; q finite.
CurvePoint NearestOnBezier(Vec2 q, const std::vector<Vec2>& control);

// How far NearestOnBezier's distance may be from the true distance to the curve:
// |distance - true| <= BezierDistanceError(distance, extent), extent the largest |P_i| of the
// control points (coordinates included: the rounding of points written in doubles scales
// with them). With u = 2^-53, s the largest distance from q to a control point (at most the
// distance plus twice the extent) and a cubic (n = 3): the translation by q and at most 60
// halvings move each control point by at most (60n + 2) u s, which the lower bound and the
// point found may each carry; a piece is done once its bounds (or Newton's bracket) are
// within 64 u s; the last evaluation adds some 3n u of the extent. Summed:
// 436 u s + 9 u extent <= 1024 u (distance + extent) = 2^-43 (distance + extent), stated
// here with a factor 2 to spare.
inline double BezierDistanceError(double distance, double extent) {
  return 0x1p-42 * (distance + extent);
}

}  // namespace gvd
