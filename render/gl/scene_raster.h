// One scene's diagram as the render thread keeps it: the GPU buffers, the snapshot last
// drawn, how far each slot's cone reaches, and the last frame. A new snapshot re-renders only
// what its differences from the last one can touch.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/gl/rasterizer.h"
#include "render/plan/error_tally.h"
#include "render/plan/update_windows.h"
#include "render/scene/snapshot.h"

namespace gvd {

// How a render from scratch is made.
enum class FullRender {
  kAuto,     // kCompute for a kNearest diagram in RenderMode::kExact, or in any mode on a
             // software rasterizer (where it is several times faster for every kind) or
             // where the sites' lines crowd (less than two pixels apart on average); else
             // kRaster. In kMesh the computed values are exact, within the mode's bound.
  kRaster,   // every site's mesh (or per-fragment quad) drawn over its coverage radius
  kCompute,  // for kNearest: a compute shader over per-tile candidate lists (exact values)
};

// Not thread-safe: the render thread owns it (it holds GL objects).
class SceneRaster {
 public:
  static absl::StatusOr<std::unique_ptr<SceneRaster>> Create(
      const Grid& grid, double eps, RenderMode mode = RenderMode::kMesh,
      Diagram diagram = Diagram::kNearest, FullRender path = FullRender::kAuto);

  // Renders `sites`, drawing what changed since the snapshot last drawn (by slot: a site
  // differs when its slot holds another Site object, SlotTable::Diff):
  //  - the first render (or the first after the scene was emptied) draws everything;
  //  - sites only added (or moved from where they were nearest to nothing) are drawn alone,
  //    over the existing buffers, within the tiles where they can now be nearest;
  //  - deleting or moving a site clears the window its old cone reached, adds the windows
  //    its new position can win, and redraws there only the sites that can be nearest there;
  //  - unless the changes would cost more than one full render (UpdateCost, from this
  //    scene's renders) or their windows cover half the grid: then everything is drawn;
  //  - in a kFarthest diagram every change draws everything.
  // Where the last full render was computed in native code (Rasterizer::native_scan: on a
  // software device), the windows are computed the same way, on the CPU, from the frame
  // (render/plan/scan.h), and the target is left as that render left it; else they are drawn
  // into the target and read back. Either way, publishes a frame that shares the other tiles.
  // The frame is of `sites` and its version. After an error, the buffers are undefined: make a
  // new SceneRaster (the render loop does).
  absl::StatusOr<std::shared_ptr<const Frame>> Apply(Rasterizer& rasterizer,
                                                     std::shared_ptr<const SiteSnapshot> sites,
                                                     RenderStats* stats = nullptr);

  // The snapshot last drawn (null before the first Apply).
  const std::shared_ptr<const SiteSnapshot>& drawn() const { return drawn_; }

 private:
  SceneRaster(const Grid& grid, double eps, RenderMode mode, Diagram diagram, FullRender path,
              std::unique_ptr<RenderTarget> target)
      : grid_(grid), eps_(eps), params_{eps, mode, diagram, 1}, path_(path),
        target_(std::move(target)) {}

  // The pixels whose centres lie within `extent` of the geometry's bounding box.
  PixelRect Reach(const Geometry& g, double extent) const;
  absl::StatusOr<std::shared_ptr<const Frame>> RenderAll(Rasterizer& rasterizer,
                                                         RenderStats* stats);
  void Publish(PixelRect rect, const std::vector<uint32_t>& ids,
               const std::vector<float>& distances);

  const Grid grid_;
  const double eps_;
  DrawParams params_;  // depth_scale: fixed between full renders, so old depths stay comparable
  const FullRender path_;
  std::unique_ptr<RenderTarget> target_;

  std::shared_ptr<const SiteSnapshot> drawn_;  // the sites the frame (and target) hold
  std::vector<double> extent_;  // per slot: how far its drawn fan reaches; < 0: not drawn

  bool valid_ = false;          // the frame holds the diagram of drawn_, and so does the
                                // target unless computed_updates_
  bool computed_updates_ = false;  // updates are computed on the CPU (the last full render was)
  ErrorTally tally_;            // since the last full render, over the sites live at some point
  UpdateCost cost_;             // what full renders and updates have taken here
  std::shared_ptr<const Frame> frame_;
};

// One whole render of `sites` from scratch, through a SceneRaster of its own (the same path
// as a scene's first render): for a one-off diagram, such as the embedded mosaic's, and for
// tests and benchmarks.
absl::StatusOr<std::shared_ptr<const Frame>> RenderOnce(Rasterizer& rasterizer, const Grid& grid,
                                                        double eps, uint64_t version,
                                                        const SiteTable& sites,
                                                        RenderStats* stats = nullptr,
                                                        RenderMode mode = RenderMode::kMesh,
                                                        Diagram diagram = Diagram::kNearest,
                                                        FullRender path = FullRender::kAuto);

}  // namespace gvd
