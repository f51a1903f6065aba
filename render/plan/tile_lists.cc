#include "render/plan/tile_lists.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <span>
#include <utility>

#include "render/scene/cpu_pool.h"

namespace gvd {

Coverage TileCandidates(const Grid& grid, const SlotTable& slots, const SiteIndex& index,
                        TileLists* lists) {
  constexpr uint32_t kTile = kScanTile;
  const uint32_t tiles_x = (grid.width + kTile - 1) / kTile;
  const uint32_t tiles_y = (grid.height + kTile - 1) / kTile;
  // A scene of plain points only: each tile on its own from a uniform grid of the points.
  // Else tiles of TopTilePx from the index, split down.
  const std::unique_ptr<const PointCover> points = PointCover::Of(grid, slots);
  const uint32_t top = points ? kTile : TopTilePx(grid, index.size(), kTile);
  const TileCover cover(grid, slots, index);
  struct Leaf {
    uint32_t tile;  // row-major index of the compute tile
    uint32_t ends[3];  // where its points, sites and segments end in the row's lists
  };
  struct Row {
    std::vector<Leaf> leaves;
    std::vector<TileLists::Point> points;
    std::vector<uint32_t> sites;
    std::vector<TileLists::Segment> segments;
    // Each (tile, site) pair once: the slot and the radius it needs there.
    std::vector<std::pair<uint32_t, double>> kept;
    std::vector<uint32_t> kept_ends;  // per leaf
  };
  const uint32_t rows_count = (grid.height + top - 1) / top;
  std::vector<Row> rows(rows_count);
  ParallelFor(rows_count, 1, [&](size_t begin, size_t end) {
    std::vector<uint32_t> needed, kept_slots;
    std::vector<double> kept_radii;
    for (size_t ty = begin; ty < end; ++ty) {
      Row& row = rows[ty];
      const TileCover::Leaf leaf = [&](PixelRect rect, std::span<const uint32_t> kept,
                                       std::span<const double> radii, double upper) {
        const size_t first_point = row.points.size();
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
          if (const Side side = SideOf(site.geometry); side != Side::kBoth) {
            // Scanned whole where its boundary comes near the tile; elsewhere present at all
            // of its centres (then as if it had no side) or at none.
            const Side where = TileCover::TileSide(grid, rect, site);
            if (where == Side::kBoth) {
              row.sites.push_back(slot);
              continue;
            }
            if (where != side) continue;
          }
          needed.clear();
          TileCover::NeededSegments(grid, rect, site, upper, &needed);
          for (uint32_t j : needed) row.segments.push_back({slot, j});
        }
        // By id, so that the scan's first least value is the lowest id's (its tie rule).
        std::sort(row.points.begin() + static_cast<ptrdiff_t>(first_point), row.points.end(),
                  [](const TileLists::Point& a, const TileLists::Point& b) { return a.id < b.id; });
        row.leaves.push_back({rect.y0 / kTile * tiles_x + rect.x0 / kTile,
                              {static_cast<uint32_t>(row.points.size()),
                               static_cast<uint32_t>(row.sites.size()),
                               static_cast<uint32_t>(row.segments.size())}});
        row.kept_ends.push_back(static_cast<uint32_t>(row.kept.size()));
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


void IndexByDraw(const std::vector<SiteDraw>& draws, uint32_t slots, TileLists* lists) {
  std::vector<uint32_t> draw_of(slots, 0);
  for (uint32_t k = 0; k < draws.size(); ++k) draw_of[draws[k].slot] = k;
  for (uint32_t& c : lists->sites) c = draw_of[c];
  for (TileLists::Segment& c : lists->segments) c.site = draw_of[c.site];
}

}  // namespace gvd
