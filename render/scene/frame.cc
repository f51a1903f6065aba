#include "render/scene/frame.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "render/kernel/exact2.h"
#include "render/scene/site_view.h"

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

Frame::Frame(Grid grid, double eps, ErrorModel error, const uint32_t* ids, const float* distances,
             std::shared_ptr<const SiteSnapshot> sites)
    : Frame(grid, eps, std::move(sites)) {
  error_ = error;
  changed_ = grid.all();
  tiles_.resize(size_t{tiles_x()} * tiles_y());
  tile_max_.resize(tiles_.size());
  for (uint32_t ty = 0; ty < tiles_y(); ++ty) {
    for (uint32_t tx = 0; tx < tiles_x(); ++tx) {
      auto t = std::make_shared<Tile>();
      tile_max_[ty * tiles_x() + tx] = Fill(*t, tx, ty, grid.all(), ids, distances, grid.width);
      tiles_[ty * tiles_x() + tx] = std::move(t);
    }
  }
}

Frame::Frame(const Frame& base, ErrorModel error, PixelRect rect, const uint32_t* ids,
             const float* distances, std::shared_ptr<const SiteSnapshot> sites)
    : Frame(base.grid_, base.eps_, std::move(sites)) {
  error_ = error;
  changed_ = base.version() == version() ? base.changed_.Union(rect) : rect;
  tiles_ = base.tiles_;
  tile_max_ = base.tile_max_;
  if (rect.empty()) return;
  if (tiles_.empty()) {
    tiles_.resize(size_t{tiles_x()} * tiles_y());
    tile_max_.resize(tiles_.size());
  }
  for (uint32_t ty = rect.y0 / kTile; ty <= (rect.y1 - 1) / kTile; ++ty) {
    for (uint32_t tx = rect.x0 / kTile; tx <= (rect.x1 - 1) / kTile; ++tx) {
      auto& slot = tiles_[ty * tiles_x() + tx];
      auto t = slot ? std::make_shared<Tile>(*slot) : std::make_shared<Tile>();
      // Shift the buffer so that Fill can index it by grid coordinates.
      tile_max_[ty * tiles_x() + tx] =
          Fill(*t, tx, ty, rect, ids - (size_t{rect.y0} * rect.width() + rect.x0),
               distances - (size_t{rect.y0} * rect.width() + rect.x0), rect.width());
      slot = std::move(t);
    }
  }
}

float Frame::max_value() const {
  return tile_max_.empty() ? 0 : *std::max_element(tile_max_.begin(), tile_max_.end());
}

float Frame::Fill(Tile& t, uint32_t tx, uint32_t ty, PixelRect rect, const uint32_t* ids,
                  const float* distances, uint32_t stride) const {
  uint32_t x0 = std::max(tx * kTile, rect.x0), x1 = std::min((tx + 1) * kTile, rect.x1);
  uint32_t y0 = std::max(ty * kTile, rect.y0), y1 = std::min((ty + 1) * kTile, rect.y1);
  for (uint32_t j = y0; j < y1; ++j) {
    const size_t row = size_t{j} * stride;
    for (uint32_t i = x0; i < x1; ++i) {
      t.ids[(j % kTile) * kTile + i % kTile] = ids[row + i];
      t.distances[(j % kTile) * kTile + i % kTile] = distances[row + i];
    }
  }
  float m = 0;
  uint32_t w = std::min(kTile, grid_.width - tx * kTile), h = std::min(kTile, grid_.height - ty * kTile);
  for (uint32_t j = 0; j < h; ++j) {
    for (uint32_t i = 0; i < w; ++i) m = std::max(m, t.distances[j * kTile + i]);
  }
  return m;
}

std::shared_ptr<const Frame> Frame::Empty(Grid grid, double eps,
                                          std::shared_ptr<const SiteSnapshot> sites) {
  auto frame = std::shared_ptr<Frame>(new Frame(grid, eps, std::move(sites)));
  frame->changed_ = grid.all();  // every pixel is empty now
  return frame;
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

std::optional<NearestAnswer> Frame::Nearest(Vec2 q, FeatureHit* feature) const {
  bool have = false;
  std::optional<NearestAnswer> a = Nearest(q, feature, &have);
  if (!a || !a->found || have) return a;
  // A plain point is its own nearest feature, read from the slot table's column.
  if (const Vec2 p = sites().point(a->site_index); !std::isnan(p.x)) {
    *feature = {SegmentDistance(q, p, p), FeatureKind::kVertex, 0, p};  // as NearestFeature
  } else {
    *feature = NearestFeature(q, *sites().get(a->site_index));
  }
  return a;
}

std::optional<NearestAnswer> Frame::Nearest(Vec2 q) const { return Nearest(q, nullptr, nullptr); }

std::optional<NearestAnswer> Frame::Nearest(Vec2 q, FeatureHit* feature, bool* have) const {
  if (empty()) return std::nullopt;
  Vec2 c = grid_.ToPixel(q);
  uint32_t i0 = FloorCenter(c.x, grid_.width), j0 = FloorCenter(c.y, grid_.height);
  uint32_t i1 = std::min(i0 + 1, grid_.width - 1), j1 = std::min(j0 + 1, grid_.height - 1);
  const Diagram diagram = error_.diagram;
  const bool nearest = diagram == Diagram::kNearest;

  NearestAnswer best;
  best.found = false;
  auto score_all = [&] {
    for (uint32_t s = 0; s < sites().size(); ++s) {
      const Site* site = sites().get(s);
      if (site == nullptr) continue;
      double value = SiteView::Of(sites(), s).ValueAt(q);
      if (std::isfinite(value) && (!best.found || Beats(diagram, value, best.distance))) {
        best = {s, value, 0, true};
      }
    }
    best.error_bound = snapshot_->CurveError(best.distance);
    best.exact = true;
    return best;
  };
  // Far outside the window, a site that is a candidate at q need not be present at the
  // centres nearest to q.
  if (error_.limited_presence) {
    for (uint32_t i : {i0, i1}) {
      for (uint32_t j : {j0, j1}) {
        if (Distance(q, grid_.Center(i, j)) > DrawMargin(grid_) / 2) return score_all();
      }
    }
  }
  // No site's value at q beats this.
  double limit = nearest ? -INFINITY : INFINITY;
  double runner_up = nearest ? INFINITY : -INFINITY;
  bool runner_up_none = true;
  const uint32_t is[2] = {i0, i1}, js[2] = {j0, j1};
  for (uint32_t a = 0; a < 2; ++a) {
    for (uint32_t b = 0; b < 2; ++b) {
      if ((a && i1 == i0) || (b && j1 == j0)) continue;
      uint32_t i = is[a], j = js[b];
      uint32_t id = id_at(i, j);
      if (id == 0) return NearestAnswer{0, 0, 0, false};  // no site is present near q
      // Every site B candidate at q: v_B(q) >= v_B(p) - L |q - p| >= LowerBound(D) - L |q - p|
      // (or <= UpperBound(D) + L |q - p|).
      double d = distance_at(i, j), step = error_.lipschitz * Distance(q, grid_.Center(i, j));
      limit = nearest ? std::max(limit, error_.LowerBound(d) - step)
                      : std::min(limit, error_.UpperBound(d) + step);
      uint32_t index = id - 1;
      if (best.found && index == best.site_index) continue;
      // When the feature is asked for, a site's value comes from its nearest feature (one
      // search of a curve or a tree for both); a plain point's feature is the caller's.
      const SiteView view = SiteView::Of(sites(), index);
      FeatureHit hit;
      const bool with_hit = feature != nullptr && !view.plain_point();
      if (with_hit) hit = NearestFeature(q, *view.site);
      double value = with_hit ? SiteValueAt(q, *view.site, hit.distance) : view.ValueAt(q);
      if (!std::isfinite(value)) continue;
      if (!best.found || Beats(diagram, value, best.distance) ||
          (value == best.distance && index < best.site_index)) {
        if (best.found && (Beats(diagram, best.distance, runner_up) || runner_up_none)) {
          runner_up = best.distance;
          runner_up_none = false;
        }
        best = {index, value, 0, true};
        if (with_hit) *feature = hit;
        if (have) *have = with_hit;
      } else if (runner_up_none || Beats(diagram, value, runner_up)) {
        runner_up = value;
        runner_up_none = false;
      }
    }
  }
  // Every centre holds a site, none a candidate at q: q lies within a few pixels of some
  // site's max_distance or side. Score them all.
  if (!best.found) return score_all();
  // The raster holds curves' flattenings, within error_.curve of the curves.
  best.error_bound = std::max(0.0, nearest ? best.distance - limit : limit - best.distance) +
                     error_.curve + snapshot_->CurveError(best.distance);
  best.exact = best.error_bound == 0;
  best.runner_up = runner_up;
  return best;
}

std::vector<uint32_t> OrderByTile(const Grid& grid, const std::vector<Vec2>& points) {
  constexpr size_t kSmall = 1 << 14;
  if (points.size() < kSmall) return {};
  const uint32_t tiles_x = (grid.width + Frame::kTile - 1) / Frame::kTile;
  const uint32_t tiles = tiles_x * ((grid.height + Frame::kTile - 1) / Frame::kTile);
  std::vector<uint32_t> tile(points.size());
  std::vector<uint32_t> start(size_t{tiles} + 2, 0);
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec2 c = grid.ToPixel(points[i]);
    const bool inside = c.x >= 0 && c.y >= 0 && c.x < grid.width && c.y < grid.height;
    tile[i] = inside ? static_cast<uint32_t>(c.y) / Frame::kTile * tiles_x +
                           static_cast<uint32_t>(c.x) / Frame::kTile
                     : tiles;
    ++start[tile[i] + 1];
  }
  for (uint32_t t = 0; t <= tiles; ++t) start[t + 1] += start[t];
  std::vector<uint32_t> order(points.size());
  for (size_t i = 0; i < points.size(); ++i) order[start[tile[i]]++] = static_cast<uint32_t>(i);
  return order;
}

NearestAnswer Frame::Refine(Vec2 q, const NearestAnswer& answer) const {
  NearestAnswer best = answer;
  best.runner_up = error_.diagram == Diagram::kNearest ? INFINITY : -INFINITY;
  auto consider = [&](uint32_t s) {
    const Site* site = sites().get(s);
    if (site == nullptr || s == best.site_index) return;
    double value = SiteView::Of(sites(), s).ValueAt(q);
    if (!std::isfinite(value)) return;
    if (Beats(error_.diagram, value, best.distance) ||
        (value == best.distance && s < best.site_index)) {
      best.runner_up = best.distance;
      best.site_index = s;
      best.distance = value;
    } else if (Beats(error_.diagram, value, best.runner_up)) {
      best.runner_up = value;
    }
  };
  if (error_.diagram == Diagram::kNearest) {
    // A site beats value V only where m d + a < V, so d < (V - least a) / least m.
    const LeastWeights& least = snapshot_->least();
    thread_local std::vector<uint32_t> near;  // no allocation per query in large batches
    near.clear();
    snapshot_->index().Within(q, (answer.distance - least.additive) / least.multiplicative * (1 + 1e-12),
                              &near);
    for (uint32_t s : near) consider(s);
  } else {
    for (uint32_t s = 0; s < sites().size(); ++s) consider(s);
  }
  best.error_bound = snapshot_->CurveError(best.distance);
  best.exact = true;
  return best;
}

}  // namespace gvd
