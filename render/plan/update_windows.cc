#include "render/plan/update_windows.h"

#include <algorithm>
#include <cmath>

#include "render/kernel/exact2.h"

namespace gvd {
namespace {

// Distance between two boxes (0 where they meet): a lower bound on the distance from any
// point of `box` to a geometry whose bounding box is `b`; exact for a point.
double BoxDistance(const Window& box, const Window& b) {
  double dx = std::max({0.0, box.min_x - b.max_x, b.min_x - box.max_x});
  double dy = std::max({0.0, box.min_y - b.max_y, b.min_y - box.max_y});
  return std::hypot(dx, dy);
}

}  // namespace

std::vector<UpdateWindow> UpdateWindows(const Grid& grid, const Frame& frame,
                                        const SlotTable& slots, std::span<const uint32_t> placed,
                                        std::span<const PixelRect> dirty) {
  const ErrorModel& err = frame.error();
  const double margin = DrawMargin(grid);
  const double top = frame.max_value();
  std::vector<UpdateWindow> windows;
  for (const PixelRect& d : dirty) windows.push_back({d, true, {}});
  for (uint32_t s : placed) {
    const Site& site = *slots.get(s);
    const Window b = BoundingBox(site.geometry);
    // A tile the site can win passes both tests below, so it lies within `reach` of the
    // site's box: its value there, m d + a, is at most the frame's greatest stored value
    // (plus slack), and it is present. Only the tiles that reach touches are tested: in a
    // crowded scene a handful around the site, not the whole frame. The reach is grown by
    // a pixel's diagonal and a relative 2^-20, so that rounding cannot leave out a tile
    // that passes.
    const double reach = std::min((top + err.Slack(top) - site.additive) / site.multiplicative,
                                  site.max_distance + margin);
    if (reach < 0) continue;  // not even a tile at distance 0 passes
    uint32_t tx0 = 0, ty0 = 0, tx1 = frame.tiles_x() - 1, ty1 = frame.tiles_y() - 1;
    if (reach < INFINITY) {  // else (infinite, NaN) every tile is tested
      const double grow = reach * (1 + 0x1p-20) + grid.pixel_diagonal();
      const Vec2 lo = grid.ToPixel({b.min_x - grow, b.min_y - grow});
      const Vec2 hi = grid.ToPixel({b.max_x + grow, b.max_y + grow});
      auto tile = [](double v, uint32_t last) {  // the tile holding pixel coordinate v
        const double t = std::floor(v / Frame::kTile);
        return t <= 0 ? 0u : t >= last ? last : static_cast<uint32_t>(t);
      };
      tx0 = tile(lo.x, tx1), ty0 = tile(lo.y, ty1), tx1 = tile(hi.x, tx1), ty1 = tile(hi.y, ty1);
    }
    double radius = -1;
    PixelRect grown;
    for (uint32_t ty = ty0; ty <= ty1; ++ty) {
      for (uint32_t tx = tx0; tx <= tx1; ++tx) {
        PixelRect rect{tx * Frame::kTile, ty * Frame::kTile,
                       std::min((tx + 1) * Frame::kTile, grid.width),
                       std::min((ty + 1) * Frame::kTile, grid.height)};
        Window box = grid.CentreBox(rect);
        double m = frame.tile_max(tx, ty);
        double near = BoxDistance(box, b);
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
