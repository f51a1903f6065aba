#include "render/plan/scan.h"

#include <algorithm>
#include <cmath>

#include "render/kernel/exact2.h"
#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

// What ScanTile reads.
struct ScanInput {
  const TileLists& lists;
  const std::vector<ComputeSite>& sites;
  const std::vector<glm::vec4>& segments;
  float pw, ph;  // a pixel's size
  float margin;  // DrawMargin
};

constexpr uint32_t kScanPixels = kScanTile * kScanTile;

// nearest.comp for one tile (t, at pixel x0, y0), as native code: each pixel centre gets the
// least value among the tile's candidates present there, ties to the lower id (plain points
// compared by squared distance), in float from the same inputs; id 0 and +infinity where no
// candidate is present. Each candidate is taken over the whole tile at once, so that the
// pixels' loops vectorize. (Compiled for AVX2 as well, chosen at run time, it was no faster
// on the build machine: 1,000 cubic Beziers at 1024x1024 took 49-52 ms either way.)
void ScanTile(const ScanInput& in, size_t t, uint32_t x0, uint32_t y0, float* best,
              uint32_t* id) {
  constexpr uint32_t kTile = kScanTile, kPixels = kScanPixels;
  alignas(32) float px[kPixels], py[kPixels], xs[kTile], ys[kTile], d2[kPixels];
  alignas(32) int32_t winding[kPixels];
  const TileLists& lists = in.lists;
  for (uint32_t i = 0; i < kTile; ++i) {
    xs[i] = (static_cast<float>(x0 + i) + 0.5f) * in.pw;
    ys[i] = (static_cast<float>(y0 + i) + 0.5f) * in.ph;
  }
  std::fill(best, best + kPixels, INFINITY);
  std::fill(id, id + kPixels, 0u);
  const uint32_t* at = &lists.offsets[3 * t];  // where each list of the tile starts
  const uint32_t* next = at + 3;               // and ends
  // Plain points, by squared distance, row by row. They come in ascending id order, so the
  // first least value is the lowest id's: no tie needs its ids compared.
  for (uint32_t k = at[0]; k < next[0]; ++k) {
    const TileLists::Point q = lists.points[k];
    for (uint32_t j = 0; j < kTile; ++j) {
      const float dy = ys[j] - q.y, dy2 = dy * dy;
      float* row = best + j * kTile;
      uint32_t* row_id = id + j * kTile;
      for (uint32_t i = 0; i < kTile; ++i) {
        const float dx = xs[i] - q.x;
        const float dd = dx * dx + dy2;
        const bool better = dd < row[i];
        row[i] = better ? dd : row[i];
        row_id[i] = better ? q.id : row_id[i];
      }
    }
  }
  for (uint32_t i = 0; i < kPixels; ++i) best[i] = std::sqrt(best[i]);
  if (at[1] == next[1] && at[2] == next[2]) return;
  // The other sites compare values.
  for (uint32_t j = 0; j < kTile; ++j) {
    for (uint32_t i = 0; i < kTile; ++i) {
      px[j * kTile + i] = xs[i];
      py[j * kTile + i] = ys[j];
    }
  }
  // The least distance from each pixel to the segment (a, b) into d2, squared, and its
  // crossing of a ray towards +x into `winding` (when `side`): 1 upwards, -1 downwards.
  auto visit = [&](const glm::vec4& s, bool side) {
    const float ax = s.x, ay = s.y, abx = s.z - s.x, aby = s.w - s.y;
    const float len2 = abx * abx + aby * aby;
    const float inv = len2 > 0 ? 1 / len2 : 0;
    for (uint32_t i = 0; i < kPixels; ++i) {
      const float apx = px[i] - ax, apy = py[i] - ay;
      const float u = std::clamp((apx * abx + apy * aby) * inv, 0.0f, 1.0f);
      const float dx = apx - u * abx, dy = apy - u * aby;
      d2[i] = std::min(d2[i], dx * dx + dy * dy);
    }
    if (!side) return;
    const int32_t up = s.w > s.y ? 1 : -1;
    for (uint32_t i = 0; i < kPixels; ++i) {
      if ((s.y > py[i]) != (s.w > py[i]) &&
          px[i] < s.x + (py[i] - s.y) / (s.w - s.y) * (s.z - s.x)) {
        winding[i] += up;
      }
    }
  };
  // A site's value from the least distance in d2, as nearest.comp takes it.
  auto take = [&](const ComputeSite& s, bool side) {
    const float m = s.weight.x, a = s.weight.y, reach = s.weight.z;
    const uint32_t site = s.info.x;
    const bool want_inside = (s.info.w & 3) == 2, nonzero = (s.info.w & 4) != 0;
    for (uint32_t i = 0; i < kPixels; ++i) {
      const float d = std::sqrt(d2[i]);
      const float value = m * d + a;
      bool present = d <= reach;
      const bool inside = nonzero ? winding[i] != 0 : (winding[i] & 1) != 0;
      if (side) present = present && (d <= in.margin || inside == want_inside);
      const bool better = value < best[i] || (value == best[i] && site < id[i]);
      best[i] = present && better ? value : best[i];
      id[i] = present && better ? site : id[i];
    }
  };
  // Sites scanned whole.
  for (uint32_t k = at[1]; k < next[1]; ++k) {
    const ComputeSite& s = in.sites[lists.sites[k]];
    const bool side = (s.info.w & 3) != 0;
    std::fill(d2, d2 + kPixels, INFINITY);
    std::fill(winding, winding + kPixels, 0);
    for (uint32_t g = s.info.y; g < s.info.y + s.info.z; ++g) visit(in.segments[g], side);
    take(s, side);
  }
  // Single segments, a site's next to each other: the least over them, then its value.
  for (uint32_t k = at[2]; k < next[2];) {
    const uint32_t site = lists.segments[k].site;
    const ComputeSite& s = in.sites[site];
    std::fill(d2, d2 + kPixels, INFINITY);
    for (; k < next[2] && lists.segments[k].site == site; ++k) {
      visit(in.segments[s.info.y + lists.segments[k].index], false);
    }
    take(s, false);
  }
}

}  // namespace

PerFragmentSite PerFragmentOf(const Site& site, uint32_t id, double reach, Vec2 origin,
                              std::vector<glm::vec4>* segments) {
  auto rel = [&](Vec2 p) { return glm::vec2(p - origin); };
  uint32_t first = static_cast<uint32_t>(segments->size()), count = 0;
  ForEachSegment(site.geometry, [&](Vec2 p, Vec2 q) {
    segments->emplace_back(rel(p), rel(q));
    ++count;
  });
  const Side where = SideOf(site.geometry);
  uint32_t side = where == Side::kOutside ? 1 : where == Side::kInside ? 2 : 0;
  if (const auto* path = std::get_if<PathSite>(&site.geometry)) {
    if (path->fill == FillRule::kNonZero) side |= 4;
  }
  return {(*segments)[first],
          glm::vec3(site.multiplicative, site.additive, reach),
          glm::uvec4(id, first, count, side)};
}

ScanSites ScanSitesOf(const Grid& grid, const DrawParams& params, const SlotTable& slots,
                      const std::vector<SiteDraw>& draws) {
  ScanSites out;
  out.sites.reserve(draws.size());
  const Vec2 origin{grid.window.min_x, grid.window.min_y};
  for (const SiteDraw& d : draws) {
    // Plain points are scanned from the lists' own points: their records are never read.
    if (!std::isnan(slots.point(d.slot).x)) {
      out.sites.emplace_back();
      continue;
    }
    const Site& site = *slots.get(d.slot);
    const SiteShape shape = ShapeOf(grid, params, site, d);
    PerFragmentSite f = PerFragmentOf(site, d.slot + 1, shape.extent, origin, &out.segments);
    out.sites.push_back({f.first, glm::vec4(f.weight, 0), f.info});
  }
  return out;
}

void ScanTiles(const Grid& grid, PixelRect rect, const TileLists& lists, const ScanSites& sites,
               float none, std::vector<uint32_t>* ids, std::vector<float>* values) {
  const float margin = static_cast<float>(DrawMargin(grid));
  const PixelRect region = ScanTilesAround(grid, rect);
  const uint32_t tiles_x = (region.width() + kScanTile - 1) / kScanTile;
  const uint32_t tiles_y = (region.height() + kScanTile - 1) / kScanTile;
  const ScanInput in{lists, sites.sites, sites.segments, static_cast<float>(grid.pixel_width()),
                     static_cast<float>(grid.pixel_height()), margin};
  ids->resize(rect.area());
  values->resize(rect.area());
  // Rows of tiles in pieces of some 64 tiles at least: a small window's on this thread.
  ParallelFor(tiles_y, std::max<size_t>(1, 64 / tiles_x), [&](size_t begin, size_t end) {
    alignas(32) float best[kScanPixels];
    alignas(32) uint32_t id[kScanPixels];
    for (size_t ty = begin; ty < end; ++ty) {
      const uint32_t y0 = region.y0 + static_cast<uint32_t>(ty) * kScanTile;
      for (uint32_t tx = 0; tx < tiles_x; ++tx) {
        const uint32_t x0 = region.x0 + tx * kScanTile;
        ScanTile(in, ty * tiles_x + tx, x0, y0, best, id);
        for (uint32_t y = std::max(y0, rect.y0); y < std::min(y0 + kScanTile, rect.y1); ++y) {
          for (uint32_t x = std::max(x0, rect.x0); x < std::min(x0 + kScanTile, rect.x1); ++x) {
            const size_t i = size_t{y - rect.y0} * rect.width() + (x - rect.x0);
            const uint32_t k = (y - y0) * kScanTile + (x - x0);
            (*ids)[i] = id[k];
            (*values)[i] = id[k] == 0 ? none : best[k];
          }
        }
      }
    }
  });
}

void OverFrame(const Frame& frame, PixelRect rect, std::vector<uint32_t>* ids,
               std::vector<float>* values) {
  for (uint32_t j = rect.y0, k = 0; j < rect.y1; ++j) {
    for (uint32_t i = rect.x0; i < rect.x1; ++i, ++k) {
      const uint32_t below = frame.id_at(i, j);
      const float value = frame.distance_at(i, j);
      const uint32_t over = (*ids)[k];
      if (below != 0 &&
          (over == 0 || value < (*values)[k] || (value == (*values)[k] && below < over))) {
        (*ids)[k] = below;
        (*values)[k] = value;
      }
    }
  }
}

}  // namespace gvd
