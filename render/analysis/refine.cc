#include "render/analysis/refine.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

namespace gvd {
namespace {

// Inclusive pixel ranges of an image whose pairs a zoom window supersedes.
struct Span {
  uint32_t i0, j0, i1, j1;
  bool Holds(uint32_t i, uint32_t j) const { return i >= i0 && i <= i1 && j >= j0 && j <= j1; }
};

// The window over pixels [i0, i1] x [j0, j1] of `grid`, out to their outer edges, at `factor`
// times the resolution. Its pixel centres reach to within half a (finer) pixel of its edges,
// so they span every centre of the range.
Grid ZoomGrid(const Grid& grid, const Span& s, uint32_t factor) {
  const double pw = grid.pixel_width(), ph = grid.pixel_height();
  Window w{grid.window.min_x + s.i0 * pw, grid.window.min_y + s.j0 * ph,
           grid.window.min_x + (s.i1 + 1) * pw, grid.window.min_y + (s.j1 + 1) * ph};
  return Grid{w, (s.i1 - s.i0 + 1) * factor, (s.j1 - s.j0 + 1) * factor};
}

struct Request {
  Grid grid;
  uint32_t depth;
  int64_t target;  // a hidden slot this window searches for, or -1
};

class Refiner {
 public:
  Refiner(const Frame& frame, const ZoomFn& zoom, const RefineOptions& options)
      : frame_(frame), zoom_(zoom), options_(options),
        refining_(zoom != nullptr && options.max_depth > 0) {}

  absl::StatusOr<RefinedNeighbors> Run(PixelRect rect) {
    IdImage base = IdsOf(frame_, rect);
    bounds_ = base.grid.window;
    out_.hidden = HiddenSites(base, frame_.sites());
    hidden_.insert(out_.hidden.begin(), out_.hidden.end());
    std::vector<Request> level;
    Process(base, frame_.error(), 0, -1, /*search_hidden=*/true, &level);
    while (!level.empty()) {
      std::vector<Request> next;
      for (size_t first = 0; first < level.size(); first += options_.batch) {
        size_t last = std::min(level.size(), first + options_.batch);
        std::vector<Grid> grids;
        for (size_t k = first; k < last; ++k) grids.push_back(level[k].grid);
        auto frames = zoom_(grids);
        if (!frames.ok()) return frames.status();
        for (size_t k = first; k < last; ++k) {
          const Frame& f = *(*frames)[k - first];
          out_.windows++;
          out_.depth = std::max(out_.depth, level[k].depth);
          Process(IdsOf(f, f.grid().all()), f.error(), level[k].depth, level[k].target, false,
                  &next);
        }
      }
      level = std::move(next);
    }
    for (uint32_t s : out_.hidden) {
      if (seen_.count(s)) out_.recovered.push_back(s);
    }
    return std::move(out_);
  }

 private:
  // Adds the pairs of one image (raster or zoom window) that no finer window of it will
  // supersede, and queues those windows.
  void Process(const IdImage& image, const ErrorModel& error, uint32_t depth, int64_t target,
               bool search_hidden, std::vector<Request>* next) {
    const uint32_t w = image.width(), h = image.height();
    if (!hidden_.empty() && depth > 0) {
      for (uint32_t id : image.ids) {
        if (id != 0 && hidden_.count(id - 1)) seen_.insert(id - 1);
      }
    }
    BoundaryEdges edges = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
    std::vector<std::pair<Span, int64_t>> windows;  // with the slot each one searches for
    // Which sides of the image are the border of the rect asked about (not a zoom window's
    // own edge inside it): between the outer pixel centres and such a side, nothing is
    // sampled at any level.
    struct {
      bool left, bottom, right, top;
    } border;
    auto same = [](double a, double b) { return std::abs(a - b) <= 1e-9 * (std::abs(a) + std::abs(b)); };
    border.left = same(image.grid.window.min_x, bounds_.min_x);
    border.bottom = same(image.grid.window.min_y, bounds_.min_y);
    border.right = same(image.grid.window.max_x, bounds_.max_x);
    border.top = same(image.grid.window.max_y, bounds_.max_y);
    if (zoom_ != nullptr && depth < options_.max_depth && w > 1 && h > 1) {
      // Doubtful cells, each with a pixel of margin: merged while the merged span stays within
      // block_px a side.
      const uint32_t most = std::max(4u, options_.block_px);
      for (uint32_t j = 0; j + 1 < h; ++j) {
        for (uint32_t i = 0; i + 1 < w; ++i) {
          if (!edges.h(i, j) && !edges.h(i, j + 1) && !edges.v(i, j) && !edges.v(i + 1, j)) {
            continue;
          }
          const bool edge = (i == 0 && border.left) || (j == 0 && border.bottom) ||
                            (i + 2 == w && border.right) || (j + 2 == h && border.top);
          if (!Doubtful(image, error, i, j, edge)) continue;
          Span cell{i >= 1 ? i - 1 : 0, j >= 1 ? j - 1 : 0, std::min(w - 1, i + 2),
                    std::min(h - 1, j + 2)};
          bool merged = false;
          for (size_t k = windows.size(); k-- > 0 && !merged;) {
            Span& s = windows[k].first;
            Span u{std::min(s.i0, cell.i0), std::min(s.j0, cell.j0), std::max(s.i1, cell.i1),
                   std::max(s.j1, cell.j1)};
            if (u.i1 - u.i0 < most && u.j1 - u.j0 < most && cell.i0 <= s.i1 + 1 &&
                s.i0 <= cell.i1 + 1 && cell.j0 <= s.j1 + 1 && s.j0 <= cell.j1 + 1) {
              s = u;
              merged = true;
            }
            if (s.j1 + most < j) break;  // windows are in row order: none further back fits
          }
          if (!merged) windows.push_back({cell, -1});
        }
      }
      // Sites that hold no pixel: a window around each, at every level until one shows.
      std::vector<uint32_t> search;
      if (search_hidden) search = out_.hidden;
      if (target >= 0 && !Holds(image, static_cast<uint32_t>(target))) {
        search.push_back(static_cast<uint32_t>(target));
      }
      for (uint32_t s : search) {
        Window b = BoundingBox(frame_.sites().get(s)->geometry);
        const double pw = image.grid.pixel_width(), ph = image.grid.pixel_height();
        PixelRect r = image.grid.CentresIn({b.min_x - pw, b.min_y - ph}, {b.max_x + pw, b.max_y + ph});
        if (r.empty() || r.width() > 64 || r.height() > 64) continue;  // not a tiny region
        windows.push_back({Span{r.x0, r.y0, r.x1 - 1, r.y1 - 1}, s});
      }
      if (planned_ + windows.size() > options_.max_windows) {
        out_.complete = false;
        windows.clear();
      }
      planned_ += windows.size();
    }
    // Pairs of pixels that a window spans are superseded by it.
    std::vector<uint8_t> gone_h(edges.horizontal.size(), 0), gone_v(edges.vertical.size(), 0);
    for (const auto& [s, slot] : windows) {
      for (uint32_t j = s.j0; j <= s.j1; ++j) {
        for (uint32_t i = s.i0; i <= s.i1; ++i) {
          if (i < s.i1) gone_h[size_t{j} * (w - 1) + i] = 1;
          if (j < s.j1) gone_v[size_t{j} * w + i] = 1;
        }
      }
    }
    auto add = [&](uint32_t i, uint32_t j, uint32_t i2, uint32_t j2) {
      uint32_t a = image.at(i, j), b = image.at(i2, j2);
      if (a == 0 || b == 0) return;
      auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = out_.pairs.find(key);
      if (it != out_.pairs.end()) {
        ++it->second;
      } else if (!refining_ || Certified(image.grid.Center(i, j), image.grid.Center(i2, j2), a, b)) {
        out_.pairs[key] = 1;
      }
    };
    for (uint32_t j = 0; j < h; ++j) {
      for (uint32_t i = 0; i + 1 < w; ++i) {
        if (edges.h(i, j) && !gone_h[size_t{j} * (w - 1) + i]) add(i, j, i + 1, j);
      }
    }
    for (uint32_t j = 0; j + 1 < h; ++j) {
      for (uint32_t i = 0; i < w; ++i) {
        if (edges.v(i, j) && !gone_v[size_t{j} * w + i]) add(i, j, i, j + 1);
      }
    }
    for (const auto& [s, slot] : windows) {
      next->push_back({ZoomGrid(image.grid, s, options_.factor), depth + 1, slot});
    }
  }

  // Whether sites a and b (ids), seen on either side of the pixel centres p and q, are best
  // together where their boundary crosses pq: no other site beats both there. A pair seen only
  // where a third site's sliver, thinner than the pixels, really separates them is not.
  bool Certified(Vec2 p, Vec2 q, uint32_t a, uint32_t b) {
    const SlotTable& sites = frame_.sites();
    const Site *sa = sites.get(a - 1), *sb = sites.get(b - 1);
    const bool nearest = frame_.error().diagram == Diagram::kNearest;
    const Vec2 x = BoundaryCrossing(p, q, sa, sb, frame_.error().diagram);
    const double va = SiteValue(x, *sa), vb = SiteValue(x, *sb);
    if (!std::isfinite(va) || !std::isfinite(vb)) return true;  // a side or a reach: no test
    // Both must be best: nothing may beat the worse of the two (they tie on the boundary;
    // where the pixels' labels are off by the meshes' error, the crossing is the midpoint).
    const double tie = nearest ? std::max(va, vb) : std::min(va, vb);
    const double tolerance = 1e-9 * (std::abs(tie) + frame_.grid().pixel_size());
    auto beats = [&](const Site& s) {
      if (&s == sa || &s == sb) return false;
      double v = SiteValue(x, s);
      return std::isfinite(v) && (nearest ? v < tie - tolerance : v > tie + tolerance);
    };
    if (nearest) {
      const LeastWeights& least = frame_.snapshot().least();
      candidates_.clear();
      frame_.snapshot().index().Within(x, (tie - least.additive) / least.multiplicative,
                                       &candidates_);
      for (uint32_t s : candidates_) {
        if (beats(*sites.get(s))) return false;
      }
      return true;
    }
    for (uint32_t s = 0; s < sites.size(); ++s) {
      if (const Site* site = sites.get(s); site && beats(*site)) return false;
    }
    return true;
  }

  // Whether the cell at (i, j), on a boundary, is where four sites are nearly equidistant:
  // three or more sites among the 4x4 pixels around it (a thin region may show only a pixel
  // or two near where it meets the others), and four of them within delta of the best value
  // at the cell's centre. delta covers the distance from the centre to a Voronoi vertex in
  // the cell (a pixel diagonal: each value changes by at most the largest weight per unit of
  // distance), a Voronoi edge up to half a pixel long between two such vertices (one pixel:
  // the fourth site's value gains at most twice its length) and the meshes' error. A cell on
  // the border of the rect asked about is doubtful with two sites and a third within three
  // pixel diagonals more: a Voronoi vertex can hide in the half pixel between its centres
  // and the border.
  bool Doubtful(const IdImage& image, const ErrorModel& e, uint32_t i, uint32_t j, bool edge) {
    // The sites of the 4x4 pixels around the cell (a thin region may show only a pixel or
    // two from where it meets the others).
    const uint32_t w = image.width(), h = image.height();
    uint32_t ids[16];
    int n = 0;
    for (uint32_t y = j >= 1 ? j - 1 : 0; y <= std::min(h - 1, j + 2); ++y) {
      for (uint32_t x = i >= 1 ? i - 1 : 0; x <= std::min(w - 1, i + 2); ++x) {
        uint32_t id = image.at(x, y);
        if (id != 0 && std::find(ids, ids + n, id) == ids + n) ids[n++] = id;
      }
    }
    if (n < (edge ? 2 : 3)) return false;
    const int enough = edge ? 3 : 4;
    const Vec2 c = 0.5 * (image.grid.Center(i, j) + image.grid.Center(i + 1, j + 1));
    const SlotTable& sites = frame_.sites();
    const bool nearest = e.diagram == Diagram::kNearest;
    double best = nearest ? INFINITY : -INFINITY;
    for (int k = 0; k < n; ++k) {
      double v = SiteValue(c, *sites.get(ids[k] - 1));
      if (std::isfinite(v)) best = nearest ? std::min(best, v) : std::max(best, v);
    }
    if (!std::isfinite(best)) return true;
    const double delta =
        ((edge ? 3 : 1) * image.grid.pixel_diagonal() + image.grid.pixel_size()) * e.lipschitz +
        e.max_excess;
    int close = 0;
    auto near = [&](const Site& s) {
      double v = SiteValue(c, s);
      return std::isfinite(v) && std::abs(v - best) <= delta;
    };
    if (nearest) {
      const LeastWeights& least = frame_.snapshot().least();
      candidates_.clear();
      frame_.snapshot().index().Within(c, (best + delta - least.additive) / least.multiplicative,
                                       &candidates_);
      for (uint32_t s : candidates_) close += near(*sites.get(s));
    } else {
      for (uint32_t s = 0; s < sites.size() && close < enough; ++s) {
        if (const Site* site = sites.get(s)) close += near(*site);
      }
    }
    return close >= enough;
  }

  static bool Holds(const IdImage& image, uint32_t slot) {
    return std::find(image.ids.begin(), image.ids.end(), slot + 1) != image.ids.end();
  }

  const Frame& frame_;
  const ZoomFn& zoom_;
  const RefineOptions& options_;
  RefinedNeighbors out_;
  std::unordered_set<uint32_t> hidden_, seen_;
  std::vector<uint32_t> candidates_;
  Window bounds_;  // the rect asked about, in scene units
  const bool refining_;
  size_t planned_ = 0;
};

}  // namespace

absl::StatusOr<RefinedNeighbors> RefineNeighbors(const Frame& frame, PixelRect rect,
                                                 const ZoomFn& zoom,
                                                 const RefineOptions& options) {
  return Refiner(frame, zoom, options).Run(rect);
}

}  // namespace gvd
