#include "render/frame.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "render/exact.h"

namespace gvd {
namespace {

// Index of the pixel centre at or below continuous pixel coordinate c, clamped to [0, n-1].
uint32_t FloorCenter(double c, uint32_t n) {
  double f = std::floor(c - 0.5);
  if (!(f > 0)) return 0;  // also NaN
  if (f >= n - 1) return n - 1;
  return static_cast<uint32_t>(f);
}

}  // namespace

Frame::Frame(Grid grid, uint64_t version, double eps, ErrorModel error, std::vector<uint32_t> ids,
             std::vector<float> distances, std::shared_ptr<const SiteTable> sites)
    : grid_(grid),
      version_(version),
      eps_(eps),
      error_(error),
      ids_(std::move(ids)),
      distances_(std::move(distances)),
      sites_(std::move(sites)) {
  assert(sites_->empty() || ids_.size() == grid_.pixel_count());
  assert(ids_.size() == distances_.size());
}

std::shared_ptr<const Frame> Frame::Empty(Grid grid, uint64_t version, double eps) {
  return std::make_shared<const Frame>(grid, version, eps, ErrorModel{}, std::vector<uint32_t>{},
                                       std::vector<float>{}, std::make_shared<const SiteTable>());
}

void Frame::PixelOf(Vec2 p, uint32_t* i, uint32_t* j) const {
  Vec2 c = grid_.ToPixel(p);
  auto nearest = [](double v, uint32_t n) -> uint32_t {
    double f = std::floor(v);
    if (!(f > 0)) return 0;
    if (f >= n - 1) return n - 1;
    return static_cast<uint32_t>(f);
  };
  *i = nearest(c.x, grid_.width);
  *j = nearest(c.y, grid_.height);
}

std::optional<NearestAnswer> Frame::Nearest(Vec2 q) const {
  if (empty()) return std::nullopt;
  Vec2 c = grid_.ToPixel(q);
  uint32_t i0 = FloorCenter(c.x, grid_.width), j0 = FloorCenter(c.y, grid_.height);
  uint32_t i1 = std::min(i0 + 1, grid_.width - 1), j1 = std::min(j0 + 1, grid_.height - 1);

  NearestAnswer best;
  bool found = false;
  double lower = 0;  // no site is closer to q than this
  const uint32_t is[2] = {i0, i1}, js[2] = {j0, j1};
  for (uint32_t a = 0; a < 2; ++a) {
    for (uint32_t b = 0; b < 2; ++b) {
      if ((a && i1 == i0) || (b && j1 == j0)) continue;
      uint32_t i = is[a], j = js[b];
      uint32_t id = id_at(i, j);
      if (id == 0) continue;
      // Every site B: dist(q, B) >= dist(p, B) - |q - p| >= LowerBound(D) - |q - p|.
      double d = distance_at(i, j);
      lower = std::max(lower, error_.LowerBound(d) - Distance(q, grid_.Center(i, j)));
      uint32_t index = id - 1;
      if (found && index == best.site_index) continue;
      double exact = ExactDistance(q, (*sites_)[index].geometry);
      if (!found || exact < best.distance || (exact == best.distance && index < best.site_index)) {
        best = {index, exact, 0};
        found = true;
      }
    }
  }
  if (!found) return std::nullopt;
  best.error_bound = std::max(0.0, best.distance - lower);
  return best;
}

}  // namespace gvd
