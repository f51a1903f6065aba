// The scan of a computed render, in native code: what the compute shader nearest.comp does on
// a GPU, done on the CPU pool where llvmpipe would run the shader on one thread, for a full
// render and for an incremental render's windows. Each pixel centre gets the least value
// among its tile's candidates (render/plan/tile_lists.h) present there, in float from the
// same inputs as the shader's. Also the per-fragment site record that the shaders
// (exact.vert, nearest.comp) and this scan read.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"
#include "render/plan/coverage.h"
#include "render/plan/site_shape.h"
#include "render/plan/tile_lists.h"
#include "render/scene/frame.h"
#include "render/scene/slot_table.h"

namespace gvd {

// A site drawn per fragment as exact.vert and nearest.comp take it: its first segment, (m,
// a, reach) and (id, index of the first segment, segment count, side), its segments appended
// to `segments`, all relative to `origin`.
struct PerFragmentSite {
  glm::vec4 first;
  glm::vec3 weight;
  glm::uvec4 info;
};
PerFragmentSite PerFragmentOf(const Site& site, uint32_t id, double reach, Vec2 origin,
                              std::vector<glm::vec4>* segments);

// nearest.comp's Site, std430: a site scanned per fragment.
struct ComputeSite {
  glm::vec4 first;   // its first segment
  glm::vec4 weight;  // (m, a, reach, unused)
  // (slot + 1, first segment, segment count, side: bits 0-1 0 both, 1 outside, 2 inside;
  // bit 2 the nonzero rule, else even-odd)
  glm::uvec4 info;
};
static_assert(sizeof(ComputeSite) == 12 * 4);

// The sites of a computed render as the scan reads them: draws[k]'s record in sites[k] (an
// unread one for a plain point, which the lists carry themselves), their segments relative to
// the window's min corner.
struct ScanSites {
  std::vector<ComputeSite> sites;
  std::vector<glm::vec4> segments;
};
ScanSites ScanSitesOf(const Grid& grid, const DrawParams& params, const SlotTable& slots,
                      const std::vector<SiteDraw>& draws);

// The ids and values of the pixel centres of `rect` (grid.all() for a full render), row-major,
// `none` where no candidate is present: nearest.comp's output, over the scan's tiles of
// ScanTilesAround(grid, rect), whose lists `lists` are, row-major over them. Runs on the CPU
// pool, tile by tile (a small window's on the calling thread). Thread-safe.
void ScanTiles(const Grid& grid, PixelRect rect, const TileLists& lists, const ScanSites& sites,
               float none, std::vector<uint32_t>* ids, std::vector<float>* values);

// The scan of sites drawn over `frame` in `rect` (ids and values as ScanTiles gives them):
// each pixel takes the frame's id and value instead where those are less, or equal with the
// lower id (the scan's tie rule), as drawing the sites over the frame would keep them.
void OverFrame(const Frame& frame, PixelRect rect, std::vector<uint32_t>* ids,
               std::vector<float>* values);

}  // namespace gvd
