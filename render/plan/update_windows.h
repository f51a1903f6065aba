// The windows an incremental render redraws (paper sec. 6.1's "only what changed"): where the
// sites a change removed or moved had drawn, and where the sites it placed can now be best.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "render/kernel/grid2.h"
#include "render/plan/coverage.h"
#include "render/scene/frame.h"
#include "render/scene/slot_table.h"

namespace gvd {

// A window of the grid an incremental render redraws.
struct UpdateWindow {
  PixelRect rect;
  bool clear;                   // holds an old piece's reach: redraw from scratch
  std::vector<SiteDraw> added;  // else: draw these over what is there
};

// The windows to redraw over `frame` (the last frame drawn) once the sites in the slots
// `placed` (of `slots`, the new version's table) are added: each of `dirty` (the pixels that
// old pieces reached; their pixels may now belong to other sites) is cleared and redrawn,
// and each placed site is drawn over the tiles where it can now be best, with the radius it
// needs there. Overlapping windows are merged (a merged window is cleared if either was), so
// no two returned overlap. O(placed * frame tiles + windows^2).
//
// Why those tiles are enough. Outside the dirty windows no pixel's best value grew, so a
// pixel p the placed site wins has m d(p, site) + a <= D(p) + slack (D the stored value):
// only tiles whose nearest point to the site passes that against their largest stored
// value, and within its presence, qualify.
std::vector<UpdateWindow> UpdateWindows(const Grid& grid, const Frame& frame,
                                        const SlotTable& slots, std::span<const uint32_t> placed,
                                        std::span<const PixelRect> dirty);

}  // namespace gvd
