#include "render/plan/site_shape.h"

#include <cmath>
#include <numbers>

#include "render/kernel/exact2.h"

namespace gvd {
namespace {

// The area of the convex polygon within `clip` (Sutherland-Hodgman, one side at a time).
double AreaWithin(const Window& clip, std::vector<Vec2> polygon) {
  std::vector<Vec2> next;
  // Keeps the part where s * (coordinate axis of p - bound) <= 0.
  auto cut = [&](int axis, double bound, double s) {
    next.clear();
    for (size_t i = 0; i < polygon.size(); ++i) {
      const Vec2 p = polygon[i], q = polygon[(i + 1) % polygon.size()];
      const double fp = s * (p[axis] - bound), fq = s * (q[axis] - bound);
      if (fp <= 0) next.push_back(p);
      if ((fp < 0) != (fq < 0) && fp != fq) next.push_back(p + (q - p) * (fp / (fp - fq)));
    }
    polygon.swap(next);
  };
  cut(0, clip.min_x, -1);
  cut(0, clip.max_x, 1);
  cut(1, clip.min_y, -1);
  cut(1, clip.max_y, 1);
  double twice = 0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2 p = polygon[i], q = polygon[(i + 1) % polygon.size()];
    twice += p.x * q.y - q.x * p.y;
  }
  return std::abs(twice) / 2;
}

// The area of the box within `lo`..`hi` that lies in `clip`.
double AreaWithin(const Window& clip, Vec2 lo, Vec2 hi) {
  return std::max(0.0, std::min(hi.x, clip.max_x) - std::max(lo.x, clip.min_x)) *
         std::max(0.0, std::min(hi.y, clip.max_y) - std::max(lo.y, clip.min_y));
}

}  // namespace

uint32_t SegmentBucket(uint32_t needed) {
  static constexpr uint32_t kBuckets[] = {3,   4,   6,   8,   12,   16,   24,   32,   48,  64,
                                          96,  128, 192, 256, 384,  512,  768,  1024, 1536,
                                          2048, 3072, 4096};
  for (uint32_t b : kBuckets) {
    if (needed <= b) return b;
  }
  return std::min(kMaxConeSegments, (needed + 4095) / 4096 * 4096);
}


bool PerFragment(const DrawParams& params, const Site& site) {
  if (params.mode == RenderMode::kExact) return true;
  if (SideOf(site.geometry) != Side::kBoth) return true;
  return params.diagram == Diagram::kFarthest && !std::holds_alternative<PointSite>(site.geometry);
}

bool ExactPoint(const DrawParams& params, const Site& site) {
  return params.mode == RenderMode::kExact && std::isinf(site.max_distance) &&
         std::holds_alternative<PointSite>(site.geometry);
}

FanDraw FanOf(uint32_t segments, double from, double to) {
  FanDraw fan{segments, FanTriangles(from, to, segments)};
  if (fan.whole()) return fan;
  const uint32_t fine = SegmentBucket(std::min(8 * segments, kMaxConeSegments));
  return {fine, FanTriangles(from, to, fine)};
}

double ClippedExtent(const Grid& grid, const Geometry& g, double extent, PixelRect clip) {
  const Window b = BoundingBox(g), c = grid.Area(clip);
  return std::min(extent, std::max({0.0, b.min_x - c.min_x, c.max_x - b.max_x,
                                    b.min_y - c.min_y, c.max_y - b.max_y}));
}

SiteShape ShapeOf(const Grid& grid, const DrawParams& params, const Site& site,
                  const SiteDraw& draw) {
  const double radius = draw.radius;
  // A sixteenth of a pixel beyond the proven radius keeps centres on the edge inside,
  // whatever the rasterizer's snapping (1/256 pixel), and 2^-18 of the largest float
  // coordinate involved keeps them inside whatever the rounding of positions and distances
  // (which dominates in deep zoom windows). Scaled by extent = r * k, a fan covers radius r;
  // the factor 1 + 2^-20 absorbs the rounding of the float ring vertices, which can fall a
  // few ulps inside the unit circle.
  const Window box = BoundingBox(site.geometry);
  const Window& w = grid.window;
  const double scale = std::max({std::abs(box.min_x - w.min_x), std::abs(box.max_x - w.min_x),
                                 std::abs(box.min_y - w.min_y), std::abs(box.max_y - w.min_y),
                                 w.width(), w.height()}) +
                       radius;
  SiteShape shape;
  shape.pad = grid.pixel_size() / 16 + scale * 0x1p-18;
  const double r = radius + shape.pad;
  const double m = site.multiplicative, a = site.additive;
  if (ExactPoint(params, site)) {
    shape.per_fragment = true;
    shape.extent = r * std::numbers::sqrt2 * (1 + 0x1p-20);
  } else if (PerFragment(params, site)) {
    shape.per_fragment = true;
    shape.extent = r;
  } else {
    const uint32_t needed = ConeSegments(r + params.eps, params.eps);
    shape.segments = SegmentBucket(needed);
    shape.overestimate = 1 / std::cos(std::numbers::pi / shape.segments);
    shape.extent = r * shape.overestimate * (1 + 0x1p-20);
    shape.excess = needed > kMaxConeSegments ? m * (shape.overestimate - 1) * shape.extent
                                             : m * params.eps;
  }
  shape.max_value = (m * shape.extent + a) * (1 + 0x1p-20);
  return shape;
}

double DrawnArea(const Grid& grid, const Site& site, const SiteDraw& draw, const SiteShape& shape) {
  if (shape.per_fragment) {  // a quad over the box grown by the padded radius
    const Window box = BoundingBox(site.geometry);
    const double r = draw.radius + shape.pad;
    return AreaWithin(grid.Area(draw.clip), {box.min_x - r, box.min_y - r},
                      {box.max_x + r, box.max_y + r});
  }
  double area = 0;
  ForEachPieceDrawn(shape, draw, site.geometry, [&](double e, PixelRect piece_clip, Vec2 p,
                                                    double from, double to) {
    const FanDraw fan = FanOf(shape.segments, from, to);
    const Window c = grid.Area(piece_clip);
    if (fan.whole()) {  // a point's cone: its box's part within the clip, at most its own
      area += std::min(std::numbers::pi * e * e,
                       AreaWithin(c, {p.x - e, p.y - e}, {p.x + e, p.y + e}));
      return;
    }
    std::vector<Vec2> wedge = {p};
    for (uint32_t k = 0; k <= fan.range.count; ++k) {
      const double t = 2 * std::numbers::pi * (fan.range.first + k) / fan.segments;
      wedge.push_back(p + e * Vec2{std::cos(t), std::sin(t)});
    }
    area += AreaWithin(c, std::move(wedge));
  }, [&](double e, PixelRect piece_clip, Vec2 p, Vec2 q, double from, double to) {
    const Vec2 n = Vec2{p.y - q.y, q.x - p.x} * (e / Distance(p, q));  // to the left
    const Vec2 a = p + from * (q - p), b = p + to * (q - p);
    area += AreaWithin(grid.Area(piece_clip), {a, b, b + n, a + n});
  });
  return area;
}

}  // namespace gvd
