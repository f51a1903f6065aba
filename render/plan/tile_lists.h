// The candidate lists of a full render computed tile by tile (the compute shader
// nearest.comp, or the same scan in native code, render/plan/scan.h): for each tile of
// kScanTile pixels, the sites that can be best at one of its pixel centres, by the coverage
// proof of render/plan/coverage.h.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "render/kernel/grid2.h"
#include "render/plan/coverage.h"
#include "render/scene/frame.h"
#include "render/scene/site_index.h"
#include "render/scene/slot_table.h"

namespace gvd {

// The side of the tiles whose candidate lists a computed render takes.
inline constexpr uint32_t kScanTile = 8;

// Candidate lists by tile of kScanTile pixels, row-major. Tile t's plain points
// (Site::plain) are points[offsets[3t] .. offsets[3t + 3]), in ascending id order; the sites
// it scans whole (polygons restricted to a side whose boundary comes near the tile: the
// even-odd test needs every edge) are draws[sites[k]] for k in [offsets[3t + 1],
// offsets[3t + 4]); of the other sites it scans single segments, segments[k] for k in
// [offsets[3t + 2], offsets[3t + 5]), those that can hold their site's nearest point where it
// can be best there (TileCover::NeededSegments), a site's next to each other.
struct TileLists {
  struct Point {  // nearest.comp's Point, std430
    float x, y;   // relative to the window's min corner
    uint32_t id;  // slot + 1
    uint32_t unused = 0;
  };
  struct Segment {   // nearest.comp's uvec2
    uint32_t site;   // draws[site]
    uint32_t index;  // its segment in ForEachSegment order
  };
  std::vector<uint32_t> offsets;  // 3 (tiles + 1) entries
  std::vector<Point> points;
  std::vector<uint32_t> sites;
  std::vector<Segment> segments;

  // The (tile, site) pairs the lists hold. O(entries).
  uint64_t pairs() const;
};
static_assert(sizeof(TileLists::Point) == 4 * 4 && sizeof(TileLists::Segment) == 2 * 4);

// The candidate lists for the whole grid, the other sites by slot (the caller maps them to
// its draws); the radii are the largest each site needs over its tiles and the clips the
// union of those tiles (as ComputeCoverage's), and pairs counts the (tile, site) pairs.
// Rows of TopTilePx tiles are covered in parallel, each split down to the scan's tiles
// (TileCover::CoverDown). CONTRACT: as ComputeCoverage's, in a kNearest diagram.
Coverage TileCandidates(const Grid& grid, const SlotTable& slots, const SiteIndex& index,
                        TileLists* lists);

// The scan's tiles that meet `rect` (a rectangle of the grid's pixels): its corners moved out
// to multiples of kScanTile, but for the grid's edge. A window's lists are of these tiles,
// row-major.
PixelRect ScanTilesAround(const Grid& grid, PixelRect rect);

// The candidate lists of the scan's tiles around `rect` (ScanTilesAround's), row-major over
// them, by the same proof as TileCandidates' from the index: for an incremental render's
// window cleared and computed again, at a cost that follows the window and the sites near
// it, not the scene's size. Returns the sites the lists name, in slot order, each with the
// radius its tiles need and their union as its clip; the lists' other sites are indices of
// it (as after IndexByDraw). On the calling thread. CONTRACT: as TileCandidates'.
std::vector<SiteDraw> WindowCandidates(const Grid& grid, const SlotTable& slots,
                                       const SiteIndex& index, PixelRect rect,
                                       TileLists* lists);

// The lists of the scan's tiles around `rect` (ScanTilesAround's) for sites drawn over what
// `frame` holds there, as an incremental render adds sites to a window it does not clear:
// each of `added` in the tiles its clip meets, with the segments that can hold its nearest
// point where its value is at most the frame's greatest in the tile
// (TileCover::NeededSegments), named as indices of `added`. CONTRACT: `frame` is of `grid`,
// and every slot of `added` holds a site of `slots`.
TileLists AddedCandidates(const Grid& grid, const SlotTable& slots, const Frame& frame,
                          PixelRect rect, std::span<const SiteDraw> added);

// Renames the lists' other sites (TileCandidates gives slots) as indices of `draws`, which
// the scan and the shader read. CONTRACT: draws are in slot order and hold every site the
// lists name; `slots` is the table's size.
void IndexByDraw(const std::vector<SiteDraw>& draws, uint32_t slots, TileLists* lists);

}  // namespace gvd
