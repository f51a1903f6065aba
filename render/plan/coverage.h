// How far each site's distance mesh must reach (paper sec. 8: "bounding the site distance
// functions to a maximum distance"), so that a render fills a small multiple of the grid
// instead of sites x grid.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "render/kernel/diagram.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"
#include "render/scene/site_index.h"
#include "render/scene/snapshot.h"
#include "render/scene/site_view.h"
#include "render/scene/slot_table.h"

namespace gvd {

// One piece of a site's mesh (ForEachPiece, render/plan/distance_mesh.h), drawn on its own: it must
// cover every pixel centre within `radius` of its feature that lies in `clip` and where the
// feature holds the site's nearest point; radius < 0: none. A half-tent need only cover
// those whose projections on its edge ab lie from `from` to `to` (distances from a).
struct PieceDraw {
  double radius = -1;
  PixelRect clip;
  double from = INFINITY, to = -INFINITY;
};

// A site to draw: it must cover every pixel centre within `radius` of its geometry that lies
// in `clip` (a rectangle of the grid's pixels); outside it, no pixel is the site's. When
// `pieces` is not empty, each piece of its mesh (in ForEachPiece's order) needs only its own.
struct SiteDraw {
  uint32_t slot = 0;
  double radius = 0;
  PixelRect clip{0, 0, UINT32_MAX, UINT32_MAX};
  std::vector<PieceDraw> pieces;
};

struct Coverage {
  // radius[s] >= the distance from the site in slot s to every pixel centre of the region
  // whose exact nearest site it is (ties included); negative when it is nearest to none of
  // them (or the slot is free), so its mesh need not be drawn there.
  std::vector<double> radius;
  // clip[s] holds every pixel whose centre's exact nearest site s can be (the union of the
  // tiles that keep it), so its mesh need not be drawn outside; empty where radius < 0.
  std::vector<PixelRect> clip;
  // When asked for: pieces[s] for each site s other than a plain point, as
  // SiteDraw::pieces (see PieceCover in coverage.cc for when a tile needs a piece).
  std::vector<std::vector<PieceDraw>> pieces;
  uint32_t tile_px = 0;  // side of the smallest tiles used
  uint64_t pairs = 0;    // (tile, candidate site) pairs kept in the smallest tiles
};

// The side of the smallest tiles that ComputeCoverage uses by default for n sites on the
// grid: a power of two about a third of the sites' mean spacing, in pixels, within [1, 4], so
// that a site's clip is little more than its cell's box; and no more than half the mean
// distance between the sites' lines, `ink` being their summed length (SiteSnapshot::ink),
// so that where lines crowd (tangles), the pieces of their meshes are told apart.
uint32_t DefaultTilePx(const Grid& grid, size_t n, double ink = 0);

// The side of the tiles whose candidates are looked up in the index before they are split
// down to leaves of leaf_px: leaf_px times a power of two, about twice the sites' mean
// spacing, within [8, 64] (or leaf_px if that is larger).
uint32_t TopTilePx(const Grid& grid, size_t n, uint32_t leaf_px);

// Computes how far each site must reach to cover the pixel centres of `region` where it is
// best (nearest, or farthest in kFarthest), and where. `index` indexes `sites` by slot. Tiles of TopTilePx are looked up in the
// index and split down to leaves of tile_px (see TileCover::CoverDown): O(top tiles * log n +
// tiles * candidates per tile).
//
// What is drawn. A site s is drawn with value v_s(p) = m_s d(p, s) + a_s wherever it is
// "present": within max_distance + DrawMargin of its geometry and, for a polygon restricted to
// one side, on that side or within DrawMargin of its boundary. The drawn diagram takes the
// least (kNearest) or greatest (kFarthest) v over the sites present.
//
// Why the radii are enough (kNearest). Take a tile of the region, C the rectangle spanned by
// its pixel centres, c the centre of C and h its half-diagonal. A site s1 present on all of C
// gives U = m1 (d(c, s1) + h) + a1 >= v_s1(p) for every p of C; the least such U is taken over
// the nearest site to c and the sites within reach of it. A site s best at some p of C has
// v_s(p) <= U, so m_s max(0, d(c, s) - h) + a_s <= U: the others are dropped, as are sites
// not present anywhere near C (beyond max_distance + margin, or an inside-only polygon whose
// box, grown by the margin, misses C). For plain point sites s and s1, s must also be at least as near
// as s1 at p: p lies in the half-plane {x : |x s| <= |x s1|}; as C is convex, some corner of C
// lies in it too, and sites with no corner there are dropped. Every remaining candidate gets
// radius >= max over C of d(., s) (capped at its presence, max_distance + DrawMargin), so
// every pixel centre lies within the radius of each site best there. With no site present
// on all of C, every site present near C is kept.
//
// kFarthest, symmetrically: a site present on all of C gives L = m1 max(0, d(c, s1) - h) + a1
// <= v_s1(p) on C, and the greatest L is taken over every site. A site s best at some p of C
// has v_s(p) >= L, so m_s (d(c, s) + h) + a_s >= L; others are dropped, as are sites absent
// from C. A plain point s is also dropped when some plain point w (one farthest from a corner
// of C) is farther than s from every corner: {x : |x s| < |x w|} is a half-plane, so C lies
// in it, and s is nowhere the farthest. The radii are as for kNearest. The farthest sites are
// not found by nearness: the region is one tile, every site its candidate, split down.
//
// Why the smaller tiles are enough. A site best at some pixel centre of a half of a tile is
// best at that centre of the tile, so the tile's list holds it. The tests above drop a site
// only by comparing it with sites that are present (U, L) or plain points (the half-planes):
// any such sites give valid bounds, so taking them from the parent's list instead of the
// index can only keep more sites, never fewer. The clip of a site is the union of the
// smallest tiles that keep it, so it holds every pixel centre where the site is best.
// tests/render/plan/coverage_test.cc checks radii and clips pixel by pixel against the oracle.
// CONTRACT: index holds exactly the live slots of the table, at least one.
Coverage ComputeCoverage(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                         PixelRect region, uint32_t tile_px = 0,
                         Diagram diagram = Diagram::kNearest, bool pieces = false);


// The proof above for one tile at a time, for renders that keep a candidate list
// per tile (the compute path) and for ComputeCoverage itself. Thread-safe: tiles may be
// covered concurrently. CONTRACT: as ComputeCoverage's; the grid, table and index outlive it.
class TileCover {
 public:
  TileCover(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
            Diagram diagram = Diagram::kNearest);

  // Appends to `slots` every site that can be best at some pixel centre of `tile` (a
  // non-empty rectangle of the grid's pixels), in no particular order, and to `radii` the
  // radius it needs there: at least its distance from every pixel centre of the tile, capped
  // at its presence (max_distance + DrawMargin).
  void Cover(PixelRect tile, std::vector<uint32_t>* slots, std::vector<double>* radii) const;

  // The same for `tile` from `candidates` instead of the index: those of them that pass the
  // tests on `tile` (radii left alone when null). CONTRACT: `candidates` holds every site
  // that can be best at some pixel centre of `tile`, such as the list of a tile holding it:
  // the tests only drop sites, never add any.
  // Returns U: an upper bound on the best drawn value at every centre of the tile (INFINITY
  // when no candidate is present on the whole of it); in kFarthest, L: a lower bound on it
  // (-INFINITY when none is).
  double Keep(PixelRect tile, std::span<const uint32_t> candidates, std::vector<uint32_t>* slots,
              std::vector<double>* radii) const;

  // Covers `tile` from the index, then splits it in halves along each side longer than
  // leaf_px (at multiples of leaf_px from its corner), each half keeping of its parent's list
  // what passes on it, down to tiles of at most leaf_px a side: calls leaf(rect, slots, radii,
  // U) once for each of those, in row-major order within each split. O(log n + the lists).
  using Leaf = std::function<void(PixelRect, std::span<const uint32_t>, std::span<const double>,
                                  double)>;
  void CoverDown(PixelRect tile, uint32_t leaf_px, const Leaf& leaf) const;

  // The radius a site needs over `box` (a rectangle of pixel centres).
  double RadiusFor(const SiteView& s, const Window& box) const;

  // Of a site that Keep kept for `tile`, where it returned `upper` (U), the segments (their
  // indices in ForEachSegment order, each once, appended to `out`) that can hold
  // the site's nearest point at a pixel centre of the tile where the site can be best.
  //
  // Why that is enough. With c the middle of the tile's centres and h their half-diagonal,
  // segment j at d_j from c is between d_j - h and d_j + h from every centre p, so the site
  // is within N = min_j d_j + h of each p. The segment holding the site's nearest point to p
  // is within N of p, so d_j - h <= N; and where the site is best, its value there is at most
  // U, so m max(0, d_j - h) + a <= U. A segment failing either test holds the site's nearest
  // point at no centre where the site can be best. So the least distance over the segments
  // kept is the site's distance at every centre where it can be best, and no less than it
  // anywhere: a scan over them finds the same best site and value at every centre as a scan
  // over all of them. (A polygon restricted to a side needs all of its edges for the
  // even-odd test; this gives the others' segments.) O(log n) with a segment tree.
  static void NeededSegments(const Grid& grid, PixelRect tile, const Site& site, double upper,
                             std::vector<uint32_t>* out);

  // For a polygon or a path: Side::kInside (kOutside) when every pixel centre of `tile` lies
  // inside (outside) it and farther than DrawMargin from its drawn boundary, so that a site
  // restricted to a side is present at all of them or at none; Side::kBoth when the boundary
  // comes nearer. CONTRACT: the site is a polygon or a path.
  static Side TileSide(const Grid& grid, PixelRect tile, const Site& site);

 private:
  const Grid& grid_;
  const SlotTable& sites_;
  const SiteIndex& index_;
  // How far from its bounding box any site is present, less DrawMargin (infinite when some
  // site is present everywhere): for the tiles with no site present on the whole of them.
  // Computed on first use, O(sites).
  double PresenceReach() const;
  // Appends to `out` the sites the index finds near `tile` (a superset of Cover's).
  void Candidates(PixelRect tile, std::vector<uint32_t>* out) const;
  void Descend(PixelRect tile, std::span<const uint32_t> parent, uint32_t leaf_px, size_t depth,
               const Leaf& leaf) const;
  // Keep, for one diagram.
  template <Diagram kDiagram>
  double KeepIn(PixelRect tile, std::span<const uint32_t> candidates,
                std::vector<uint32_t>* slots, std::vector<double>* radii) const;

  const Diagram diagram_;
  const LeastWeights least_;
  const double margin_;
  mutable std::once_flag reach_once_;
  mutable double reach_ = INFINITY;
};

// The proof above for scenes whose live sites are all plain points (Site::plain), in a
// kNearest diagram, with a uniform grid of buckets in place of the index and the tests done
// on squared distances: what the computed full render of a point scene spends its lists on.
// Per tile: the point nearest to the middle c of its centres (by rings of buckets), which
// gives U; the points within U + h of c (the buckets that square of side 2 (U + h) meets);
// of those, the ones not beaten at all four corners by one of five points (the nearest to
// each corner and to c). A point is dropped only where Keep's tests (on distances, with
// their rounding slack) drop it with the same witnesses, so every point that can be nearest
// at one of the tile's centres is kept. Points outside the window lie in the buckets at its
// edge, where they are no nearer than they are.
// Thread-safe: tiles may be covered concurrently. CONTRACT: the grid and table outlive it.
class PointCover {
 public:
  // Null when the table holds no live site, or one that is not a plain point; and where
  // squared distances could underflow or overflow (a pixel under 2^-400, coordinates over
  // 2^400), or more than a quarter of the points lie outside the window. O(slots).
  static std::unique_ptr<const PointCover> Of(const Grid& grid, const SlotTable& sites);

  // As TileCover::Cover for `tile` (a non-empty rectangle of the grid's pixels): appends
  // every point that can be nearest at one of its centres, and the radius it needs there (its
  // distance from the farthest centre). Returns U (Keep's).
  double Cover(PixelRect tile, std::vector<uint32_t>* slots, std::vector<double>* radii) const;

 private:
  PointCover(const Grid& grid, uint32_t bucket_px);
  // The bucket column (row) of x (y), clamped to the grid's buckets.
  uint32_t Column(double x) const;
  uint32_t Row(double y) const;

  const Grid& grid_;
  uint32_t columns_ = 0, rows_ = 0;
  double bucket_w_ = 0, bucket_h_ = 0;  // in the plane
  // Bucket b holds points [start_[b], start_[b + 1]) of x_, y_, slot_ (row-major buckets,
  // each in slot order).
  std::vector<uint32_t> start_;
  std::vector<double> x_, y_;
  std::vector<uint32_t> slot_;
};

// Draws gathered from (slot, radius, tile) pairs, each slot's merged into one: the greatest
// radius, the union of the tiles.
class DrawsBySlot {
 public:
  // The slot's draw, widened to `radius` and `tile`.
  SiteDraw& Add(uint32_t slot, double radius, PixelRect tile);
  // The draws, in slot order.
  std::vector<SiteDraw> Take();

 private:
  std::unordered_map<uint32_t, SiteDraw> drawn_;
};

// The same radii and clips as ComputeCoverage, as draws in slot order: for a small region of
// a large scene (a zoom window), whose cost then depends on the region and the sites near
// it, not on the scene's size (but for kFarthest, whose first tile tests every site).
std::vector<SiteDraw> SparseCoverage(const Grid& grid, const SlotTable& sites,
                                     const SiteIndex& index, PixelRect region, uint32_t tile_px,
                                     Diagram diagram, bool pieces = false);

// ComputeCoverage of `region` for the snapshot's sites, at its default tile sizes
// (DefaultTilePx), in bands of TopTilePx rows covered in parallel on the CPU pool: the tiles,
// and so the radii and clips, are the same as in one pass.
Coverage ParallelCoverage(const Grid& grid, const SiteSnapshot& snapshot, PixelRect region,
                          Diagram diagram, bool pieces);

}  // namespace gvd
