// An immutable CPU copy of a rendered discrete Voronoi diagram: per pixel centre, the
// nearest site (by slot of the snapshot it was rendered from) and the distance to it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "geometry/exact.h"
#include "geometry/geometry.h"
#include "geometry/site.h"
#include "geometry/coverage.h"
#include "geometry/site_index.h"
#include "core/snapshot.h"

namespace gvd {

// How distance functions are drawn. kMesh: the paper's bounded-error meshes (a fan of
// triangles within eps for every vertex, two exact planes per edge), interpolated by the
// rasterizer. kExact: one quad per site whose fragments compute the site's distance
// analytically and write it as depth (no meshing error; no early depth test either).
// Some sites are drawn as in kExact whatever the mode, because one depth test cannot draw
// them from pieces: polygons restricted to one side (the fragment tests the side), and every
// site but a point in a kFarthest diagram (the site's value is the least over its pieces,
// the diagram's the greatest over sites).
enum class RenderMode { kMesh, kExact };

// How far a frame's stored values can be from the truth. Let v_B(p) = m_B d(p, B) + a_B be
// site B's value, ignoring its max_distance and side. Wherever B's pieces are drawn over a
// pixel centre p, their height satisfies
//   v_B(p) <= h_B(p) <= min(overestimate * v_B(p), v_B(p) + max_excess)
// (a fan's spokes lie on the cone, sec. 4.1.1; a tent is exact; a >= 0), and each pixel
// centre is covered by the pieces of every site best there among those present
// (geometry/coverage.h). The stored value D(p) is the least (kNearest) or greatest (kFarthest)
// height drawn there, up to the rasterizer's arithmetic: slack(D) = absolute_slack +
// relative_slack * D. A site that is a candidate at q is present at the pixel centres around
// q, and its value changes by at most lipschitz per unit of distance.
struct ErrorModel {
  Diagram diagram = Diagram::kNearest;
  double overestimate = 1;    // k >= 1
  double max_excess = 0;      // eps * the largest weight, scene units
  double absolute_slack = 0;  // scene units: sub-pixel vertex snapping and interpolation
  double relative_slack = 0;  // float depth and interpolation rounding, relative to D
  double lipschitz = 1;       // the largest multiplicative weight of any site
  double curve = 0;           // the largest Bezier tolerance * weight, added to every bound
  // Some site has a max_distance or a side: it is present (drawn) only within DrawMargin of
  // where it is a candidate.
  bool limited_presence = false;

  double Slack(double d) const { return absolute_slack + relative_slack * d; }
  // A lower bound on v_B(p) for every site B present at p, given the least stored value D
  // at p: the best site's height at p is at least D.
  double LowerBound(double d) const {
    return std::max(d / overestimate, d - max_excess) - Slack(d);
  }
  // An upper bound on v_B(p) for every site B present at p, given the greatest stored value
  // D at p: every height drawn is at least the value.
  double UpperBound(double d) const { return d + Slack(d); }
};

// The answer to a nearest-site (or farthest-site) query at a point.
struct NearestAnswer {
  uint32_t site_index = 0;  // a slot of Frame::sites()
  double distance = 0;      // that site's exact value at the query point
  double error_bound = 0;   // no site's value beats distance by more than error_bound
  bool found = true;        // false: no site is a candidate at the point (certain)
  // The value at q of the best other site stored around q (+inf, or -inf in kFarthest, when
  // there is none): when it is within error_bound of distance, either site may be the best.
  double runner_up = INFINITY;
  bool ambiguous() const {
    return found && error_bound > 0 && std::abs(runner_up - distance) <= error_bound;
  }
};

// For a large batch of query points (16,384 or more), their indices in the order of the
// frame tiles (Frame::kTile pixels a side) of `grid` they fall in, those outside the window
// last, so that a batch answered in that order keeps each tile's pixels and sites in cache;
// empty for a smaller batch, answered in its own order. A counting sort: O(points + tiles).
std::vector<uint32_t> OrderByTile(const Grid& grid, const std::vector<Vec2>& points);

// Immutable once made; shared between threads by shared_ptr. Pixels live in square tiles
// that later frames share, so a frame that changes a small window copies only its tiles.
class Frame {
 public:
  static constexpr uint32_t kTile = 32;
  struct Tile {
    uint32_t ids[kTile * kTile];
    float distances[kTile * kTile];
    float max_distance;  // over the tile's pixels inside the grid
  };

  // A frame of `sites` from whole-grid buffers, row-major from row 0 (min_y). ids are 0 (no
  // site) or 1 + a slot of `sites`.
  Frame(Grid grid, double eps, ErrorModel error, const uint32_t* ids, const float* distances,
        std::shared_ptr<const SiteSnapshot> sites);
  // A frame of `sites` equal to `base` outside `rect`; inside it, the values come from
  // row-major buffers of rect.width() x rect.height().
  Frame(const Frame& base, ErrorModel error, PixelRect rect, const uint32_t* ids,
        const float* distances, std::shared_ptr<const SiteSnapshot> sites);

  // A frame of no sites (`sites` must be empty) and no pixels.
  static std::shared_ptr<const Frame> Empty(Grid grid, double eps,
                                            std::shared_ptr<const SiteSnapshot> sites);

  const Grid& grid() const { return grid_; }
  // The version of the snapshot the frame was rendered from.
  uint64_t version() const { return snapshot_->version(); }
  double eps() const { return eps_; }
  const ErrorModel& error() const { return error_; }
  // The snapshot the frame was rendered from: its slots are the frame's ids, its index finds
  // the sites near a point, and every answer read from the frame is of this version.
  const SiteSnapshot& snapshot() const { return *snapshot_; }
  const std::shared_ptr<const SiteSnapshot>& snapshot_ptr() const { return snapshot_; }
  const SlotTable& sites() const { return snapshot_->sites(); }
  size_t site_count() const { return snapshot_->size(); }
  bool empty() const { return snapshot_->empty(); }
  // The pixels that may differ from the last frame of an earlier version this frame was made
  // from: all of them for a frame made from whole buffers or an empty one; for one made from
  // `base`, `rect` joined with base's own when base is of the same version (a render that
  // writes several windows makes a frame per window), else `rect` alone. Empty: none.
  const PixelRect& changed() const { return changed_; }

  // Pixel access. CONTRACT: i < width, j < height, and the frame is not empty.
  uint32_t id_at(uint32_t i, uint32_t j) const {
    return tile(i, j).ids[(j % kTile) * kTile + i % kTile];
  }
  float distance_at(uint32_t i, uint32_t j) const {
    return tile(i, j).distances[(j % kTile) * kTile + i % kTile];
  }
  uint32_t tiles_x() const { return (grid_.width + kTile - 1) / kTile; }
  uint32_t tiles_y() const { return (grid_.height + kTile - 1) / kTile; }
  const Tile& tile_at(uint32_t tx, uint32_t ty) const { return *tiles_[ty * tiles_x() + tx]; }
  // Whether two frames share the storage of a tile (for tests of copy-on-write).
  bool SharesTile(const Frame& other, uint32_t tx, uint32_t ty) const {
    return tiles_[ty * tiles_x() + tx] == other.tiles_[ty * tiles_x() + tx];
  }

  // The pixel whose centre is nearest to p (clamped to the grid).
  void PixelOf(Vec2 p, uint32_t* i, uint32_t* j) const;

  // The best site at q with its exact value and a proven error bound (see NearestSite in the
  // API). Uses the up to four pixel centres around q: each stored site is a candidate, scored
  // exactly; each stored value bounds every site present there. An empty centre proves that
  // no site is a candidate at q. O(1), except where none of the stored sites is a candidate
  // at q (within a few pixels of a max_distance or a side), or where q lies farther than
  // DrawMargin outside the window in a scene with limited presence: then every site is scored.
  // Returns nullopt when the frame is empty. q may lie anywhere; outside the window the
  // bound grows with the distance to the nearest pixel centre.
  std::optional<NearestAnswer> Nearest(Vec2 q) const;

  // The exact best site at q among the frame's sites (certified: error_bound is only the
  // Bezier flattening's tolerance, `curve`), given any answer with a finite value there:
  // the sites that can beat it come from the snapshot's index (kNearest), or are all scored (kFarthest).
  // For answers that are ambiguous(): paper sec. 6.2, refining before answering.
  NearestAnswer Refine(Vec2 q, const NearestAnswer& answer) const;

 private:
  Frame(Grid grid, double eps, std::shared_ptr<const SiteSnapshot> sites)
      : grid_(grid), eps_(eps), snapshot_(std::move(sites)) {}
  const Tile& tile(uint32_t i, uint32_t j) const {
    return *tiles_[(j / kTile) * tiles_x() + i / kTile];
  }
  // Copies the part of a row-major buffer (origin ox, oy; row length stride) that falls in
  // tile (tx, ty) and `rect` into `t`, then recomputes its max distance.
  void Fill(Tile& t, uint32_t tx, uint32_t ty, PixelRect rect, const uint32_t* ids,
            const float* distances, uint32_t stride) const;

  Grid grid_;
  double eps_;
  std::shared_ptr<const SiteSnapshot> snapshot_;
  ErrorModel error_;
  PixelRect changed_;
  std::vector<std::shared_ptr<const Tile>> tiles_;
};

}  // namespace gvd
