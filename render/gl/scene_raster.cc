#include "render/gl/scene_raster.h"

#include <algorithm>
#include <chrono>
#include <numbers>
#include <optional>

#include "render/kernel/exact2.h"
#include "render/plan/coverage.h"
#include "render/plan/scan.h"
#include "render/plan/site_shape.h"
#include "render/plan/tile_lists.h"
#include "render/plan/update_windows.h"

namespace gvd {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

absl::StatusOr<std::unique_ptr<SceneRaster>> SceneRaster::Create(const Grid& grid, double eps,
                                                                  RenderMode mode,
                                                                  Diagram diagram,
                                                                  FullRender path) {
  auto target = RenderTarget::Create(grid.width, grid.height);
  if (!target.ok()) return target.status();
  return std::unique_ptr<SceneRaster>(
      new SceneRaster(grid, eps, mode, diagram, path, std::move(*target)));
}

PixelRect SceneRaster::Reach(const Geometry& g, double extent) const {
  Window b = BoundingBox(g);
  return grid_.CentresIn({b.min_x - extent, b.min_y - extent}, {b.max_x + extent, b.max_y + extent});
}

void SceneRaster::Publish(PixelRect rect, const std::vector<uint32_t>& ids,
                          const std::vector<float>& distances) {
  const ErrorModel error = tally_.Model(grid_, params_);
  if (rect == grid_.all() || frame_ == nullptr || frame_->empty()) {  // a full render
    frame_ = std::make_shared<const Frame>(grid_, eps_, error, ids.data(), distances.data(),
                                           drawn_);
  } else {
    frame_ = std::make_shared<const Frame>(*frame_, error, rect, ids.data(), distances.data(),
                                           drawn_);
  }
}

absl::StatusOr<std::shared_ptr<const Frame>> SceneRaster::RenderAll(Rasterizer& rasterizer,
                                                                    RenderStats* stats) {
  auto start = std::chrono::steady_clock::now();
  const SlotTable& slots = drawn_->sites();
  // Where the sites' lines lie less than two pixels apart on average, the meshes' coverage
  // needs leaves of one pixel and its pieces overlap many times: 100,000 crossing segments
  // at 1024x1024 took 38 s drawn (35 s of it the coverage, on the CPU whatever the device)
  // against 4.4 s computed (tests/bench/README.md). Such scenes are computed on every device.
  const bool crowded = drawn_->ink() / grid_.pixel_size() > grid_.pixel_count() / 2.0;
  bool compute =
      params_.diagram == Diagram::kNearest &&
      (path_ == FullRender::kCompute ||
       (path_ == FullRender::kAuto &&
        (params_.mode == RenderMode::kExact || rasterizer.software() || crowded)));
  Coverage cov;
  TileLists lists;
  double coverage_seconds = 0;
  std::vector<SiteDraw> draws;
  double max_value = 0, area = 0;
  uint32_t max_segments = 0;
  {
    // The plan makes no GL call: on a software device the other render threads have their
    // turn at GL meanwhile (it takes seconds in a scene of 100,000 crossing segments).
    GlTurn::Away off_gl(rasterizer.gl_turn());
    rasterizer.RunPlanningHook();
    if (compute) {
      cov = TileCandidates(grid_, slots, drawn_->index(), &lists);
    } else {
      cov = ParallelCoverage(grid_, *drawn_, grid_.all(), params_.diagram,
                             params_.mode == RenderMode::kMesh);
    }
    coverage_seconds = Seconds(start);
    tally_.Reset();
    extent_.assign(slots.size(), -1);
    for (uint32_t s = 0; s < slots.size(); ++s) {
      const Site* site = slots.get(s);
      if (site == nullptr) continue;
      tally_.Live(*site);
      if (cov.radius[s] < 0) continue;
      SiteDraw& d = draws.emplace_back(SiteDraw{s, cov.radius[s], cov.clip[s]});
      if (s < cov.pieces.size()) d.pieces = std::move(cov.pieces[s]);
      SiteShape shape = ShapeOf(grid_, params_, *site, d);
      extent_[s] = ClippedExtent(grid_, site->geometry, shape.extent, d.clip);
      max_value = std::max(max_value, shape.max_value);
      max_segments = std::max(max_segments, shape.segments);
      tally_.Drawn(grid_, *site, shape);
      if (!compute) area += DrawnArea(grid_, *site, d, shape);
    }
    if (compute) IndexByDraw(draws, slots.size(), &lists);
  }
  // Headroom: later increments may draw values up to twice this render's largest (or four
  // window diagonals) without a full render. Float depth keeps its relative precision at any
  // scale.
  params_.depth_scale = std::max(2 * max_value, 4 * grid_.window.diagonal());
  auto draw_start = std::chrono::steady_clock::now();
  std::vector<uint32_t> ids;
  std::vector<float> distances;
  double draw_seconds = 0, readback_seconds = 0;
  if (compute) {
    absl::Status s =
        rasterizer.Compute(grid_, params_, slots, draws, lists, *target_, &ids, &distances);
    // Too large for the GL's storage buffers: the same radii serve the meshes.
    if (absl::IsResourceExhausted(s)) {
      compute = false;
    } else if (!s.ok()) {
      return s;
    }
    draw_seconds = Seconds(draw_start);
  }
  if (!compute) {
    if (auto s = rasterizer.Draw(grid_, params_, grid_.all(), true, slots, draws, *target_);
        !s.ok()) {
      return s;
    }
    auto read_start = std::chrono::steady_clock::now();
    draw_seconds = Seconds(draw_start);
    if (auto s = rasterizer.ReadBack(*target_, grid_.all(), params_.depth_scale, &ids,
                                     &distances);
        !s.ok()) {
      return s;
    }
    readback_seconds = Seconds(read_start);
  }
  valid_ = true;
  computed_updates_ = compute && rasterizer.native_scan();
  Publish(grid_.all(), ids, distances);
  if (stats) {
    stats->cone_segments = max_segments;
    stats->sites_drawn = draws.size();
    stats->fill_ratio = compute ? 0 : area / (grid_.window.width() * grid_.window.height());
    stats->computed = compute;
    stats->candidates_per_pixel =
        compute ? double(cov.pairs) * kScanTile * kScanTile /
                      double(grid_.pixel_count())
                : 0;
    stats->tile_px = cov.tile_px;
    stats->coverage_seconds = coverage_seconds;
    stats->draw_seconds = draw_seconds;
    stats->readback_seconds = readback_seconds;
    stats->window = grid_.all();
    stats->windows = 1;
    stats->pixels = grid_.pixel_count();
    stats->full = true;
  }
  cost_.Full(Seconds(start));
  return frame_;
}

absl::StatusOr<std::shared_ptr<const Frame>> SceneRaster::Apply(
    Rasterizer& rasterizer, std::shared_ptr<const SiteSnapshot> sites, RenderStats* stats) {
  // 1. Compare the slots with those last drawn: collect the windows that old cones reached
  //    (their pixels may now belong to other sites) and the slots placed anew. A slot freed
  //    and taken again since is both; its old pixels all lie inside its dirty window, which
  //    is redrawn below, so no pixel keeps an id that now means another site.
  std::vector<PixelRect> dirty;
  std::vector<uint32_t> placed;
  const bool from_scratch = !valid_ || frame_ == nullptr || frame_->empty() || drawn_ == nullptr;
  if (extent_.size() < sites->sites().size()) extent_.resize(sites->sites().size(), -1);
  if (!from_scratch) {
    SlotTable::Diff(drawn_->sites(), sites->sites(),
                    [&](uint32_t s, const Site* before, const Site* after) {
                      if (before && extent_[s] >= 0) {
                        PixelRect r = Reach(before->geometry, extent_[s]);
                        if (!r.empty()) dirty.push_back(r);
                      }
                      extent_[s] = -1;
                      if (after) placed.push_back(s);
                    });
  }
  drawn_ = std::move(sites);
  const SlotTable& slots = drawn_->sites();

  if (drawn_->empty()) {
    valid_ = false;
    frame_ = Frame::Empty(grid_, eps_, drawn_);
    return frame_;
  }
  if (from_scratch) return RenderAll(rasterizer, stats);
  if (params_.diagram == Diagram::kFarthest) return RenderAll(rasterizer, stats);
  for (uint32_t s : placed) tally_.Live(*slots.get(s));

  // Each change costs about the same wherever it is; a full render grows with the scene and
  // its kind of sites, so the scene's own renders say where one becomes cheaper. (A cap of
  // max(64, n / 512) changes, right for points, sent every update of 20,000 segments that
  // gathered 33 moves to a full render of 200 ms, where its windows took some 40 ms.)
  const size_t changes = placed.size() + dirty.size();
  if (cost_.FullIsCheaper(changes, drawn_->size())) return RenderAll(rasterizer, stats);

  auto start = std::chrono::steady_clock::now();
  // 2. The windows to redraw: the old pieces' reach, and where each placed site can be
  //    best now (render/plan/update_windows.h).
  std::vector<UpdateWindow> windows = UpdateWindows(grid_, *frame_, slots, placed, dirty);
  uint64_t area = 0;
  for (const auto& w : windows) area += w.rect.area();
  if (area > grid_.pixel_count() / 2) return RenderAll(rasterizer, stats);

  // 3. Each window: cleared ones get every site that can be best there, with the coverage
  //    proof restricted to the window; the others only their new sites.
  //    The proof runs sparse: its cost follows the window and the sites near it, not the
  //    scene's size.
  //    Computed, each window gets the scan's candidate lists of its tiles instead.
  std::vector<std::vector<SiteDraw>> draws(windows.size());
  std::vector<TileLists> lists(computed_updates_ ? windows.size() : 0);
  uint32_t tile_px = 0;
  for (size_t w = 0; w < windows.size(); ++w) {
    if (!windows[w].clear) {
      draws[w] = std::move(windows[w].added);
      if (computed_updates_) {
        lists[w] = AddedCandidates(grid_, slots, *frame_, windows[w].rect, draws[w]);
      }
      continue;
    }
    if (computed_updates_) {
      tile_px = kScanTile;
      draws[w] = WindowCandidates(grid_, slots, drawn_->index(), windows[w].rect, &lists[w]);
      continue;
    }
    tile_px = DefaultTilePx(grid_, drawn_->size(), drawn_->ink());
    draws[w] = SparseCoverage(grid_, slots, drawn_->index(), windows[w].rect, tile_px,
                              params_.diagram, params_.mode == RenderMode::kMesh);
  }
  double coverage_seconds = Seconds(start);
  double fill = 0, max_value = 0;
  uint32_t max_segments = 0;
  size_t drawn = 0;
  std::vector<std::pair<uint32_t, SiteShape>> shapes;
  std::vector<double> extents;  // each shape's, cut to its clip
  for (const auto& list : draws) {
    for (const SiteDraw& d : list) {
      const Site& site = *slots.get(d.slot);
      SiteShape shape = ShapeOf(grid_, params_, site, d);
      max_value = std::max(max_value, shape.max_value);
      max_segments = std::max(max_segments, shape.segments);
      if (!computed_updates_) fill += DrawnArea(grid_, site, d, shape);
      extents.push_back(ClippedExtent(grid_, site.geometry, shape.extent, d.clip));
      shapes.emplace_back(d.slot, shape);
      ++drawn;
    }
  }
  if (max_value > params_.depth_scale) return RenderAll(rasterizer, stats);  // rescale
  for (size_t k = 0; k < shapes.size(); ++k) {
    const auto& [slot, shape] = shapes[k];
    extent_[slot] = std::max(extent_[slot], extents[k]);
    tally_.Drawn(grid_, *slots.get(slot), shape);
  }
  // The sites placed now hold no pixel outside these windows. Their extents, drawn from
  // coarse tile bounds, shrink to the pixels they won (read back below), so that moving or
  // deleting one of them later clears only that much.
  std::sort(placed.begin(), placed.end());
  std::vector<double> won(placed.size(), -1);
  std::vector<Window> boxes;
  for (uint32_t s : placed) boxes.push_back(BoundingBox(slots.get(s)->geometry));
  double draw_seconds = 0, readback_seconds = 0;
  PixelRect all_windows;
  // Computed: no GL call, so other render threads may have their turn at GL meanwhile.
  std::optional<GlTurn::Away> off_gl;
  if (computed_updates_) off_gl.emplace(rasterizer.gl_turn());
  for (size_t w = 0; w < windows.size(); ++w) {
    const PixelRect& rect = windows[w].rect;
    auto draw_start = std::chrono::steady_clock::now();
    std::vector<uint32_t> ids;
    std::vector<float> distances;
    if (computed_updates_) {
      ScanTiles(grid_, rect, lists[w], ScanSitesOf(grid_, params_, slots, draws[w]),
                static_cast<float>(params_.depth_scale), &ids, &distances);
      if (!windows[w].clear) OverFrame(*frame_, rect, &ids, &distances);
      draw_seconds += Seconds(draw_start);
    } else {
      if (auto s = rasterizer.Draw(grid_, params_, rect, windows[w].clear, slots, draws[w],
                                   *target_);
          !s.ok()) {
        return s;
      }
      auto read_start = std::chrono::steady_clock::now();
      draw_seconds += std::chrono::duration<double>(read_start - draw_start).count();
      if (auto s = rasterizer.ReadBack(*target_, rect, params_.depth_scale, &ids, &distances);
          !s.ok()) {
        return s;
      }
      readback_seconds += Seconds(read_start);
    }
    for (uint32_t j = rect.y0, k = 0; j < rect.y1; ++j) {
      for (uint32_t i = rect.x0; i < rect.x1; ++i, ++k) {
        if (ids[k] == 0) continue;
        auto it = std::lower_bound(placed.begin(), placed.end(), ids[k] - 1);
        if (it == placed.end() || *it != ids[k] - 1) continue;
        const Window& b = boxes[it - placed.begin()];
        const Vec2 c = grid_.Center(i, j);
        double& e = won[it - placed.begin()];
        e = std::max({e, b.min_x - c.x, c.x - b.max_x, b.min_y - c.y, c.y - b.max_y, 0.0});
      }
    }
    Publish(rect, ids, distances);
    all_windows = all_windows.Union(rect);
  }
  // Reach(geometry, extent) then holds every pixel they won (half a pixel spare for rounding).
  for (size_t k = 0; k < placed.size(); ++k) {
    extent_[placed[k]] = won[k] < 0 ? -1 : won[k] + 0.5 * grid_.pixel_size();
  }
  if (windows.empty()) Publish({}, {}, {});  // nothing visible changed
  cost_.Update(changes, Seconds(start));
  if (stats) {
    stats->cone_segments = max_segments;
    stats->sites_drawn = drawn;
    stats->fill_ratio =
        computed_updates_ ? 0 : fill / (grid_.window.width() * grid_.window.height());
    stats->computed = computed_updates_;
    uint64_t pairs = 0;
    for (const TileLists& l : lists) pairs += l.pairs();
    stats->candidates_per_pixel =
        area > 0 ? double(pairs) * kScanTile * kScanTile / double(area) : 0;
    stats->tile_px = tile_px;
    stats->coverage_seconds = coverage_seconds;
    stats->draw_seconds = draw_seconds;
    stats->readback_seconds = readback_seconds;
    stats->window = all_windows;
    stats->windows = windows.size();
    stats->pixels = area;
    stats->full = false;
  }
  return frame_;
}

absl::StatusOr<std::shared_ptr<const Frame>> RenderOnce(Rasterizer& rasterizer, const Grid& grid,
                                                        double eps, uint64_t version,
                                                        const SiteTable& sites, RenderStats* stats,
                                                        RenderMode mode, Diagram diagram,
                                                        FullRender path) {
  auto scene = SceneRaster::Create(grid, eps, mode, diagram, path);
  if (!scene.ok()) return scene.status();
  return (*scene)->Apply(rasterizer, SiteSnapshot::Of(version, sites), stats);
}

}  // namespace gvd
