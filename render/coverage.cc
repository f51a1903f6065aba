#include "render/coverage.h"

#include <algorithm>
#include <cmath>

#include "render/exact.h"

namespace gvd {
namespace {

// Whether some corner x of c satisfies |x s| <= |x s1| (with a little slack for rounding, so
// the test can only keep too many sites, never too few).
bool BeatsSomewhere(Vec2 s, Vec2 s1, const Window& c) {
  for (Vec2 x : {Vec2{c.min_x, c.min_y}, Vec2{c.max_x, c.min_y}, Vec2{c.min_x, c.max_y},
                 Vec2{c.max_x, c.max_y}}) {
    double a = Distance(x, s), b = Distance(x, s1);
    if (a <= b * (1 + 1e-12) + 1e-300) return true;
  }
  return false;
}

}  // namespace

uint32_t DefaultTilePx(const Grid& grid, size_t n) {
  double spacing = std::sqrt(double(grid.pixel_count()) / std::max<size_t>(n, 1));
  return static_cast<uint32_t>(std::clamp(2 * spacing, 4.0, 64.0));
}

Coverage ComputeCoverage(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                         PixelRect region, uint32_t tile_px) {
  Coverage cov;
  cov.radius.assign(sites.size(), -1);
  cov.tile_px = tile_px ? tile_px : DefaultTilePx(grid, index.size());
  std::vector<uint32_t> candidates;
  for (uint32_t ty = region.y0; ty < region.y1; ty += cov.tile_px) {
    for (uint32_t tx = region.x0; tx < region.x1; tx += cov.tile_px) {
      uint32_t x1 = std::min(tx + cov.tile_px, region.x1) - 1;
      uint32_t y1 = std::min(ty + cov.tile_px, region.y1) - 1;
      Vec2 lo = grid.Center(tx, ty), hi = grid.Center(x1, y1);
      Window cell{lo.x, lo.y, hi.x, hi.y};
      Vec2 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2};
      double h = Distance(lo, hi) / 2;
      ExactNearest s1 = index.Nearest(c, sites);
      // Rounding slack on the search radius keeps the candidate set a superset.
      double reach = (s1.distance + 2 * h) * (1 + 1e-12);
      candidates.clear();
      index.Within(c, reach, &candidates);
      const auto* p1 = std::get_if<PointSite>(&sites.get(s1.index)->geometry);
      for (uint32_t s : candidates) {
        const Geometry& g = sites.get(s)->geometry;
        if (ExactDistance(c, g) > reach) continue;
        const auto* p = std::get_if<PointSite>(&g);
        if (p && p1 && s != s1.index && !BeatsSomewhere(p->p, p1->p, cell)) continue;
        // The margin absorbs rounding differences between this bound and distances computed
        // elsewhere (a few ulps), so the radius can never fall short of them.
        cov.radius[s] = std::max(cov.radius[s], FarthestDistance(cell, g) * (1 + 0x1p-40));
        ++cov.pairs;
      }
    }
  }
  return cov;
}

}  // namespace gvd
