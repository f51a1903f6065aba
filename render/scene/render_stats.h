// What one render did and what it cost, as a renderer reports it (metrics, logs, benchmarks):
// a 2D scene's frame drawn by the render threads, or a 3D scene's volume scanned on the CPU.
#pragma once

#include <cstddef>
#include <cstdint>

#include "render/kernel/grid2.h"

namespace gvd {

struct RenderStats {
  uint32_t cone_segments = 0;  // triangles in the largest point cone of this render
  uint64_t sites_drawn = 0;    // sites nearest to some pixel centre
  double fill_ratio = 0;       // total area of the drawn meshes / area of the window
  uint32_t tile_px = 0;        // tile side of the coverage pass
  double coverage_seconds = 0; // spatial index and coverage radii
  double draw_seconds = 0;     // until the GPU finished drawing
  double readback_seconds = 0;
  PixelRect window;            // bounds the pixels redrawn and read back
  size_t windows = 0;          // separate windows redrawn
  uint64_t pixels = 0;         // pixels redrawn and read back (a volume's: voxels rendered)
  bool full = false;           // a render from scratch
  bool computed = false;       // by a scan of candidate lists (no mesh drawn); volumes always
  // When computed: the mean length of the candidate lists a pixel (voxel) scanned.
  double candidates_per_pixel = 0;
};

}  // namespace gvd
