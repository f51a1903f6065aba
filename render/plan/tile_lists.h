// The candidate lists of a full render computed tile by tile (the compute shader
// nearest.comp, or the same scan in native code, render/plan/scan.h): for each tile of
// kScanTile pixels, the sites that can be best at one of its pixel centres, by the coverage
// proof of render/plan/coverage.h.
#pragma once

#include <cstdint>
#include <vector>

#include "render/kernel/grid2.h"
#include "render/plan/coverage.h"
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
};
static_assert(sizeof(TileLists::Point) == 4 * 4 && sizeof(TileLists::Segment) == 2 * 4);

// The candidate lists for the whole grid, the other sites by slot (the caller maps them to
// its draws); the radii are the largest each site needs over its tiles and the clips the
// union of those tiles (as ComputeCoverage's), and pairs counts the (tile, site) pairs.
// Rows of TopTilePx tiles are covered in parallel, each split down to the scan's tiles
// (TileCover::CoverDown). CONTRACT: as ComputeCoverage's, in a kNearest diagram.
Coverage TileCandidates(const Grid& grid, const SlotTable& slots, const SiteIndex& index,
                        TileLists* lists);

// Renames the lists' other sites (TileCandidates gives slots) as indices of `draws`, which
// the scan and the shader read. CONTRACT: draws are in slot order and hold every site the
// lists name; `slots` is the table's size.
void IndexByDraw(const std::vector<SiteDraw>& draws, uint32_t slots, TileLists* lists);

}  // namespace gvd
