// The 2D kernel as the scene's data structures name it (render/scene/slot_table.h,
// site_index.h): its point, box and site types, and the few things those structures ask of
// a site. The structures are templates on a kernel, instantiated for this one; a 3D kernel
// (Vec3 points, boxes of space, sites of space: Kernel3) goes beside it and gets the same
// structures without a new alternative in any of the 2D code.
#pragma once

#include <algorithm>
#include <optional>
#include <variant>

#include "render/kernel/exact2.h"
#include "render/kernel/grid2.h"
#include "render/kernel/segment_tree.h"
#include "render/kernel/site2.h"

namespace gvd {

struct Kernel2 {
  static constexpr int kDimension = 2;
  using Point = Vec2;
  using Box = Window;
  using Site = gvd::Site;
  using Geometry = gvd::Geometry;

  // The site's nearest point to q and the feature it lies on.
  using Hit = FeatureHit;
  static Hit Feature(Point q, const Site& s) { return NearestFeature(q, s); }
  // A box's bounds on an axis (0: x, 1: y).
  static double Min(const Box& b, int axis) { return axis == 0 ? b.min_x : b.min_y; }
  static double Max(const Box& b, int axis) { return axis == 0 ? b.max_x : b.max_y; }
  // A point's coordinate on an axis.
  static double At(Point p, int axis) { return p[axis]; }
  // A point whose coordinates are all NaN: none.
  static Point None() { return Point(NAN, NAN); }

  // The smallest box holding the site's geometry.
  static Box BoxOf(const Site& s) { return BoundingBox(s.geometry); }
  // Where the site is, when its geometry is a point (whatever its weights); else nullopt.
  static std::optional<Point> PointOf(const Site& s) {
    const auto* p = std::get_if<PointSite>(&s.geometry);
    return p ? std::optional<Point>(p->p) : std::nullopt;
  }
  // The Euclidean distance from q to the site's geometry.
  static double Distance(Point q, const Site& s) { return ExactDistance(q, s); }
  // The site's value at q: its weighted distance, +inf where it has no influence.
  static double Value(Point q, const Site& s) { return SiteValue(q, s); }
  // The length of line the site draws (TotalLength), summed over a scene as its ink.
  static double Ink(const Site& s) { return TotalLength(s.geometry); }
  // How far the site's distances may be from its true geometry's, in value: the tolerance
  // of a Bezier's or a path's curves (their drawn polylines stand in for them) times its
  // multiplicative weight; 0 for every other kind.
  static double Tolerance(const Site& s) { return DrawnTolerance(s.geometry) * s.multiplicative; }
  // How far a site's pieces may be from the shape they stand for, in value (a path's
  // approximation, times its weight where that exceeds 1, so that it bounds distances too).
  static double ShapeError(const Site& s) {
    const auto* path = std::get_if<PathSite>(&s.geometry);
    return path ? path->approximation * std::max(1.0, s.multiplicative) : 0.0;
  }
  // The scale of a curve's measuring error (BezierDistanceError's extent, times the weight);
  // 0 for every other kind.
  static double CurveExtent(const Site& s) {
    double extent = 0;
    if (const auto* b = std::get_if<BezierSite>(&s.geometry)) {
      for (Vec2 p : b->control) extent = std::max(extent, Length(p));
    } else if (const auto* path = std::get_if<PathSite>(&s.geometry); path && path->curved) {
      for (const PathPiece& piece : path->pieces) {
        if (piece.degree == 1) continue;
        for (int i = 0; i <= piece.degree; ++i) extent = std::max(extent, Length(piece.control[i]));
      }
    }
    return extent * s.multiplicative;
  }
  // Readies a site that enters a table: its segment tree, for sites of many segments.
  static void Prepare(Site& s) { IndexSegments(s); }
};

}  // namespace gvd
