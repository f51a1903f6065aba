// Voronoi neighbours made reliable by zooming in (paper sec. 6.2): where the raster is too
// coarse to say which regions touch, zoom windows resolve it, and sites that own no pixel
// are searched for around their geometry.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "render/analysis/analysis.h"
#include "render/scene/frame.h"

namespace gvd {

// Renders the frame's sites at each grid (render/gl/zoom.h), same slots. The refinement calls it
// with batches of grids, one level of zoom at a time. Give it EXACT mode: near four nearly
// equidistant sites a mesh's error, even at a zoom's finer eps, blurs which is nearest over
// a band much wider than the structure sought.
using ZoomFn = std::function<absl::StatusOr<std::vector<std::shared_ptr<const Frame>>>(
    const std::vector<Grid>& grids)>;

struct RefineOptions {
  uint32_t block_px = 8;      // zoom windows of doubtful cells merge up to this side (pixels)
  uint32_t factor = 8;        // each zoom level has this many times the resolution of its parent
  uint32_t max_depth = 5;     // zoom levels below the frame (8^5: 1/32768 pixel); 0: none
  size_t max_windows = 200000;  // past this many windows, stop zooming (complete = false)
  size_t batch = 128;         // windows per call of the ZoomFn
};

struct RefinedNeighbors {
  NeighborCounts pairs;                // ids (slot + 1), a < b; count: pixel pairs seen
  std::vector<uint32_t> hidden;        // slots whose geometry meets the rect, with no pixel
  std::vector<uint32_t> recovered;     // of those, the slots found in a zoom window
  size_t windows = 0;                  // zoom windows rendered
  uint32_t depth = 0;                  // the deepest level rendered
  bool complete = true;                // false: max_windows cut the refinement short
};

// The Voronoi neighbours in `rect` of the frame, refined:
//  - a cell on a boundary is doubtful where four sites are nearly equidistant: three or more
//    sites among the 4x4 pixels around it, and four within a pixel diagonal plus a pixel
//    (times the largest weight, plus the meshes' error) of the best value at its centre.
//    There a Voronoi edge shorter than the pixels can be missed, or a pair seen that a thin
//    region really separates. Doubtful cells are rendered again, with a pixel of margin
//    (merged up to block_px a side), at `factor` times the resolution; the pairs between
//    pixel centres that a window spans come from the window (and its own doubtful cells,
//    recursively), the others from the image;
//  - a pair counts once it is certified at one of its pixel pairs: where the two sites'
//    boundary crosses between the pixel centres (located exactly), no other site beats both;
//  - a site whose geometry meets the rect but holds no pixel (a region smaller than the
//    pixels) is searched for by zooming around its geometry, level by level; once it shows,
//    that window's pairs count.
// Without `zoom` (or with max_depth 0): the pairs of adjacent pixels as the frame shows them
// (paper sec. 5), and the hidden sites. Thread-safe if `zoom` is. CONTRACT: the frame is not
// empty; rect is inside its grid.
absl::StatusOr<RefinedNeighbors> RefineNeighbors(const Frame& frame, PixelRect rect,
                                                 const ZoomFn& zoom,
                                                 const RefineOptions& options = {});

}  // namespace gvd
