// Structure in a discrete Voronoi diagram (paper sec. 5): the boundaries between pixels of
// different sites, Voronoi neighbours, the Delaunay triangulation of point sites, and sites
// that own no pixel (sec. 6.2). Pure CPU work on an id image; thread-safe (no shared state).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "render/kernel/exact2.h"
#include "render/scene/frame.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"

namespace gvd {

// The ids of a rectangle of pixel centres, row-major from its min-y row: 0 is no site, else
// 1 + a slot of the frame's site table.
struct IdImage {
  Grid grid;  // the rectangle's own grid: its pixel centres are the frame's
  std::vector<uint32_t> ids;

  uint32_t width() const { return grid.width; }
  uint32_t height() const { return grid.height; }
  uint32_t at(uint32_t i, uint32_t j) const { return ids[size_t{j} * grid.width + i]; }
};

// The ids of `rect` of the frame. CONTRACT: rect is inside the grid and not empty; the
// frame is not empty.
IdImage IdsOf(const Frame& frame, PixelRect rect);

// The pairs of 4-adjacent pixel centres whose ids differ, as masks: horizontal[j * (w - 1) + i]
// is the pair (i, j)-(i + 1, j), vertical[j * w + i] the pair (i, j)-(i, j + 1).
struct BoundaryEdges {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> horizontal, vertical;
  size_t count = 0;  // pairs marked
  size_t cells_visited = 0;  // 2x2 cells the method looked at

  bool h(uint32_t i, uint32_t j) const { return horizontal[size_t{j} * (width - 1) + i]; }
  bool v(uint32_t i, uint32_t j) const { return vertical[size_t{j} * width + i]; }
};

enum class BoundaryMethod {
  // Every pair of adjacent pixels: O(pixels), finds every boundary.
  kFullScan,
  // Seeded at the pairs on the image's border, walks cell by cell along the boundary (paper
  // sec. 5, after Bloomenthal): O(boundary). Finds exactly the boundaries connected to the
  // border, which are all of them when the sites are convex (their diagram is connected and
  // unbounded); around a concave or curved site it can miss a boundary that closes on itself.
  kContinuation,
};

BoundaryEdges FindBoundaryEdges(const IdImage& image, BoundaryMethod method);

// A boundary between the regions of two ids, a < b (a = 0: where no site is a candidate).
// Its points are where it crosses the segments between adjacent pixel centres, located
// exactly (by the sites' exact values) wherever the two pixels' ids agree with them, else
// the midpoint; where three or more regions meet in a cell, a polyline ends at the mean of
// the cell's crossings. Open polylines end at such junctions or at the image's border.
struct BoundaryPolyline {
  uint32_t a = 0, b = 0;
  std::vector<Vec2> points;
  bool closed = false;
};

// The polylines through the marked pairs. `sites` is the table the ids index.
std::vector<BoundaryPolyline> TraceBoundaries(const IdImage& image, const BoundaryEdges& edges,
                                              const SlotTable& sites, Diagram diagram);

// Where the boundary between sites A (best at p) and B (best at q) crosses the segment pq:
// exact for two plain points, else by bisection on their exact values (null: no site).
// The midpoint when the values do not put A at p and B at q.
Vec2 BoundaryCrossing(Vec2 p, Vec2 q, const Site* a, const Site* b, Diagram diagram);

// Id pairs (a < b, both sites) with the number of marked pixel pairs between them.
using NeighborCounts = std::map<std::pair<uint32_t, uint32_t>, uint32_t>;
NeighborCounts NeighborPairs(const IdImage& image, const BoundaryEdges& edges);

// Whether some point of the site's geometry lies in the closed box.
bool GeometryMeetsBox(const Geometry& g, const Window& box);

// The live slots whose geometry meets the box spanned by the image's pixel centres (grown by
// half a pixel) but which hold no pixel of it (sec. 6.2: missing Voronoi regions).
std::vector<uint32_t> HiddenSites(const IdImage& image, const SlotTable& sites);

// The triangles of a planar triangulation given its edges: for each point, its neighbours in
// angular order; two consecutive neighbours b, c of a that are neighbours of each other, with
// a, b, c counter-clockwise, make the triangle (a, b, c). Each triangle once, its smallest
// index first, counter-clockwise. `points[i]` is point i; edges index it.
std::vector<std::array<uint32_t, 3>> TrianglesFromEdges(
    const std::vector<Vec2>& points, const std::vector<std::pair<uint32_t, uint32_t>>& edges);

}  // namespace gvd
