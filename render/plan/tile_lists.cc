#include "render/plan/tile_lists.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <span>
#include <utility>

#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

constexpr uint32_t kTile = kScanTile;

// Lists being built for a run of the scan's tiles (a row of top tiles, or a window), in the
// order their leaves come; Assemble puts them in row-major order.
struct Run {
  struct Leaf {
    uint32_t tile;     // row-major index among the region's tiles
    uint32_t ends[3];  // where its points, sites and segments end in the run's lists
  };
  std::vector<Leaf> leaves;
  std::vector<TileLists::Point> points;
  std::vector<uint32_t> sites;
  std::vector<TileLists::Segment> segments;
  // Each (tile, site) pair once: the slot and the radius it needs there; left empty unless
  // `pairs`, for runs whose caller does not read them.
  bool pairs = true;
  std::vector<std::pair<uint32_t, double>> kept;
  std::vector<uint32_t> kept_ends;  // per leaf
  std::vector<uint32_t> needed;     // scratch

  // Tile `tile` (`rect`) gets the sites `kept` (slots), which can be best at its centres
  // with values at most `upper` there: plain points in its points, the others' segments that
  // can hold their nearest points (or the whole site, for a polygon restricted to a side
  // whose boundary comes near), named by `name`(slot).
  template <class Name>
  void Add(const Grid& grid, const SlotTable& slots, uint32_t tile, PixelRect rect,
           std::span<const uint32_t> kept_slots, std::span<const double> radii, double upper,
           Name&& name) {
    const size_t first_point = points.size();
    for (size_t k = 0; k < kept_slots.size(); ++k) {
      const uint32_t slot = kept_slots[k];
      if (pairs) kept.emplace_back(slot, radii[k]);
      const Vec2 p = slots.point(slot);
      if (!std::isnan(p.x)) {
        points.push_back({static_cast<float>(p.x - grid.window.min_x),
                          static_cast<float>(p.y - grid.window.min_y), slot + 1});
        continue;
      }
      const Site& site = *slots.get(slot);
      if (const Side side = SideOf(site.geometry); side != Side::kBoth) {
        // Scanned whole where its boundary comes near the tile; elsewhere present at all of
        // its centres (then as if it had no side) or at none.
        const Side where = TileCover::TileSide(grid, rect, site);
        if (where == Side::kBoth) {
          sites.push_back(name(slot));
          continue;
        }
        if (where != side) continue;
      }
      needed.clear();
      TileCover::NeededSegments(grid, rect, site, upper, &needed);
      for (uint32_t j : needed) segments.push_back({name(slot), j});
    }
    // By id, so that the scan's first least value is the lowest id's (its tie rule).
    std::sort(points.begin() + static_cast<ptrdiff_t>(first_point), points.end(),
              [](const TileLists::Point& a, const TileLists::Point& b) { return a.id < b.id; });
    leaves.push_back({tile,
                      {static_cast<uint32_t>(points.size()), static_cast<uint32_t>(sites.size()),
                       static_cast<uint32_t>(segments.size())}});
    kept_ends.push_back(static_cast<uint32_t>(kept.size()));
  }
};

// The scan's tile `tile` of `region` (ScanTilesAround's), row-major.
PixelRect TileRect(PixelRect region, uint32_t tiles_x, uint32_t tile) {
  const uint32_t x0 = region.x0 + tile % tiles_x * kTile, y0 = region.y0 + tile / tiles_x * kTile;
  return {x0, y0, std::min(x0 + kTile, region.x1), std::min(y0 + kTile, region.y1)};
}

uint32_t TilesAcross(PixelRect region) { return (region.width() + kTile - 1) / kTile; }

// The runs' lists into `lists`, in row-major order of the region's tiles; calls kept(slot,
// radius, tile's rect) for each (tile, site) pair.
template <class Kept>
void Assemble(const std::vector<Run>& runs, PixelRect region, TileLists* lists, Kept&& kept) {
  const uint32_t tiles_x = TilesAcross(region);
  const size_t tiles = size_t{tiles_x} * ((region.height() + kTile - 1) / kTile);
  // Each tile's entries: counts, then offsets, then the entries.
  std::vector<uint32_t> counts(3 * tiles, 0);
  for (const Run& run : runs) {
    uint32_t from[3] = {0, 0, 0};
    for (const Run::Leaf& l : run.leaves) {
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
  for (const Run& run : runs) {
    uint32_t from[3] = {0, 0, 0}, k = 0;
    for (size_t n = 0; n < run.leaves.size(); ++n) {
      const Run::Leaf& l = run.leaves[n];
      std::copy(run.points.begin() + from[0], run.points.begin() + l.ends[0],
                lists->points.begin() + lists->offsets[3 * l.tile]);
      std::copy(run.sites.begin() + from[1], run.sites.begin() + l.ends[1],
                lists->sites.begin() + lists->offsets[3 * l.tile + 1]);
      std::copy(run.segments.begin() + from[2], run.segments.begin() + l.ends[2],
                lists->segments.begin() + lists->offsets[3 * l.tile + 2]);
      std::copy(l.ends, l.ends + 3, from);
      const PixelRect rect = TileRect(region, tiles_x, l.tile);
      for (; k < run.kept_ends[n]; ++k) kept(run.kept[k].first, run.kept[k].second, rect);
    }
  }
}

}  // namespace

uint64_t TileLists::pairs() const {
  uint64_t n = points.size() + sites.size();
  for (size_t t = 0; t + 1 < offsets.size() / 3; ++t) {
    for (uint32_t k = offsets[3 * t + 2]; k < offsets[3 * t + 5]; ++k) {
      n += k == offsets[3 * t + 2] || segments[k].site != segments[k - 1].site;
    }
  }
  return n;
}

PixelRect ScanTilesAround(const Grid& grid, PixelRect rect) {
  return {rect.x0 / kTile * kTile, rect.y0 / kTile * kTile,
          std::min((rect.x1 + kTile - 1) / kTile * kTile, grid.width),
          std::min((rect.y1 + kTile - 1) / kTile * kTile, grid.height)};
}

Coverage TileCandidates(const Grid& grid, const SlotTable& slots, const SiteIndex& index,
                        TileLists* lists) {
  const uint32_t tiles_x = (grid.width + kTile - 1) / kTile;
  // A scene of plain points only: each tile on its own from a uniform grid of the points.
  // Else tiles of TopTilePx from the index, split down.
  const std::unique_ptr<const PointCover> points = PointCover::Of(grid, slots);
  const uint32_t top = points ? kTile : TopTilePx(grid, index.size(), kTile);
  const TileCover cover(grid, slots, index);
  const auto by_slot = [](uint32_t slot) { return slot; };
  const uint32_t rows_count = (grid.height + top - 1) / top;
  std::vector<Run> rows(rows_count);
  ParallelFor(rows_count, 1, [&](size_t begin, size_t end) {
    std::vector<uint32_t> kept_slots;
    std::vector<double> kept_radii;
    for (size_t ty = begin; ty < end; ++ty) {
      Run& row = rows[ty];
      const TileCover::Leaf leaf = [&](PixelRect rect, std::span<const uint32_t> kept,
                                       std::span<const double> radii, double upper) {
        row.Add(grid, slots, rect.y0 / kTile * tiles_x + rect.x0 / kTile, rect, kept, radii,
                upper, by_slot);
      };
      const uint32_t y0 = static_cast<uint32_t>(ty) * top;
      for (uint32_t x0 = 0; x0 < grid.width; x0 += top) {
        const PixelRect rect{x0, y0, std::min(x0 + top, grid.width),
                             std::min(y0 + top, grid.height)};
        if (points) {
          kept_slots.clear();
          kept_radii.clear();
          const double upper = points->Cover(rect, &kept_slots, &kept_radii);
          leaf(rect, kept_slots, kept_radii, upper);
        } else {
          cover.CoverDown(rect, kTile, leaf);
        }
      }
    }
  });
  Coverage cov;
  cov.tile_px = kTile;
  cov.radius.assign(slots.size(), -1);
  cov.clip.assign(slots.size(), PixelRect{});
  Assemble(rows, grid.all(), lists, [&](uint32_t slot, double radius, PixelRect rect) {
    cov.radius[slot] = std::max(cov.radius[slot], radius);
    cov.clip[slot] = cov.clip[slot].Union(rect);
    ++cov.pairs;
  });
  return cov;
}

std::vector<SiteDraw> WindowCandidates(const Grid& grid, const SlotTable& slots,
                                       const SiteIndex& index, PixelRect rect,
                                       TileLists* lists) {
  const PixelRect region = ScanTilesAround(grid, rect);
  const uint32_t tiles_x = TilesAcross(region);
  const uint32_t top = TopTilePx(grid, index.size(), kTile);
  const TileCover cover(grid, slots, index);
  // The sites kept, by slot: what the lists name until they are renamed below.
  const auto by_slot = [](uint32_t slot) { return slot; };
  std::vector<Run> run(1);
  const TileCover::Leaf leaf = [&](PixelRect leaf_rect, std::span<const uint32_t> kept,
                                   std::span<const double> radii, double upper) {
    const uint32_t tile = (leaf_rect.y0 - region.y0) / kTile * tiles_x +
                          (leaf_rect.x0 - region.x0) / kTile;
    run[0].Add(grid, slots, tile, leaf_rect, kept, radii, upper, by_slot);
  };
  for (uint32_t y0 = region.y0; y0 < region.y1; y0 += top) {
    for (uint32_t x0 = region.x0; x0 < region.x1; x0 += top) {
      cover.CoverDown({x0, y0, std::min(x0 + top, region.x1), std::min(y0 + top, region.y1)},
                      kTile, leaf);
    }
  }
  DrawsBySlot drawn;
  Assemble(run, region, lists, [&](uint32_t slot, double radius, PixelRect tile) {
    drawn.Add(slot, radius, tile);
  });
  std::vector<SiteDraw> draws = drawn.Take();
  auto draw_of = [&](uint32_t slot) {
    return static_cast<uint32_t>(
        std::lower_bound(draws.begin(), draws.end(), slot,
                         [](const SiteDraw& d, uint32_t s) { return d.slot < s; }) -
        draws.begin());
  };
  for (uint32_t& c : lists->sites) c = draw_of(c);
  for (TileLists::Segment& c : lists->segments) c.site = draw_of(c.site);
  return draws;
}

TileLists AddedCandidates(const Grid& grid, const SlotTable& slots, const Frame& frame,
                          PixelRect rect, std::span<const SiteDraw> added) {
  const PixelRect region = ScanTilesAround(grid, rect);
  const uint32_t tiles_x = TilesAcross(region);
  const uint32_t tiles_y = (region.height() + kTile - 1) / kTile;
  const ErrorModel& error = frame.error();
  std::vector<Run> run(1);
  run[0].pairs = false;
  std::vector<uint32_t> kept;
  std::vector<double> radii;
  for (uint32_t tile = 0; tile < tiles_x * tiles_y; ++tile) {
    const PixelRect tile_rect = TileRect(region, tiles_x, tile);
    kept.clear();
    radii.clear();
    for (const SiteDraw& d : added) {
      if (d.radius >= 0 && d.clip.Intersects(tile_rect)) {
        kept.push_back(d.slot);
        radii.push_back(d.radius);
      }
    }
    if (kept.empty()) continue;
    // The frame's values bound the values drawn over it: a site best at one of these
    // centres is below the greatest of them there.
    double upper = 0;
    for (uint32_t j = tile_rect.y0; j < tile_rect.y1; ++j) {
      for (uint32_t i = tile_rect.x0; i < tile_rect.x1; ++i) {
        upper = std::max(upper, static_cast<double>(frame.distance_at(i, j)));
      }
    }
    upper = error.UpperBound(upper);
    run[0].Add(grid, slots, tile, tile_rect, kept, radii, upper, [&](uint32_t slot) {
      for (uint32_t k = 0; k < added.size(); ++k) {
        if (added[k].slot == slot) return k;
      }
      return 0u;  // unreachable: every slot kept is one of added's
    });
  }
  TileLists lists;
  Assemble(run, region, &lists, [](uint32_t, double, PixelRect) {});
  return lists;
}

void IndexByDraw(const std::vector<SiteDraw>& draws, uint32_t slots, TileLists* lists) {
  std::vector<uint32_t> draw_of(slots, 0);
  for (uint32_t k = 0; k < draws.size(); ++k) draw_of[draws[k].slot] = k;
  for (uint32_t& c : lists->sites) c = draw_of[c];
  for (TileLists::Segment& c : lists->segments) c.site = draw_of[c.site];
}

}  // namespace gvd
