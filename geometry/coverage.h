// How far each site's distance mesh must reach (paper sec. 8: "bounding the site distance
// functions to a maximum distance"), so that a render fills a small multiple of the grid
// instead of sites x grid.
#pragma once

#include <cmath>
#include <cstdint>
#include <mutex>
#include <utility>
#include <vector>

#include "geometry/geometry.h"
#include "geometry/site.h"
#include "geometry/site_index.h"

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
// What is drawn. A site s is drawn with value v_s(p) = m_s d(p, s) + a_s wherever it is
// "present": within max_distance + DrawMargin of its geometry and, for a polygon restricted to
// one side, on that side or within DrawMargin of its boundary. The drawn diagram takes the
// least (kNearest) or greatest (kFarthest) v over the sites present.
//
// Why the radii are enough (kNearest). Take a tile of the region, C the rectangle spanned by
// its pixel centres, c the centre of C and h its half-diagonal. A site s1 present on all of C
// gives U = m1 (d(c, s1) + h) + a1 >= v_s1(p) for every p of C; the least such U is taken over
// the nearest site to c and the sites within reach of it. A site s best at some p of C has
// v_s(p) <= U, so m_s max(0, d(c, s) - h) + a_s <= U: the others are dropped, as are sites
// not present anywhere near C (beyond max_distance + margin, or an inside-only polygon whose
// box, grown by the margin, misses C). For plain point sites s and s1, s must also be at least as near
// as s1 at p: p lies in the half-plane {x : |x s| <= |x s1|}; as C is convex, some corner of C
// lies in it too, and sites with no corner there are dropped. Every remaining candidate gets
// radius >= max over C of d(., s) (capped at its presence, max_distance + DrawMargin), so
// every pixel centre lies within the radius of each site best there. With no site present
// on all of C, every site present near C is kept. kFarthest keeps every site, over the whole
// region. tests/coverage_test.cc checks this pixel by pixel against the oracle.
// CONTRACT: index holds exactly the live slots of the table, at least one.
Coverage ComputeCoverage(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                         PixelRect region, uint32_t tile_px = 0,
                         Diagram diagram = Diagram::kNearest);


// The proof above for one tile at a time (kNearest), for renders that keep a candidate list
// per tile (the compute path) and for ComputeCoverage itself. Thread-safe: tiles may be
// covered concurrently. CONTRACT: as ComputeCoverage's; the grid, table and index outlive it.
class TileCover {
 public:
  TileCover(const Grid& grid, const SlotTable& sites, const SiteIndex& index);

  // Appends to `slots` every site that can be best at some pixel centre of `tile` (a
  // non-empty rectangle of the grid's pixels), in no particular order, and to `radii` the
  // radius it needs there: at least its distance from every pixel centre of the tile, capped
  // at its presence (max_distance + DrawMargin).
  void Cover(PixelRect tile, std::vector<uint32_t>* slots, std::vector<double>* radii) const;

  // The radius a site needs over `box` (a rectangle of pixel centres).
  double RadiusFor(const SiteView& s, const Window& box) const;

 private:
  const Grid& grid_;
  const SlotTable& sites_;
  const SiteIndex& index_;
  // How far from its bounding box any site is present, less DrawMargin (infinite when some
  // site is present everywhere): for the tiles with no site present on the whole of them.
  // Computed on first use, O(sites).
  double PresenceReach() const;

  const LeastWeights least_;
  const double margin_;
  mutable std::once_flag reach_once_;
  mutable double reach_ = INFINITY;
};

// The same radii as ComputeCoverage, as a list of (slot, radius) for the sites with one, in
// slot order: for a small region of a large scene (a zoom window), whose cost then depends
// on the region and the sites near it, not on the scene's size (but for kFarthest, which
// keeps every site).
std::vector<std::pair<uint32_t, double>> SparseCoverage(const Grid& grid, const SlotTable& sites,
                                                        const SiteIndex& index,
                                                        PixelRect region, uint32_t tile_px,
                                                        Diagram diagram);

}  // namespace gvd
