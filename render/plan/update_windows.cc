#include "render/plan/update_windows.h"

#include <algorithm>
#include <cmath>

#include "render/kernel/exact2.h"

namespace gvd {
namespace {

// Distance from the geometry to the nearest point of the box (0 inside).
double NearestDistance(const Window& box, const Geometry& g) {
  Window b = BoundingBox(g);
  double dx = std::max({0.0, box.min_x - b.max_x, b.min_x - box.max_x});
  double dy = std::max({0.0, box.min_y - b.max_y, b.min_y - box.max_y});
  return std::hypot(dx, dy);  // a lower bound; exact for points
}

}  // namespace

std::vector<UpdateWindow> UpdateWindows(const Grid& grid, const Frame& frame,
                                        const SlotTable& slots, std::span<const uint32_t> placed,
                                        std::span<const PixelRect> dirty) {
  const ErrorModel& err = frame.error();
  const double margin = DrawMargin(grid);
  std::vector<UpdateWindow> windows;
  for (const PixelRect& d : dirty) windows.push_back({d, true, {}});
  for (uint32_t s : placed) {
    const Site& site = *slots.get(s);
    double radius = -1;
    PixelRect grown;
    for (uint32_t ty = 0; ty < frame.tiles_y(); ++ty) {
      for (uint32_t tx = 0; tx < frame.tiles_x(); ++tx) {
        PixelRect rect{tx * Frame::kTile, ty * Frame::kTile,
                       std::min((tx + 1) * Frame::kTile, grid.width),
                       std::min((ty + 1) * Frame::kTile, grid.height)};
        Window box = grid.CentreBox(rect);
        double m = frame.tile_at(tx, ty).max_distance;
        double near = NearestDistance(box, site.geometry);
        if (site.multiplicative * near + site.additive > m + err.Slack(m)) continue;
        if (near > site.max_distance + margin) continue;
        grown = grown.Union(rect);
        radius = std::max(radius, std::min(FarthestDistance(box, site) * (1 + 0x1p-40),
                                           site.max_distance + margin));
      }
    }
    if (radius >= 0) windows.push_back({grown, false, {{s, radius, grown}}});
  }
  // Merge overlapping windows until none overlap (a merged window is cleared if either was).
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t a = 0; a < windows.size() && !merged; ++a) {
      for (size_t b = a + 1; b < windows.size() && !merged; ++b) {
        if (windows[a].rect.Intersects(windows[b].rect)) {
          windows[a].rect = windows[a].rect.Union(windows[b].rect);
          windows[a].clear = windows[a].clear || windows[b].clear;
          windows[a].added.insert(windows[a].added.end(), windows[b].added.begin(),
                                  windows[b].added.end());
          windows.erase(windows.begin() + b);
          merged = true;
        }
      }
    }
  }
  return windows;
}

void UpdateCost::Update(size_t changes, double seconds) {
  update_seconds_ = update_seconds_ / 2 + seconds;
  update_changes_ = update_changes_ / 2 + static_cast<double>(changes);
}

bool UpdateCost::FullIsCheaper(size_t changes, size_t sites) const {
  constexpr size_t kFewest = 64;
  if (changes <= kFewest) return false;
  if (full_seconds_ <= 0 || update_seconds_ <= 0 || update_changes_ <= 0) {
    return changes > sites / 512;
  }
  return static_cast<double>(changes) * (update_seconds_ / update_changes_) > full_seconds_;
}

}  // namespace gvd
