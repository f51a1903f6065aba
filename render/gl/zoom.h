// Zoom windows (paper sec. 6.2, adaptive resolution): any window of a frame's diagram,
// rendered at a resolution of its own from the frame's sites.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/gl/rasterizer.h"

namespace gvd {

// Sites outside a zoom window keep their regions inside it, so each window's coverage is
// proven from all of the frame's sites (render/plan/coverage.h), and each fan's triangle count
// follows from how far it must reach at the window's eps: the paper's warning that "the
// maximum distance to a site must be adjusted" when zooming. A fan that would need more than
// kMaxConeSegments widens the frame's reported bound instead (SiteShape::excess).
//
// Many windows are drawn side by side into one atlas and read back together. Not
// thread-safe: use it on the GL context's thread.
class ZoomRenderer {
 public:
  ZoomRenderer() = default;
  ~ZoomRenderer();
  ZoomRenderer(const ZoomRenderer&) = delete;
  ZoomRenderer& operator=(const ZoomRenderer&) = delete;

  // One frame per grid, in order: the base frame's sites (same slots), diagram and version,
  // drawn in `mode` with eps scaled to the grid's pixels (base eps * pixel size / base pixel
  // size). Grids may lie anywhere in the plane. CONTRACT: the base frame is not empty; every
  // grid is valid (finite window, min < max, 1 to 8192 pixels a side).
  absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> Render(
      Rasterizer& rasterizer, const Frame& base, RenderMode mode, const std::vector<Grid>& grids);

  // Zoom windows drawn since this renderer was made.
  uint64_t windows_drawn() const { return windows_drawn_; }

 private:
  std::unique_ptr<RenderTarget> atlas_;
  uint64_t windows_drawn_ = 0;
};

}  // namespace gvd
