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

#include "render/kernel/exact2.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"
#include "render/scene/error_model.h"
#include "render/scene/site_index.h"
#include "render/scene/snapshot.h"

namespace gvd {

// The answer to a nearest-site (or farthest-site) query at a point.
struct NearestAnswer {
  uint32_t site_index = 0;  // a slot of Frame::sites()
  double distance = 0;      // that site's exact value at the query point
  double error_bound = 0;   // no site's value beats distance by more than error_bound
  bool found = true;        // false: no site is a candidate at the point (certain)
  // The value at q of the best other site stored around q (+inf, or -inf in kFarthest, when
  // there is none): when it is within error_bound of distance, either site may be the best.
  double runner_up = INFINITY;
  // Certified: every site that could beat it was measured exactly, so error_bound is only
  // the rounding of measuring curves (Snapshot::CurveError; 0 in a scene without curves).
  bool exact = false;
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
  // The greatest value stored in tile (tx, ty), over its pixels inside the grid; and over
  // every tile. Kept apart from the tiles, so that reading them all touches 4 bytes a tile.
  float tile_max(uint32_t tx, uint32_t ty) const { return tile_max_[ty * tiles_x() + tx]; }
  float max_value() const;
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
  // The same, with the answer's site's nearest feature in *feature when one is found.
  std::optional<NearestAnswer> Nearest(Vec2 q, FeatureHit* feature) const;

  // The exact best site at q among the frame's sites (certified: error_bound is only the
  // Bezier flattening's tolerance, `curve`), given any answer with a finite value there:
  // the sites that can beat it come from the snapshot's index (kNearest), or are all scored (kFarthest).
  // For answers that are ambiguous(): paper sec. 6.2, refining before answering.
  NearestAnswer Refine(Vec2 q, const NearestAnswer& answer) const;

 private:
  // Nearest's work. With `feature`, each candidate's value comes from its nearest feature,
  // and the answer's is left in *feature with *have set, unless its site is a plain point
  // or every site was scored.
  std::optional<NearestAnswer> Nearest(Vec2 q, FeatureHit* feature, bool* have) const;

  Frame(Grid grid, double eps, std::shared_ptr<const SiteSnapshot> sites)
      : grid_(grid), eps_(eps), snapshot_(std::move(sites)) {}
  const Tile& tile(uint32_t i, uint32_t j) const {
    return *tiles_[(j / kTile) * tiles_x() + i / kTile];
  }
  // Copies the part of a row-major buffer (origin ox, oy; row length stride) that falls in
  // tile (tx, ty) and `rect` into `t`, and returns the greatest value of `t` in the grid.
  float Fill(Tile& t, uint32_t tx, uint32_t ty, PixelRect rect, const uint32_t* ids,
             const float* distances, uint32_t stride) const;

  Grid grid_;
  double eps_;
  std::shared_ptr<const SiteSnapshot> snapshot_;
  ErrorModel error_;
  PixelRect changed_;
  std::vector<std::shared_ptr<const Tile>> tiles_;
  std::vector<float> tile_max_;  // each tile's greatest value, as tiles_
};

}  // namespace gvd
