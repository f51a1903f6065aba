// What drawing one site amounts to, before any GL: how far its pieces reach to cover the
// radius the coverage proof asks for within the error bound, how many triangles its fans
// take, which sites are drawn per fragment, and the area they cover. The rasterizer draws
// exactly these shapes; the planning of a render reads them without a GPU.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "render/kernel/diagram.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"
#include "render/plan/coverage.h"
#include "render/plan/distance_mesh.h"
#include "render/scene/settings.h"

namespace gvd {

// What drawing one site with a given radius amounts to.
struct SiteShape {
  double extent = 0;        // no fragment lies farther than this from the geometry
  double pad = 0;           // added to a radius for rounding before it is drawn
  double max_value = 0;     // no value written exceeds this (m * extent + a)
  double overestimate = 1;  // k of its fans (1 when none)
  uint32_t segments = 0;    // triangles in each of its fans (0 when none)
  bool per_fragment = false;  // drawn as a quad evaluated per fragment
  // A bound on height - value over what is drawn: m * eps for fans with enough triangles;
  // m * (k - 1) * extent for a fan that would need more than kMaxConeSegments (a site far
  // from a small window); 0 per fragment.
  double excess = 0;
};

// The fixed parameters of one scene's draws.
struct DrawParams {
  double eps = 0;
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;
  double depth_scale = 1;  // depth = value / depth_scale
};

// How a site that must cover `draw.radius` within `draw.clip` is drawn.
SiteShape ShapeOf(const Grid& grid, const DrawParams& params, const Site& site,
                  const SiteDraw& draw);

// The area that the pieces of a site drawn as `shape` (ShapeOf's) cover within the clip:
// each piece's, or its box's within the clip where that is less. For a drawn render's fill
// ratio: a fan's area costs a sine and a cosine a triangle, which renders computed on the
// CPU (or zoom windows) have no use for.
double DrawnArea(const Grid& grid, const Site& site, const SiteDraw& draw, const SiteShape& shape);

// Fans are drawn with one of these triangle counts (or a multiple of 4096 beyond): the next
// one up from what a site needs, so that sites share a few instanced draws. More triangles
// than needed only lower the error.
uint32_t SegmentBucket(uint32_t needed);

// Whether a site is drawn per fragment (see RenderMode).
bool PerFragment(const DrawParams& params, const Site& site);

// A point drawn per fragment with no max_distance to honour: a square of its own.
bool ExactPoint(const DrawParams& params, const Site& site);

// How the fan of a site drawn with `segments` triangles a turn is drawn over the directions
// [from, to]: the whole cone, or a range of a finer one (eight times the triangles a turn,
// so that the triangle of margin FanTriangles adds on each side costs little area). A finer
// fan with the same extent covers at least the same radius, with a smaller overestimate.
struct FanDraw {
  uint32_t segments = 0;
  FanRange range;
  bool whole() const { return range.count == segments; }
};
FanDraw FanOf(uint32_t segments, double from, double to);

// How far beyond the geometry's box a site drawn with `extent` within `clip` can have drawn:
// the pixels whose centres lie within the result of the geometry's bounding box hold every
// pixel it can have written.
double ClippedExtent(const Grid& grid, const Geometry& g, double extent, PixelRect clip);

// ForEachPiece of a site drawn as `shape`, with each piece's extent and clip: its own from
// draw.pieces where the coverage gave them (pieces with none are left out), else the site's;
// and each half-tent's part of its edge, g(extent, clip, a, b, from, to), from and to as
// fractions of ab (0 and 1 where the coverage gave none).
template <class F, class G>
void ForEachPieceDrawn(const SiteShape& shape, const SiteDraw& draw, const Geometry& geometry,
                       F&& f, G&& g) {
  size_t k = 0;
  const PieceDraw* p = nullptr;
  auto piece = [&](double* extent, PixelRect* clip) {
    *extent = shape.extent;
    *clip = draw.clip;
    p = nullptr;
    if (k >= draw.pieces.size()) return true;
    p = &draw.pieces[k++];
    if (p->radius < 0) return false;
    *extent = std::min(shape.extent, (p->radius + shape.pad) * shape.overestimate * (1 + 0x1p-20));
    *clip = p->clip;
    return true;
  };
  double e;
  PixelRect clip;
  ForEachPiece(
      geometry,
      [&](Vec2 q, double from, double to) {
        if (piece(&e, &clip)) f(e, clip, q, from, to);
      },
      [&](Vec2 a, Vec2 b) {
        if (!piece(&e, &clip)) return;
        // The part of the edge it needs, as fractions of ab, a pad beyond it (as its extent).
        double from = 0, to = 1;
        if (p != nullptr && p->from <= p->to) {
          const double length = Distance(a, b);
          from = std::max(0.0, (p->from - shape.pad) / length);
          to = std::min(1.0, (p->to + shape.pad) / length);
        }
        g(e, clip, a, b, from, to);
      });
}


}  // namespace gvd
