#include "render/gl/scene_raster.h"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <numbers>

#include "render/scene/cpu_pool.h"
#include "render/plan/coverage.h"
#include "render/kernel/exact2.h"

namespace gvd {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Distance from the geometry to the nearest point of the box (0 inside).
double NearestDistance(const Window& box, const Geometry& g) {
  Window b = BoundingBox(g);
  double dx = std::max({0.0, box.min_x - b.max_x, b.min_x - box.max_x});
  double dy = std::max({0.0, box.min_y - b.max_y, b.min_y - box.max_y});
  return std::hypot(dx, dy);  // a lower bound; exact for points
}

// How far beyond the geometry's box a site drawn with `extent` within `clip` can have drawn:
// Reach(geometry, result) holds every pixel it can have written.
double ClippedExtent(const Grid& grid, const Geometry& g, double extent, PixelRect clip) {
  const Window b = BoundingBox(g), c = grid.Area(clip);
  return std::min(extent, std::max({0.0, b.min_x - c.min_x, c.max_x - b.max_x,
                                    b.min_y - c.min_y, c.max_y - b.max_y}));
}

// ComputeCoverage of `region` in bands of TopTilePx rows covered in parallel (the tiles and
// so the radii and clips are the same as in one pass), then merged.
Coverage ParallelCoverage(const Grid& grid, const SiteSnapshot& snapshot, PixelRect region,
                          Diagram diagram, bool pieces) {
  const SlotTable& slots = snapshot.sites();
  const SiteIndex& index = snapshot.index();
  const uint32_t leaf = DefaultTilePx(grid, snapshot.size(), snapshot.ink());
  const uint32_t top = TopTilePx(grid, index.size(), leaf);
  const size_t bands = (size_t{region.height()} + top - 1) / top;
  if (bands < 2) {
    return ComputeCoverage(grid, slots, index, region, leaf, diagram, pieces);
  }
  std::mutex mu;
  std::vector<Coverage> parts;
  ParallelFor(bands, 1, [&](size_t begin, size_t end) {
    PixelRect band{region.x0, static_cast<uint32_t>(region.y0 + begin * top), region.x1,
                   static_cast<uint32_t>(std::min<size_t>(region.y0 + end * top, region.y1))};
    Coverage part = ComputeCoverage(grid, slots, index, band, leaf, diagram, pieces);
    std::lock_guard<std::mutex> lock(mu);
    parts.push_back(std::move(part));
  });
  Coverage cov = std::move(parts[0]);
  for (size_t p = 1; p < parts.size(); ++p) {
    const Coverage& part = parts[p];
    cov.pairs += part.pairs;
    for (uint32_t s = 0; s < slots.size(); ++s) {
      if (part.radius[s] < 0) continue;
      cov.radius[s] = std::max(cov.radius[s], part.radius[s]);
      cov.clip[s] = cov.clip[s].Union(part.clip[s]);
      if (s >= part.pieces.size() || part.pieces[s].empty()) continue;
      std::vector<PieceDraw>& into = cov.pieces[s];
      into.resize(std::max(into.size(), part.pieces[s].size()));
      for (size_t k = 0; k < part.pieces[s].size(); ++k) {
        into[k].radius = std::max(into[k].radius, part.pieces[s][k].radius);
        into[k].clip = into[k].clip.Union(part.pieces[s][k].clip);
        into[k].from = std::min(into[k].from, part.pieces[s][k].from);
        into[k].to = std::max(into[k].to, part.pieces[s][k].to);
      }
    }
  }
  return cov;
}

// The candidate lists of Rasterizer::Compute for the whole grid, the other sites by slot
// (Apply maps them to draws); the radii are the largest each site needs over its tiles and
// the clips the union of those tiles (as ComputeCoverage's), and pairs counts the (tile,
// site) pairs. Rows of TopTilePx tiles are covered in parallel, each split down to the
// compute tiles (TileCover::CoverDown).
Coverage TileCandidates(const Grid& grid, const SlotTable& slots, const SiteIndex& index,
                        Rasterizer::TileLists* lists) {
  constexpr uint32_t kTile = Rasterizer::kComputeTile;
  const uint32_t tiles_x = (grid.width + kTile - 1) / kTile;
  const uint32_t tiles_y = (grid.height + kTile - 1) / kTile;
  const uint32_t top = TopTilePx(grid, index.size(), kTile);
  const TileCover cover(grid, slots, index);
  struct Leaf {
    uint32_t tile;  // row-major index of the compute tile
    uint32_t ends[3];  // where its points, sites and segments end in the row's lists
  };
  struct Row {
    std::vector<Leaf> leaves;
    std::vector<Rasterizer::Point> points;
    std::vector<uint32_t> sites;
    std::vector<Rasterizer::Segment> segments;
    // Each (tile, site) pair once: the slot and the radius it needs there.
    std::vector<std::pair<uint32_t, double>> kept;
    std::vector<uint32_t> kept_ends;  // per leaf
  };
  const uint32_t rows_count = (grid.height + top - 1) / top;
  std::vector<Row> rows(rows_count);
  ParallelFor(rows_count, 1, [&](size_t begin, size_t end) {
    std::vector<uint32_t> needed;
    for (size_t ty = begin; ty < end; ++ty) {
      Row& row = rows[ty];
      const TileCover::Leaf leaf = [&](PixelRect rect, std::span<const uint32_t> kept,
                                       std::span<const double> radii, double upper) {
        for (size_t k = 0; k < kept.size(); ++k) {
          const uint32_t slot = kept[k];
          row.kept.emplace_back(slot, radii[k]);
          const Vec2 p = slots.point(slot);
          if (!std::isnan(p.x)) {
            row.points.push_back({static_cast<float>(p.x - grid.window.min_x),
                                  static_cast<float>(p.y - grid.window.min_y), slot + 1});
            continue;
          }
          const Site& site = *slots.get(slot);
          const auto* poly = std::get_if<PolygonSite>(&site.geometry);
          if (poly && poly->side != Side::kBoth) {
            // Scanned whole where its boundary comes near the tile; elsewhere present at all
            // of its centres (then as if it had no side) or at none.
            const Side where = TileCover::TileSide(grid, rect, site);
            if (where == Side::kBoth) {
              row.sites.push_back(slot);
              continue;
            }
            if (where != poly->side) continue;
          }
          needed.clear();
          TileCover::NeededSegments(grid, rect, site, upper, &needed);
          for (uint32_t j : needed) row.segments.push_back({slot, j});
        }
        row.leaves.push_back({rect.y0 / kTile * tiles_x + rect.x0 / kTile,
                              {static_cast<uint32_t>(row.points.size()),
                               static_cast<uint32_t>(row.sites.size()),
                               static_cast<uint32_t>(row.segments.size())}});
        row.kept_ends.push_back(static_cast<uint32_t>(row.kept.size()));
      };
      const uint32_t y0 = static_cast<uint32_t>(ty) * top;
      for (uint32_t x0 = 0; x0 < grid.width; x0 += top) {
        cover.CoverDown({x0, y0, std::min(x0 + top, grid.width), std::min(y0 + top, grid.height)},
                        kTile, leaf);
      }
    }
  });
  // Each tile's entries, in row-major tile order: counts, then offsets, then the entries.
  const size_t tiles = size_t{tiles_x} * tiles_y;
  std::vector<uint32_t> counts(3 * tiles, 0);
  for (const Row& row : rows) {
    uint32_t from[3] = {0, 0, 0};
    for (const Leaf& l : row.leaves) {
      for (int list = 0; list < 3; ++list) {
        counts[3 * l.tile + list] = l.ends[list] - from[list];
        from[list] = l.ends[list];
      }
    }
  }
  lists->offsets.assign(3 * (tiles + 1), 0);
  for (size_t t = 0; t < tiles; ++t) {
    for (int list = 0; list < 3; ++list) {
      lists->offsets[3 * t + 3 + list] = lists->offsets[3 * t + list] + counts[3 * t + list];
    }
  }
  lists->points.resize(lists->offsets[3 * tiles]);
  lists->sites.resize(lists->offsets[3 * tiles + 1]);
  lists->segments.resize(lists->offsets[3 * tiles + 2]);
  Coverage cov;
  cov.tile_px = kTile;
  cov.radius.assign(slots.size(), -1);
  cov.clip.assign(slots.size(), PixelRect{});
  for (const Row& row : rows) {
    uint32_t from[3] = {0, 0, 0}, kept = 0;
    for (size_t n = 0; n < row.leaves.size(); ++n) {
      const Leaf& l = row.leaves[n];
      const PixelRect rect{l.tile % tiles_x * kTile, l.tile / tiles_x * kTile,
                           std::min(l.tile % tiles_x * kTile + kTile, grid.width),
                           std::min(l.tile / tiles_x * kTile + kTile, grid.height)};
      std::copy(row.points.begin() + from[0], row.points.begin() + l.ends[0],
                lists->points.begin() + lists->offsets[3 * l.tile]);
      std::copy(row.sites.begin() + from[1], row.sites.begin() + l.ends[1],
                lists->sites.begin() + lists->offsets[3 * l.tile + 1]);
      std::copy(row.segments.begin() + from[2], row.segments.begin() + l.ends[2],
                lists->segments.begin() + lists->offsets[3 * l.tile + 2]);
      std::copy(l.ends, l.ends + 3, from);
      for (; kept < row.kept_ends[n]; ++kept) {
        const auto [slot, radius] = row.kept[kept];
        cov.radius[slot] = std::max(cov.radius[slot], radius);
        cov.clip[slot] = cov.clip[slot].Union(rect);
        ++cov.pairs;
      }
    }
  }
  return cov;
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
  Rasterizer::TileLists lists;
  if (compute) {
    cov = TileCandidates(grid_, slots, drawn_->index(), &lists);
  } else {
    cov = ParallelCoverage(grid_, *drawn_, grid_.all(), params_.diagram,
                           params_.mode == RenderMode::kMesh);
  }
  double coverage_seconds = Seconds(start);
  std::vector<SiteDraw> draws;
  double max_value = 0, area = 0;
  uint32_t max_segments = 0;
  tally_.Reset();
  extent_.assign(slots.size(), -1);
  for (uint32_t s = 0; s < slots.size(); ++s) {
    const Site* site = slots.get(s);
    if (site == nullptr) continue;
    tally_.Live(*site);
    if (cov.radius[s] < 0) continue;
    SiteDraw& d = draws.emplace_back(SiteDraw{s, cov.radius[s], cov.clip[s]});
    if (s < cov.pieces.size()) d.pieces = std::move(cov.pieces[s]);
    SiteShape shape = rasterizer.Shape(grid_, params_, *site, d);
    extent_[s] = ClippedExtent(grid_, site->geometry, shape.extent, d.clip);
    max_value = std::max(max_value, shape.max_value);
    max_segments = std::max(max_segments, shape.segments);
    tally_.Drawn(grid_, *site, shape);
    area += shape.area;
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
    // The lists' other sites index the draws, which are in slot order.
    std::vector<uint32_t> draw_of(slots.size(), 0);
    for (uint32_t k = 0; k < draws.size(); ++k) draw_of[draws[k].slot] = k;
    for (uint32_t& c : lists.sites) c = draw_of[c];
    for (Rasterizer::Segment& c : lists.segments) c.site = draw_of[c.site];
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
  Publish(grid_.all(), ids, distances);
  if (stats) {
    stats->cone_segments = max_segments;
    stats->sites_drawn = draws.size();
    stats->fill_ratio = compute ? 0 : area / (grid_.window.width() * grid_.window.height());
    stats->computed = compute;
    stats->candidates_per_pixel =
        compute ? double(cov.pairs) * Rasterizer::kComputeTile * Rasterizer::kComputeTile /
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

  // Past a few dozen windows, finding and merging them costs more than drawing everything.
  constexpr size_t kMaxWindows = 64;
  if (placed.size() + dirty.size() > kMaxWindows) return RenderAll(rasterizer, stats);

  auto start = std::chrono::steady_clock::now();
  // 2. Where can each placed site be nearest now? Outside the old pieces' windows no pixel's
  //    best value grew, so a pixel p the site wins has m d(p, site) + a <= D(p) + slack:
  //    only tiles whose nearest point to the site passes that against their largest stored
  //    value, and within its presence, qualify. (Inside those windows everything is
  //    recomputed anyway.)
  const ErrorModel& err = frame_->error();
  const double margin = DrawMargin(grid_);
  struct Window_ {
    PixelRect rect;
    bool clear;                   // holds an old piece's reach: redraw from scratch
    std::vector<SiteDraw> added;  // else: draw these over what is there
  };
  std::vector<Window_> windows;
  for (const PixelRect& d : dirty) windows.push_back({d, true, {}});
  for (uint32_t s : placed) {
    const Site& site = *slots.get(s);
    double radius = -1;
    PixelRect grown;
    for (uint32_t ty = 0; ty < frame_->tiles_y(); ++ty) {
      for (uint32_t tx = 0; tx < frame_->tiles_x(); ++tx) {
        PixelRect rect{tx * Frame::kTile, ty * Frame::kTile,
                       std::min((tx + 1) * Frame::kTile, grid_.width),
                       std::min((ty + 1) * Frame::kTile, grid_.height)};
        Window box = grid_.CentreBox(rect);
        double m = frame_->tile_at(tx, ty).max_distance;
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
  uint64_t area = 0;
  for (const auto& w : windows) area += w.rect.area();
  if (area > grid_.pixel_count() / 2) return RenderAll(rasterizer, stats);

  // 3. Each window: cleared ones get every site that can be best there, with the coverage
  //    proof restricted to the window; the others only their new sites.
  std::vector<std::vector<SiteDraw>> draws(windows.size());
  uint32_t tile_px = 0;
  for (size_t w = 0; w < windows.size(); ++w) {
    if (!windows[w].clear) {
      draws[w] = std::move(windows[w].added);
      continue;
    }
    Coverage cov = ComputeCoverage(grid_, slots, drawn_->index(), windows[w].rect,
                                   DefaultTilePx(grid_, drawn_->size(), drawn_->ink()),
                                   params_.diagram, params_.mode == RenderMode::kMesh);
    tile_px = cov.tile_px;
    for (uint32_t s = 0; s < slots.size(); ++s) {
      if (cov.radius[s] < 0) continue;
      SiteDraw& d = draws[w].emplace_back(SiteDraw{s, cov.radius[s], cov.clip[s]});
      if (s < cov.pieces.size()) d.pieces = std::move(cov.pieces[s]);
    }
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
      SiteShape shape = rasterizer.Shape(grid_, params_, site, d);
      max_value = std::max(max_value, shape.max_value);
      max_segments = std::max(max_segments, shape.segments);
      fill += shape.area;
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
  for (size_t w = 0; w < windows.size(); ++w) {
    const PixelRect& rect = windows[w].rect;
    auto draw_start = std::chrono::steady_clock::now();
    if (auto s = rasterizer.Draw(grid_, params_, rect, windows[w].clear, slots, draws[w],
                                 *target_);
        !s.ok()) {
      return s;
    }
    std::vector<uint32_t> ids;
    std::vector<float> distances;
    auto read_start = std::chrono::steady_clock::now();
    draw_seconds += std::chrono::duration<double>(read_start - draw_start).count();
    if (auto s = rasterizer.ReadBack(*target_, rect, params_.depth_scale, &ids, &distances);
        !s.ok()) {
      return s;
    }
    readback_seconds += Seconds(read_start);
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
  if (stats) {
    stats->cone_segments = max_segments;
    stats->sites_drawn = drawn;
    stats->fill_ratio = fill / (grid_.window.width() * grid_.window.height());
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
