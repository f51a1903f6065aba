// An immutable CPU copy of a rendered 3D discrete Voronoi diagram: per voxel centre, the best
// site (by slot of the snapshot it was rendered from) and its value there. The frame of a 3D
// scene: its slices are shared, unchanged, between the volumes of successive versions.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "render/kernel/diagram.h"
#include "render/kernel/grid3.h"
#include "render/kernel/site3.h"
#include "render/scene/error_model.h"
#include "render/scene/frame.h"
#include "render/scene/snapshot.h"

namespace gvd {

// Immutable once made; shared between threads by shared_ptr.
//
// What it holds. At each voxel centre c, among the sites that are candidates there (within
// their max_distance), the best value v(c) = m d(c, s) + a (least in kNearest, greatest in
// kFarthest; ties: the least slot) and its site; id 0 and +inf (kNearest) or -inf (kFarthest)
// where no site is a candidate. The values are exact in double, stored as float: within
// error().Slack of the truth.
class Volume {
 public:
  // Voxels are kept in bricks of kBrick^3 (slices are their storage); a brick's extreme value
  // bounds what a change can alter there.
  static constexpr uint32_t kBrick = 4;
  struct Slice {
    std::vector<uint32_t> ids;      // row-major, width x height: 0 or 1 + a slot
    std::vector<float> distances;
  };

  // CONTRACT: slices.size() == grid.depth, each of grid.slice_size() voxels; brick_extreme
  // holds, for each brick (x fastest, then y, then z), the greatest stored value of its
  // voxels in kNearest (least in kFarthest).
  Volume(Grid3 grid, Diagram diagram, std::vector<std::shared_ptr<const Slice>> slices,
         std::vector<float> brick_extreme, std::shared_ptr<const SiteSnapshot3> sites);

  // A volume of no sites: every voxel empty, one slice's storage shared by every slice.
  static std::shared_ptr<const Volume> Empty(Grid3 grid, Diagram diagram,
                                             std::shared_ptr<const SiteSnapshot3> sites);

  const Grid3& grid() const { return grid_; }
  Diagram diagram() const { return error_.diagram; }
  uint64_t version() const { return snapshot_->version(); }
  const ErrorModel& error() const { return error_; }
  const SiteSnapshot3& snapshot() const { return *snapshot_; }
  const std::shared_ptr<const SiteSnapshot3>& snapshot_ptr() const { return snapshot_; }
  const SlotTable3& sites() const { return snapshot_->sites(); }
  bool empty() const { return snapshot_->empty(); }

  // Voxel access. CONTRACT: i < width, j < height, k < depth.
  uint32_t id_at(uint32_t i, uint32_t j, uint32_t k) const {
    return slices_[k]->ids[size_t{j} * grid_.width + i];
  }
  float distance_at(uint32_t i, uint32_t j, uint32_t k) const {
    return slices_[k]->distances[size_t{j} * grid_.width + i];
  }
  const std::shared_ptr<const Slice>& slice(uint32_t k) const { return slices_[k]; }
  // Whether two volumes share the storage of slice k (for tests of copy-on-write).
  bool SharesSlice(const Volume& other, uint32_t k) const { return slices_[k] == other.slices_[k]; }

  uint32_t bricks_x() const { return (grid_.width + kBrick - 1) / kBrick; }
  uint32_t bricks_y() const { return (grid_.height + kBrick - 1) / kBrick; }
  uint32_t bricks_z() const { return (grid_.depth + kBrick - 1) / kBrick; }
  float brick_extreme(uint32_t bx, uint32_t by, uint32_t bz) const {
    return brick_extreme_[(size_t{bz} * bricks_y() + by) * bricks_x() + bx];
  }
  const std::vector<float>& brick_extremes() const { return brick_extreme_; }

  // The best site at q with its exact value and a proven error bound, read from the up to
  // eight voxel centres around q: each stored site is scored exactly at q; each stored value
  // D bounds every site's value at q by D -+ Slack(D) -+ L |q - c|, L the largest
  // multiplicative weight (a site's value changes by at most L per unit of distance). Where
  // some site has a max_distance, a site that is a candidate at q need not be one at the
  // centres around it: then, and in kFarthest, the sites are searched exactly (Refine) and
  // the bound is 0. q may lie anywhere; outside the box the bound grows with the distance to
  // the nearest centre. nullopt when the volume has no sites.
  std::optional<NearestAnswer> Nearest(Vec3 q) const { return Nearest(q, nullptr); }
  // The same, with the answer's site's nearest feature (NearestFeature) in *feature when one
  // is found (when feature is not null): a mesh's search for its value is that search, made
  // once.
  std::optional<NearestAnswer> Nearest(Vec3 q, Hit3* feature) const;

  // The exact best site at q (error_bound 0), given any answer with a finite value there:
  // in kNearest the sites that can beat it come from the snapshot's index; in kFarthest, and
  // when `answer` is not found, every site is scored.
  NearestAnswer Refine(Vec3 q, const NearestAnswer& answer) const;

 private:
  Grid3 grid_;
  ErrorModel error_;
  std::shared_ptr<const SiteSnapshot3> snapshot_;
  std::vector<std::shared_ptr<const Slice>> slices_;
  std::vector<float> brick_extreme_;
};

// The error model of a volume of `sites` on `grid`, rendered exactly per voxel and stored in
// float: no meshing error (overestimate 1, no excess); the slack covers the float rounding of
// the stored values (relative) and the double rounding of distances among coordinates as
// large as the box's or the sites' (absolute).
ErrorModel ExactVolumeError(const Grid3& grid, Diagram diagram, const SiteSnapshot3& sites);

}  // namespace gvd
