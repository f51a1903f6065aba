// An immutable CPU snapshot of a rendered discrete Voronoi diagram: per pixel centre, the
// nearest site (by index into the frame's site table) and the distance to it.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "render/geometry.h"
#include "render/site.h"

namespace gvd {

// How far a frame's stored distances can be from the truth. Wherever a site B's mesh is
// drawn over a pixel centre p, its height satisfies
//   dist(p, B) <= h_B(p) <= min(overestimate * dist(p, B), dist(p, B) + max_excess)
// (the fan's spokes lie on the cone; sec. 4.1.1), and each pixel centre is covered by the
// mesh of its nearest site (render/coverage.h). The stored value D(p) is the smallest height
// drawn there, up to the rasterizer's arithmetic: slack(D) = absolute_slack + relative_slack * D.
struct ErrorModel {
  double overestimate = 1;    // k >= 1
  double max_excess = 0;      // eps, scene units
  double absolute_slack = 0;  // scene units: sub-pixel vertex snapping and interpolation
  double relative_slack = 0;  // float depth and interpolation rounding, relative to D

  double Slack(double d) const { return absolute_slack + relative_slack * d; }
  // A lower bound on dist(p, B) for every site B, given the stored distance D at p: the
  // nearest site's height at p is at least D.
  double LowerBound(double d) const {
    return std::max(d / overestimate, d - max_excess) - Slack(d);
  }
};

// The answer to a nearest-site query at a point.
struct NearestAnswer {
  uint32_t site_index = 0;  // into Frame::sites()
  double distance = 0;      // exact distance from the query point to that site
  double error_bound = 0;   // no site is closer than distance - error_bound
};

class Frame {
 public:
  // Takes ownership of the buffers. CONTRACT: ids and distances hold grid.pixel_count() values,
  // row-major from row 0 (min_y); ids are 0 (no site) or 1 + an index into *sites.
  Frame(Grid grid, uint64_t version, double eps, ErrorModel error, std::vector<uint32_t> ids,
        std::vector<float> distances, std::shared_ptr<const SiteTable> sites);

  // An empty frame: no sites, no pixels read back.
  static std::shared_ptr<const Frame> Empty(Grid grid, uint64_t version, double eps);

  const Grid& grid() const { return grid_; }
  uint64_t version() const { return version_; }
  double eps() const { return eps_; }
  const ErrorModel& error() const { return error_; }
  const SiteTable& sites() const { return *sites_; }
  const std::shared_ptr<const SiteTable>& shared_sites() const { return sites_; }
  bool empty() const { return sites_->empty(); }

  // Raw pixel access. CONTRACT: i < width, j < height, and the frame is not empty.
  uint32_t id_at(uint32_t i, uint32_t j) const { return ids_[size_t{j} * grid_.width + i]; }
  float distance_at(uint32_t i, uint32_t j) const {
    return distances_[size_t{j} * grid_.width + i];
  }
  const std::vector<uint32_t>& ids() const { return ids_; }
  const std::vector<float>& distances() const { return distances_; }

  // The pixel whose centre is nearest to p (clamped to the grid).
  void PixelOf(Vec2 p, uint32_t* i, uint32_t* j) const;

  // The nearest site to q with an exact distance and a proven error bound (see NearestSite in
  // the API). Uses the up to four pixel centres around q: each stored site is a candidate,
  // scored exactly; each stored distance bounds every site from below. O(1).
  // Returns nullopt when the frame is empty. q may lie anywhere; outside the window the
  // bound grows with the distance to the nearest pixel centre.
  std::optional<NearestAnswer> Nearest(Vec2 q) const;

 private:
  Grid grid_;
  uint64_t version_;
  double eps_;
  ErrorModel error_;
  std::vector<uint32_t> ids_;
  std::vector<float> distances_;
  std::shared_ptr<const SiteTable> sites_;
};

}  // namespace gvd
