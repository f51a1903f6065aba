#include "render/gl/zoom.h"

#include <algorithm>

#include "render/plan/coverage.h"
#include "render/plan/error_tally.h"
#include "render/plan/site_shape.h"

namespace gvd {
namespace {

// The atlas is this wide (or as wide as the widest window), and a batch at most this tall
// (or as tall as the tallest window).
constexpr uint32_t kAtlasWidth = 2048;
constexpr uint32_t kAtlasHeight = 2048;
// Coverage tiles of a zoom window: its sites are few, so large tiles cost little.
constexpr uint32_t kZoomTilePx = 32;

struct Placed {
  size_t grid;    // index into the request
  uint32_t x, y;  // where its pixel (0, 0) sits in the atlas
};

}  // namespace

ZoomRenderer::~ZoomRenderer() = default;

absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> ZoomRenderer::Render(
    Rasterizer& rasterizer, const Frame& base, RenderMode mode, const std::vector<Grid>& grids) {
  std::vector<std::shared_ptr<const Frame>> out(grids.size());
  if (grids.empty()) return out;
  const SiteSnapshot& snapshot = base.snapshot();
  const SlotTable& sites = base.sites();
  const Diagram diagram = base.error().diagram;
  // Weights, presence and curves of every live site, whether drawn in a window or not.
  ErrorTally live;
  for (uint32_t s = 0; s < sites.size(); ++s) {
    if (const Site* site = sites.get(s)) live.Live(*site);
  }

  uint32_t width = kAtlasWidth;
  for (const Grid& g : grids) width = std::max(width, g.width);
  size_t next = 0;
  while (next < grids.size()) {
    // Shelf-pack a batch of windows into the atlas.
    std::vector<Placed> batch;
    uint32_t x = 0, y = 0, shelf = 0;
    for (; next < grids.size(); ++next) {
      const Grid& g = grids[next];
      if (x + g.width > width) {
        x = 0;
        y += shelf;
        shelf = 0;
      }
      if (!batch.empty() && y + g.height > kAtlasHeight) break;
      batch.push_back({next, x, y});
      x += g.width;
      shelf = std::max(shelf, g.height);
    }
    const uint32_t height = y + shelf;
    if (!atlas_ || atlas_->width() < width || atlas_->height() < height) {
      const uint32_t h = std::max(height, atlas_ ? atlas_->height() : 0u);
      atlas_.reset();
      auto t = RenderTarget::Create(width, h);
      if (!t.ok()) return t.status();
      atlas_ = std::move(*t);
    }
    std::vector<double> depth_scale(batch.size()), eps(batch.size());
    std::vector<ErrorModel> models(batch.size());
    for (size_t k = 0; k < batch.size(); ++k) {
      const Grid& g = grids[batch[k].grid];
      DrawParams params;
      params.eps = base.eps() * g.pixel_size() / base.grid().pixel_size();
      params.mode = mode;
      params.diagram = diagram;
      std::vector<SiteDraw> draws;
      ErrorTally tally = live;
      double max_value = 0;
      draws = SparseCoverage(g, sites, snapshot.index(), g.all(), kZoomTilePx, diagram,
                             mode == RenderMode::kMesh);
      for (const SiteDraw& d : draws) {
        SiteShape shape = ShapeOf(g, params, *sites.get(d.slot), d);
        max_value = std::max(max_value, shape.max_value);
        tally.Drawn(g, *sites.get(d.slot), shape);
      }
      params.depth_scale = std::max(max_value, g.window.diagonal());
      depth_scale[k] = params.depth_scale;
      if (auto s = rasterizer.Draw(g, params, g.all(), /*clear=*/true, sites, draws, *atlas_,
                                   batch[k].x, batch[k].y);
          !s.ok()) {
        return s;
      }
      eps[k] = params.eps;
      models[k] = tally.Model(g, params);
    }
    std::vector<uint32_t> ids;
    std::vector<float> depths;
    if (auto s = rasterizer.ReadBack(*atlas_, {0, 0, width, height}, 1.0, &ids, &depths); !s.ok()) {
      return s;
    }
    for (size_t k = 0; k < batch.size(); ++k) {
      const Grid& g = grids[batch[k].grid];
      std::vector<uint32_t> zi(g.pixel_count());
      std::vector<float> zd(g.pixel_count());
      for (uint32_t j = 0; j < g.height; ++j) {
        const size_t row = size_t{batch[k].y + j} * width + batch[k].x;
        for (uint32_t i = 0; i < g.width; ++i) {
          zi[size_t{j} * g.width + i] = ids[row + i];
          zd[size_t{j} * g.width + i] = static_cast<float>(depths[row + i] * depth_scale[k]);
        }
      }
      out[batch[k].grid] = std::make_shared<const Frame>(g, eps[k], models[k], zi.data(), zd.data(),
                                                         base.snapshot_ptr());
      ++windows_drawn_;
    }
  }
  if (atlas_ && uint64_t{atlas_->width()} * atlas_->height() > uint64_t{4096} * 4096) {
    atlas_.reset();  // keep only a modest atlas between calls
  }
  return out;
}

}  // namespace gvd
