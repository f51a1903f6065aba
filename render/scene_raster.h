// One scene's diagram as the render thread keeps it: the GPU buffers, the sites as last
// drawn (by slot), their spatial index, how far each one's cone reaches, and the last frame.
// Changes re-render only what they can touch.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "absl/status/statusor.h"
#include "render/frame.h"
#include "render/raster.h"
#include "render/site.h"
#include "render/site_index.h"

namespace gvd {

// An upsert (site set, with this id) or a deletion (site empty) of the site `id`.
struct SiteChange {
  SiteChange(std::string id, std::optional<Site> site) : id(std::move(id)), site(std::move(site)) {}
  // An upsert of a plain site.
  SiteChange(std::string id, Geometry geometry)
      : id(std::move(id)), site(Site{this->id, std::move(geometry)}) {}
  std::string id;
  std::optional<Site> site;
};

// Not thread-safe: the render thread owns it (it holds GL objects).
class SceneRaster {
 public:
  static absl::StatusOr<std::unique_ptr<SceneRaster>> Create(
      const Grid& grid, double eps, RenderMode mode = RenderMode::kMesh,
      Diagram diagram = Diagram::kNearest);

  // Applies the changes in order and renders what they can touch:
  //  - the first render (or the first after the scene was emptied) draws everything;
  //  - sites only added (or moved from where they were nearest to nothing) are drawn alone,
  //    over the existing buffers, within the tiles where they can now be nearest;
  //  - deleting or moving a site clears the window its old cone reached, adds the windows
  //    its new position can win, and redraws there only the sites that can be nearest there;
  //  - in a kFarthest diagram every change draws everything.
  // Reads back only that window and publishes a frame that shares the other tiles.
  // Deleting an unknown id is a no-op. After an error, the buffers are undefined: make a new
  // SceneRaster (the render loop does).
  absl::StatusOr<std::shared_ptr<const Frame>> Apply(Rasterizer& rasterizer, uint64_t version,
                                                     std::vector<SiteChange> changes,
                                                     RenderStats* stats = nullptr);

  size_t site_count() const { return slot_of_.size(); }

 private:
  SceneRaster(const Grid& grid, double eps, RenderMode mode, Diagram diagram,
              std::unique_ptr<RenderTarget> target)
      : grid_(grid), eps_(eps), params_{eps, mode, diagram, 1}, target_(std::move(target)) {}

  // The pixels whose centres lie within `extent` of the geometry's bounding box.
  PixelRect Reach(const Geometry& g, double extent) const;
  absl::StatusOr<std::shared_ptr<const Frame>> RenderAll(Rasterizer& rasterizer, uint64_t version,
                                                         RenderStats* stats);
  void Publish(uint64_t version, PixelRect rect, const std::vector<uint32_t>& ids,
               const std::vector<float>& distances);

  const Grid grid_;
  const double eps_;
  DrawParams params_;  // depth_scale: fixed between full renders, so old depths stay comparable
  std::unique_ptr<RenderTarget> target_;

  SlotTable slots_;
  std::unordered_map<std::string, uint32_t> slot_of_;
  std::vector<uint32_t> free_;
  SiteIndex index_;
  std::vector<double> extent_;  // per slot: how far its drawn fan reaches; < 0: not drawn

  bool valid_ = false;          // the target holds the diagram of slots_
  ErrorTally tally_;            // since the last full render, over the sites live at some point
  std::shared_ptr<const Frame> frame_;
};

}  // namespace gvd
