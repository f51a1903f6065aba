// The 3D kernel as the scene's data structures name it, beside Kernel2 (kernel2.h): points of
// space, boxes of space and the sites of site3.h. The slot table and the spatial index
// (render/scene/slot_table.h, site_index.h) are instantiated for it as for Kernel2, so 3D
// scenes get the same versioned, persistent structures with no new alternative in 2D code.
#pragma once

#include <cmath>
#include <optional>
#include <variant>

#include "render/kernel/exact3.h"
#include "render/kernel/site3.h"

namespace gvd {

struct Kernel3 {
  static constexpr int kDimension = 3;
  using Point = Vec3;
  using Box = Box3;
  using Site = Site3;
  using Geometry = Geometry3;

  using Hit = Hit3;
  static Hit Feature(Point q, const Site& s) { return NearestFeature(q, s.geometry); }
  // A box's bounds on an axis (0: x, 1: y, 2: z).
  static double Min(const Box& b, int axis) {
    return axis == 0 ? b.min_x : axis == 1 ? b.min_y : b.min_z;
  }
  static double Max(const Box& b, int axis) {
    return axis == 0 ? b.max_x : axis == 1 ? b.max_y : b.max_z;
  }
  static double At(Point p, int axis) { return p[axis]; }
  static Point None() { return Point(NAN, NAN, NAN); }

  static Box BoxOf(const Site& s) { return BoundingBox(s.geometry); }
  static std::optional<Point> PointOf(const Site& s) {
    const auto* p = std::get_if<PointSite3>(&s.geometry);
    return p ? std::optional<Point>(p->p) : std::nullopt;
  }
  static double Distance(Point q, const Site& s) { return ExactDistance(q, s.geometry); }
  static double Value(Point q, const Site& s) { return SiteValue(q, s); }
  // No 3D structure is sized by the length of its sites' lines.
  static double Ink(const Site&) { return 0; }
  static double Tolerance(const Site&) { return 0; }  // every distance is the geometry's
  static double ShapeError(const Site&) { return 0; }
  static double CurveExtent(const Site&) { return 0; }
  // A mesh comes ready from MakeMesh; nothing else needs readying.
  static void Prepare(Site&) {}
};

}  // namespace gvd
