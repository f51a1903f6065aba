// How far each site's distance mesh must reach (paper sec. 8: "bounding the site distance
// functions to a maximum distance"), so that a render fills a small multiple of the grid
// instead of sites x grid.
#pragma once

#include <cstdint>
#include <vector>

#include "render/geometry.h"
#include "render/site.h"
#include "render/site_index.h"

namespace gvd {

struct Coverage {
  // radius[s] >= the distance from the site in slot s to every pixel centre of the region
  // whose exact nearest site it is (ties included); negative when it is nearest to none of
  // them (or the slot is free), so its mesh need not be drawn there.
  std::vector<double> radius;
  uint32_t tile_px = 0;  // side of the tiles used
  uint64_t pairs = 0;    // (tile, candidate site) pairs examined
};

// The tile side that ComputeCoverage uses by default for n sites on the grid: about twice the
// mean spacing of the sites, in pixels, within [4, 64].
uint32_t DefaultTilePx(const Grid& grid, size_t n);

// Computes how far each site must reach to cover the pixel centres of `region` it is nearest
// to. `index` indexes `sites` by slot. O(tiles * candidates per tile * log n).
//
// Why it is enough. Take a tile of the region, C the rectangle spanned by its pixel centres,
// c the centre of C and h its half-diagonal; let s1 be the exact nearest site to c and
// d1 = |c s1|. For any centre p in C and any site s nearest to p:
//   d(p, s) <= d(p, s1) <= |p c| + d1 <= h + d1,   so   d(c, s) <= |c p| + d(p, s) <= d1 + 2h.
// So s is among the sites within d1 + 2h of c. For point sites, s must also be at least as
// near as s1 at p: p lies in the half-plane {x : |x s| <= |x s1|}; as C is convex, some corner
// of C lies in it too, and sites with no corner there are dropped. Every remaining candidate
// gets radius >= max over C of d(., s) >= d(p, s) for every p of C. Hence every pixel centre
// lies within the radius of each of its nearest sites. tests/coverage_test.cc checks this
// pixel by pixel against the oracle.
// CONTRACT: index holds exactly the live slots of the table, at least one.
Coverage ComputeCoverage(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                         PixelRect region, uint32_t tile_px = 0);

}  // namespace gvd
