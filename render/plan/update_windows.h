// The windows an incremental render redraws (paper sec. 6.1's "only what changed"): where the
// sites a change removed or moved had drawn, and where the sites it placed can now be best.
#pragma once

#include <cstddef>
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
// no two returned overlap. O(frame tiles + placed * the tiles near each + windows^2).
//
// Why those tiles are enough. Outside the dirty windows no pixel's best value grew, so a
// pixel p the placed site wins has m d(p, site) + a <= D(p) + slack (D the stored value):
// only tiles whose nearest point to the site passes that against their largest stored
// value, and within its presence, qualify; none beyond the distance at which the frame's
// largest stored value fails, so only the tiles within it are tested.
std::vector<UpdateWindow> UpdateWindows(const Grid& grid, const Frame& frame,
                                        const SlotTable& slots, std::span<const uint32_t> placed,
                                        std::span<const PixelRect> dirty);

// Whether an update redraws its windows or renders everything, from what each has cost this
// scene. A full render's time grows with the scene and the kind of its sites (on the 2-core
// machine: 100,000 points 70-90 ms, 20,000 segments 200 ms), an update's with the changes it
// gathered (a moved site's old reach and new place, drawn through llvmpipe: 0.4 ms each at
// 100,000 points, 0.5-0.6 ms for segments; computed on the CPU, 0.1-0.3 ms at 100,000
// points). Not thread-safe: a scene's render thread keeps one.
class UpdateCost {
 public:
  // A full render took `seconds`.
  void Full(double seconds) { full_seconds_ = seconds; }
  // An update of `changes` changes (its slots placed and its old reaches) took `seconds`.
  void Update(size_t changes, double seconds);
  // Whether `changes` changes, in a scene of `sites` sites, cost more as windows than one
  // full render: by what both cost the last times, weighting each update by its changes;
  // until both have been measured, past max(64, sites / 512) changes (what windows of
  // 100,000 points take as long as their full render). Never under 64 changes, so that a
  // few slow updates cannot send every later one to a full render.
  bool FullIsCheaper(size_t changes, size_t sites) const;

 private:
  double full_seconds_ = 0;     // the last full render's
  double update_seconds_ = 0;   // updates' seconds and changes, each halved at every update:
  double update_changes_ = 0;   // their ratio, the recent cost of one change
};

}  // namespace gvd
