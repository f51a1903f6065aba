#include "render/plan/coverage.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <mutex>
#include <numbers>
#include <unordered_map>

#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "render/kernel/segment_tree.h"
#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

// How far a distance measured from a point near c may be off by rounding: a few ulps of
// the coordinates, and far more to be safe. The tests below widen their bounds by it (a
// tile's half-diagonal h by it, and comparisons of distances by twice it), so that rounding
// can only keep a site or a piece too many, never drop one: at a pixel centre a hair's
// breadth from an edge, say, the two halves of its tent measure distances a few ulps apart.
double Rounding(Vec2 c) { return 0x1p-40 * (std::abs(c.x) + std::abs(c.y)) + 0x1p-1000; }

// Whether some corner x of c satisfies |x s| <= |x s1| (with slack for rounding, so the
// test can only keep too many sites, never too few).
bool BeatsSomewhere(Vec2 s, Vec2 s1, const Window& c) {
  const double slack = 2 * Rounding({(c.min_x + c.max_x) / 2, (c.min_y + c.max_y) / 2});
  for (Vec2 x : {Vec2{c.min_x, c.min_y}, Vec2{c.max_x, c.min_y}, Vec2{c.min_x, c.max_y},
                 Vec2{c.max_x, c.max_y}}) {
    double a = Distance(x, s), b = Distance(x, s1);
    if (a <= b * (1 + 1e-12) + slack) return true;
  }
  return false;
}

// Whether the site is present (drawn) on the whole disc of radius h around a point whose
// distance from the site is d.
bool PresentOnDisc(const SiteView& s, double d, double h, double margin) {
  if (s.plain_point()) return true;
  if (!(d + h <= s.site->max_distance + margin)) return false;
  return SideOf(s.site->geometry) == Side::kBoth;
}

// False when the site is a polygon or path restricted to its inside whose box, grown by the
// margin, misses the cell: it is present nowhere there.
bool InsideReach(const SiteView& s, const Window& cell, double margin) {
  if (s.site == nullptr || SideOf(s.site->geometry) != Side::kInside) return true;
  Window b = BoundingBox(s.site->geometry);
  return b.min_x - margin <= cell.max_x && cell.min_x <= b.max_x + margin &&
         b.min_y - margin <= cell.max_y && cell.min_y <= b.max_y + margin;
}

// One piece of a site's mesh as PieceCover tests it: the half-tent on the left of the edge
// ab, or the fan at a (a == b); its region is the side of the line through a where
// (x - a) . n1 >= 0 and of the line through b where (x - b) . n2 >= 0 (a tent's slab, a fan's
// wedge), and for a half-tent (x - a) . n3 >= 0 (the left of ab); or the whole plane for a
// fan that turns half-way or more.
struct PieceRegion {
  Vec2 a, b, n1, n2, n3;
  bool bounded = true;
};

std::vector<PieceRegion> Regions(const Site& site) {
  std::vector<PieceRegion> out;
  ForEachPiece(
      site.geometry,
      [&](Vec2 v, double from, double to) {
        // Left of the direction `from`, right of the direction `to`.
        out.push_back({v, v, {-std::sin(from), std::cos(from)}, {std::sin(to), -std::cos(to)},
                       {0, 0}, to - from <= std::numbers::pi});
      },
      [&](Vec2 a, Vec2 b) { out.push_back({a, b, b - a, a - b, {a.y - b.y, b.x - a.x}, true}); });
  return out;
}

// For each segment of the site (ForEachSegment order), the pieces of its mesh (ForEachPiece
// order, render/plan/distance_mesh.h) whose feature is part of it: its two half-tents and the fans at
// its ends (kNone where there is none), so that a site with a segment tree finds its pieces
// near a point from the segments near it.
constexpr uint32_t kNone = UINT32_MAX;
std::vector<std::array<uint32_t, 4>> PiecesOfSegments(const Geometry& g) {
  std::vector<uint32_t> edges;  // the segments of positive length, in order
  std::vector<bool> degenerate;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) {
    degenerate.push_back(a.x == b.x && a.y == b.y);
    if (!degenerate.back()) edges.push_back(static_cast<uint32_t>(degenerate.size() - 1));
  });
  std::vector<std::array<uint32_t, 4>> out(degenerate.size(), {kNone, kNone, kNone, kNone});
  const uint32_t n = static_cast<uint32_t>(edges.size());
  for (uint32_t e = 0; e < n; ++e) {
    out[edges[e]][0] = 2 * e;
    out[edges[e]][1] = 2 * e + 1;
  }
  // The fans, chain after chain as ForEachPiece draws them.
  uint32_t fan = 2 * n, e = 0;
  ForEachChain(g, [&](uint32_t begin, uint32_t end, bool closed) {
    const uint32_t first = e;
    while (e < n && edges[e] < end) ++e;
    const uint32_t m = e - first;
    auto at = [&](uint32_t i) { return edges[first + i]; };
    if (m == 0) {  // every vertex at one point: one fan
      for (uint32_t i = begin; i < end; ++i) out[i][0] = fan;
      ++fan;
    } else if (closed) {  // joint i: the end of edge i, start of i + 1
      for (uint32_t i = 0; i < m; ++i) {
        out[at(i)][3] = fan + i;
        out[at((i + 1) % m)][2] = fan + i;
      }
      fan += m;
    } else {  // the chain's two ends, then its joints
      out[at(0)][2] = fan;
      out[at(m - 1)][3] = fan + 1;
      for (uint32_t i = 0; i + 1 < m; ++i) {
        out[at(i)][3] = fan + 2 + i;
        out[at(i + 1)][2] = fan + 2 + i;
      }
      fan += m + 1;
    }
  });
  return out;
}

// The pieces of a site's mesh that a tile keeping it needs (Coverage::pieces). With c the
// middle of the tile's centres and h their half-diagonal, a feature at d_k from c is
// between d_k - h and d_k + h from each centre p, and the site at most min_k d_k + h. The
// piece holding the site's nearest point to p is therefore no farther than that, and, if the
// site is best at p, its value there is at most the tile's upper bound U (Keep). Pieces that
// fail either bound are not needed there, nor those whose region the tile misses (they hold
// no nearest point there); the others get the tile's pixels and a radius of d_k + h, capped
// at the site's presence. A half-tent's value at a centre of its slab is the distance to its
// edge's line, at most the greatest over the tile's corners (it is linear on its side), and
// the centres' projections on the edge lie between the corners' least and greatest: it
// gets those instead, where they are less.
class PieceCover {
 public:
  explicit PieceCover(const Grid& grid) : grid_(grid), margin_(DrawMargin(grid)) {}

  void Cover(const SlotTable& sites, uint32_t slot, PixelRect rect, double upper,
             std::vector<PieceDraw>* pieces) {
    if (!std::isnan(sites.point(slot).x)) return;  // a plain point is its one piece
    const Site& site = *sites.get(slot);
    // Not a structured binding: clang 14 lets no lambda below capture one.
    const auto emplaced = regions_.try_emplace(slot);
    const auto it = emplaced.first;
    if (emplaced.second) {
      it->second.regions = Regions(site);
      if (site.segment_tree) it->second.of_segment = PiecesOfSegments(site.geometry);
    }
    const std::vector<PieceRegion>& regions = it->second.regions;
    const Window box = grid_.CentreBox(rect);
    const Vec2 c{(box.min_x + box.max_x) / 2, (box.min_y + box.max_y) / 2};
    const double h = Distance({box.min_x, box.min_y}, {box.max_x, box.max_y}) / 2 + Rounding(c);
    const Vec2 corners[4] = {{box.min_x, box.min_y}, {box.max_x, box.min_y},
                             {box.min_x, box.max_y}, {box.max_x, box.max_y}};
    // Whether some corner x has (x - o) . n >= -snap |n|: the box comes within `snap` of
    // that half-plane. The rasterizer snaps vertices to 1/256 pixel, which can move a pixel
    // centre within that of an edge's line to the other half of its tent, so both halves
    // must be drawn there; and rounding adds its own slack.
    const double snap = grid_.pixel_size() / 64;
    auto meets = [&](Vec2 o, Vec2 n) {
      const double slack = Length(n) * (snap + 1e-9 * (h + Distance(c, o)));
      for (Vec2 x : corners) {
        if (glm::dot(x - o, n) >= -slack) return true;
      }
      return false;
    };
    // The pieces to test, their features' distances from c, and the site's (least of them).
    dist_.resize(regions.size());
    candidates_.clear();
    double nearest = INFINITY;
    auto measure = [&](uint32_t k) {
      const PieceRegion& r = regions[k];
      dist_[k] = r.a == r.b ? Distance(c, r.a) : SegmentDistance(c, r.a, r.b);
      candidates_.push_back(k);
    };
    const double m = site.multiplicative, a = site.additive;
    if (site.segment_tree) {
      // Only pieces of segments near c can pass the tests below: a fan's vertex is no
      // nearer than the segments that end there, and the site is as near as its nearest
      // segment.
      nearest = site.segment_tree->Nearest(c).distance + h;
      double reach = nearest * (1 + 1e-12) + h;
      if (std::isfinite(upper)) reach = std::min(reach, std::max(0.0, (upper * (1 + 1e-12) - a) / m) + h);
      seen_.resize(regions.size(), false);
      site.segment_tree->Within(c, reach * (1 + 1e-9), [&](uint32_t j, Vec2, Vec2) {
        for (uint32_t k : it->second.of_segment[j]) {
          if (k == kNone || seen_[k]) continue;
          seen_[k] = true;
          measure(k);
        }
      });
      for (uint32_t k : candidates_) seen_[k] = false;
    } else {
      for (uint32_t k = 0; k < regions.size(); ++k) {
        measure(k);
        nearest = std::min(nearest, dist_[k] + h);
      }
    }
    if (pieces->size() < regions.size()) pieces->resize(regions.size());
    const double presence = site.max_distance + margin_;
    for (uint32_t k : candidates_) {
      const PieceRegion& r = regions[k];
      const double lower = std::max(0.0, dist_[k] - h);
      if (lower > nearest * (1 + 1e-12)) continue;
      if (m * lower + a > upper * (1 + 1e-12)) continue;
      if (r.bounded && !(meets(r.a, r.n1) && meets(r.b, r.n2) && meets(r.a, r.n3))) continue;
      PieceDraw& p = (*pieces)[k];
      double radius = dist_[k] + h;
      if (r.a != r.b) {  // a half-tent: along ab from `from`, to its left up to `radius`
        const double length = Distance(r.a, r.b);
        const Vec2 along = (r.b - r.a) / length, left = r.n3 / length;
        double lo = INFINITY, hi = -INFINITY, side = 0;
        for (Vec2 x : corners) {
          const double t = glm::dot(x - r.a, along);
          lo = std::min(lo, t);
          hi = std::max(hi, t);
          side = std::max(side, glm::dot(x - r.a, left));
        }
        // Rounding slack, relative to the coordinates involved (far more than a few ulps).
        const double slack = 0x1p-40 * (Length(r.a) + Length(c) + h + length);
        radius = std::min(radius, side + slack);
        p.from = std::min(p.from, std::max(0.0, lo - slack));
        p.to = std::max(p.to, std::min(length, hi + slack));
      }
      p.radius = std::max(p.radius, std::min(radius * (1 + 0x1p-40), presence));
      p.clip = p.clip.Union(rect);
    }
  }

 private:
  const Grid& grid_;
  const double margin_;
  struct Pieces {
    std::vector<PieceRegion> regions;
    std::vector<std::array<uint32_t, 4>> of_segment;  // for a site with a segment tree
  };
  std::unordered_map<uint32_t, Pieces> regions_;  // by slot, made on use
  std::vector<double> dist_;
  std::vector<uint32_t> candidates_;
  std::vector<bool> seen_;
};

}  // namespace

uint32_t DefaultTilePx(const Grid& grid, size_t n, double ink) {
  double spacing = std::sqrt(double(grid.pixel_count()) / std::max<size_t>(n, 1));
  uint32_t leaf = 1;
  while (leaf < 4 && 2 * leaf <= spacing / 3) leaf *= 2;
  // Lines of total length `ink` in pixels over the grid's area are about area / ink apart.
  const double lines = double(grid.pixel_count()) / (ink / grid.pixel_size());
  while (leaf > 1 && leaf > lines / 2) leaf /= 2;
  return leaf;
}

uint32_t TopTilePx(const Grid& grid, size_t n, uint32_t leaf_px) {
  double spacing = std::sqrt(double(grid.pixel_count()) / std::max<size_t>(n, 1));
  const double want = std::clamp(2 * spacing, 8.0, 64.0);
  uint32_t top = std::max(leaf_px, 1u);
  while (top < want && top <= 64 / 2) top *= 2;
  return top;
}

TileCover::TileCover(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                     Diagram diagram)
    : grid_(grid), sites_(sites), index_(index), diagram_(diagram), least_(sites.least()),
      margin_(DrawMargin(grid)) {}

double TileCover::RadiusFor(const SiteView& s, const Window& box) const {
  // The margin absorbs rounding differences between these bounds and distances computed
  // elsewhere (a few ulps), so a radius can never fall short of them.
  return std::min(s.FarthestFrom(box) * (1 + 0x1p-40), s.max_distance() + margin_);
}

double TileCover::PresenceReach() const {
  std::call_once(reach_once_, [&] {
    double reach = 0;
    for (uint32_t s = 0; s < sites_.size() && std::isfinite(reach); ++s) {
      const Site* site = sites_.get(s);
      if (site == nullptr) continue;
      // An inside-only polygon or path is present within DrawMargin of its box at most.
      reach = SideOf(site->geometry) == Side::kInside ? reach : std::max(reach, site->max_distance);
    }
    reach_ = reach;
  });
  return reach_;
}

void TileCover::Candidates(PixelRect tile, std::vector<uint32_t>* out) const {
  if (diagram_ == Diagram::kFarthest) {  // the farthest sites are not found by nearness
    for (uint32_t s = 0; s < sites_.size(); ++s) {
      if (sites_.get(s)) out->push_back(s);
    }
    return;
  }
  const SiteIndex& index = index_;
  Vec2 lo = grid_.Center(tile.x0, tile.y0), hi = grid_.Center(tile.x1 - 1, tile.y1 - 1);
  Vec2 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2};
  const double h = Distance(lo, hi) / 2 + Rounding(c);
  // U: an upper bound on the best drawn value at every centre of the cell, from the site
  // nearest to its middle; every site whose least value there can reach U is a candidate.
  ExactNearest s0 = index.Nearest(c);
  const SiteView best = SiteView::Of(sites_, static_cast<uint32_t>(s0.index));
  // As drawn (a curve's flattening): the boxes the index searches hold both.
  const double d0 = best.DrawnDistanceFrom(c);
  if (PresentOnDisc(best, d0, h, margin_)) {
    double upper = best.multiplicative() * (d0 + h) + best.additive();
    // Rounding slack on the search radius keeps the candidate set a superset.
    index.Within(c, ((upper - least_.additive) / least_.multiplicative + h) * (1 + 1e-12), out);
  } else if (double reach = PresenceReach(); std::isfinite(reach)) {
    // No U: the sites present somewhere on C, whose boxes come within h + reach of c.
    index.Within(c, (h + reach + margin_) * (1 + 1e-12), out);
  } else {
    for (uint32_t s = 0; s < sites_.size(); ++s) {
      if (sites_.get(s)) out->push_back(s);
    }
  }
}

void TileCover::Cover(PixelRect tile, std::vector<uint32_t>* slots,
                      std::vector<double>* radii) const {
  thread_local std::vector<uint32_t> candidates;
  candidates.clear();
  Candidates(tile, &candidates);
  Keep(tile, candidates, slots, radii);
}

double TileCover::Keep(PixelRect tile, std::span<const uint32_t> candidates,
                       std::vector<uint32_t>* slots, std::vector<double>* radii) const {
  return diagram_ == Diagram::kFarthest
             ? KeepIn<Diagram::kFarthest>(tile, candidates, slots, radii)
             : KeepIn<Diagram::kNearest>(tile, candidates, slots, radii);
}

template <Diagram kDiagram>
double TileCover::KeepIn(PixelRect tile, std::span<const uint32_t> candidates,
                         std::vector<uint32_t>* slots, std::vector<double>* radii) const {
  // The proof of coverage.h, for both diagrams (one instance of this each, so that no loop
  // asks which). Over the cell C (the tile's centres, within h of c) a site's value lies
  // between m max(0, d - h) + a and m (d + h) + a, d its distance from c. The bound B is the
  // best, among the sites present on all of C, of the worst end (U, the least upper end, in
  // kNearest; L, the greatest lower end, in kFarthest); a site whose best end loses to B is
  // best nowhere on C.
  constexpr bool farthest = kDiagram == Diagram::kFarthest;
  const SlotTable& sites = sites_;
  const double margin = margin_;
  Vec2 lo = grid_.Center(tile.x0, tile.y0), hi = grid_.Center(tile.x1 - 1, tile.y1 - 1);
  Window cell{lo.x, lo.y, hi.x, hi.y};
  Vec2 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2};
  const double h = Distance(lo, hi) / 2 + Rounding(c);
  thread_local std::vector<SiteView> views;
  thread_local std::vector<double> dist;
  views.resize(candidates.size());
  dist.resize(candidates.size());
  auto low = [&](size_t k) {
    return views[k].multiplicative() * std::max(0.0, dist[k] - h) + views[k].additive();
  };
  auto high = [&](size_t k) { return views[k].multiplicative() * (dist[k] + h) + views[k].additive(); };
  double bound = farthest ? -INFINITY : INFINITY;
  size_t s1 = SIZE_MAX;  // the site that gives the bound
  for (size_t k = 0; k < candidates.size(); ++k) {
    views[k] = SiteView::Of(sites, candidates[k]);
    dist[k] = views[k].DrawnDistanceFrom(c);
    if (!PresentOnDisc(views[k], dist[k], h, margin)) continue;
    const double worst = farthest ? low(k) : high(k);
    if (Beats(kDiagram, worst, bound)) {
      bound = worst;
      s1 = k;
    }
  }
  // Whether a site whose best end is v loses to the bound, with the tests' rounding slack.
  auto loses = [&](double v) {
    return farthest ? v * (1 + 1e-12) < bound - 1e-12 * std::abs(bound) : v > bound * (1 + 1e-12);
  };
  // Plain points clipped by the bisectors of the plain points best at the cell's corners
  // (nearest to them, or farthest): a plain point that loses to one of those at every corner
  // loses to it on all of C (the points nearer to one than to the other form a half-plane,
  // which is convex), and plain points are present everywhere, so it is best nowhere on C.
  const Vec2 corners[4] = {lo, {hi.x, lo.y}, {lo.x, hi.y}, hi};
  thread_local std::vector<std::array<double, 4>> at;  // distances from the corners
  at.resize(candidates.size());
  size_t best_at[4] = {SIZE_MAX, SIZE_MAX, SIZE_MAX, SIZE_MAX};
  for (size_t k = 0; k < candidates.size(); ++k) {
    if (!views[k].plain_point()) continue;
    for (int i = 0; i < 4; ++i) {
      at[k][i] = Distance(corners[i], views[k].point);
      if (best_at[i] == SIZE_MAX || Beats(kDiagram, at[k][i], at[best_at[i]][i])) best_at[i] = k;
    }
  }
  const double slack = 2 * Rounding(c);
  // Whether distance x exceeds y beyond rounding.
  auto beyond = [&](double x, double y) { return x > y * (1 + 1e-12) + slack; };
  auto clipped = [&](size_t k) {
    for (size_t w : best_at) {
      if (w == SIZE_MAX || w == k) continue;
      bool beaten = true;
      for (int i = 0; i < 4 && beaten; ++i) {
        beaten = farthest ? beyond(at[w][i], at[k][i]) : beyond(at[k][i], at[w][i]);
      }
      if (beaten) return true;
    }
    return false;
  };
  const bool plain_best = !farthest && s1 != SIZE_MAX && views[s1].plain_point();
  for (size_t k = 0; k < candidates.size(); ++k) {
    const SiteView& s = views[k];
    if (s.plain_point() && clipped(k)) continue;
    if (loses(farthest ? high(k) : low(k))) continue;
    if (dist[k] - h > (s.max_distance() + margin) * (1 + 1e-12)) continue;  // absent on C
    if (!InsideReach(s, cell, margin)) continue;
    // Nearest only: a plain point no nearer than s1 at any corner is nowhere nearer.
    if (plain_best && s.plain_point() && k != s1 &&
        !BeatsSomewhere(s.point, views[s1].point, cell)) {
      continue;
    }
    slots->push_back(candidates[k]);
    // A plain point's farthest distance over the cell is exact and cheap; another site's
    // bound (four corners by every segment) costs more than d(c) + h, which also holds.
    if (radii) {
      radii->push_back(s.plain_point() ? RadiusFor(s, cell)
                                       : std::min((dist[k] + h) * (1 + 0x1p-40),
                                                  s.max_distance() + margin));
    }
  }
  return bound;
}

void TileCover::NeededSegments(const Grid& grid, PixelRect tile, const Site& site,
                               double upper, std::vector<uint32_t>* out) {
  const Window box = grid.CentreBox(tile);
  const Vec2 c{(box.min_x + box.max_x) / 2, (box.min_y + box.max_y) / 2};
  const double h = Distance({box.min_x, box.min_y}, {box.max_x, box.max_y}) / 2 + Rounding(c);
  const double m = site.multiplicative, a = site.additive;
  // Rounding slack: the tests may keep a segment too many, never one too few.
  auto needed = [&](double d, double nearest) {
    const double lower = std::max(0.0, d - h);
    return lower <= nearest * (1 + 1e-12) && m * lower + a <= upper * (1 + 1e-12);
  };
  if (site.segment_tree) {
    const double nearest = site.segment_tree->Nearest(c).distance + h;
    // Segments farther from c than N + h, or than (U - a) / m + h, fail a test (both with
    // the tests' slack).
    double reach = nearest * (1 + 1e-12) + h;
    if (std::isfinite(upper)) {
      reach = std::min(reach, std::max(0.0, (upper * (1 + 1e-12) - a) / m) + h);
    }
    const size_t from = out->size();
    site.segment_tree->Within(c, reach * (1 + 1e-9), [&](uint32_t j, Vec2 p, Vec2 q) {
      if (needed(SegmentDistance(c, p, q), nearest)) out->push_back(j);
    });
    // A long segment comes once for each of its pieces near c.
    std::sort(out->begin() + static_cast<ptrdiff_t>(from), out->end());
    out->erase(std::unique(out->begin() + static_cast<ptrdiff_t>(from), out->end()), out->end());
    return;
  }
  thread_local std::vector<double> dist;
  dist.clear();
  double nearest = INFINITY;
  ForEachSegment(site.geometry, [&](Vec2 p, Vec2 q) {
    dist.push_back(SegmentDistance(c, p, q));
    nearest = std::min(nearest, dist.back() + h);
  });
  for (uint32_t j = 0; j < dist.size(); ++j) {
    if (needed(dist[j], nearest)) out->push_back(j);
  }
}

Side TileCover::TileSide(const Grid& grid, PixelRect tile, const Site& site) {
  const Window box = grid.CentreBox(tile);
  const Vec2 c{(box.min_x + box.max_x) / 2, (box.min_y + box.max_y) / 2};
  const double h = Distance({box.min_x, box.min_y}, {box.max_x, box.max_y}) / 2 + Rounding(c);
  // The boundary is farther than the margin from every centre: none is on it, nor near it,
  // and all lie on the side of c.
  // (The drawn outline's distance: the rasterizer tests the side of that.)
  if (!(DrawnDistance(c, site) - h > DrawMargin(grid) * (1 + 1e-12))) return Side::kBoth;
  return InsideOf(c, site.geometry) ? Side::kInside : Side::kOutside;
}

void TileCover::CoverDown(PixelRect tile, uint32_t leaf_px, const Leaf& leaf) const {
  thread_local std::vector<uint32_t> candidates;
  candidates.clear();
  Candidates(tile, &candidates);
  Descend(tile, candidates, std::max(leaf_px, 1u), 0, leaf);
}

void TileCover::Descend(PixelRect tile, std::span<const uint32_t> parent, uint32_t leaf_px,
                        size_t depth, const Leaf& leaf) const {
  // One list per depth, reused; sized once, so that a parent's list never moves while its
  // halves are kept (64 levels split 2^64 leaves).
  thread_local std::vector<std::vector<uint32_t>> lists(64);
  thread_local std::vector<double> radii;
  std::vector<uint32_t>& slots = lists[depth];
  slots.clear();
  if (tile.width() <= leaf_px && tile.height() <= leaf_px) {
    radii.clear();
    const double upper = Keep(tile, parent, &slots, &radii);
    leaf(tile, slots, radii, upper);
    return;
  }
  Keep(tile, parent, &slots, nullptr);
  // Split where the first half holds half the leaves (rounded up).
  auto mid = [&](uint32_t a, uint32_t b) {
    uint32_t leaves = (b - a + leaf_px - 1) / leaf_px;
    return b - a <= leaf_px ? b : a + (leaves + 1) / 2 * leaf_px;
  };
  const uint32_t xs[3] = {tile.x0, mid(tile.x0, tile.x1), tile.x1};
  const uint32_t ys[3] = {tile.y0, mid(tile.y0, tile.y1), tile.y1};
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      PixelRect half{xs[i], ys[j], xs[i + 1], ys[j + 1]};
      if (!half.empty()) Descend(half, slots, leaf_px, depth + 1, leaf);
    }
  }
}

std::unique_ptr<const PointCover> PointCover::Of(const Grid& grid, const SlotTable& sites) {
  // Squared distances neither underflow nor overflow within the window's scale, nor for
  // points up to 2^400 away (beyond, the index's path, which measures with hypot).
  const Window& w = grid.window;
  if (!(grid.pixel_size() > 0x1p-400) ||
      !(std::max({std::abs(w.min_x), std::abs(w.max_x), std::abs(w.min_y), std::abs(w.max_y)}) <
        0x1p400)) {
    return nullptr;
  }
  std::vector<uint32_t> slots;
  std::vector<Vec2> points;
  slots.reserve(sites.size());
  points.reserve(sites.size());
  size_t outside = 0;
  for (uint32_t s = 0; s < sites.size(); ++s) {
    const Vec2 p = sites.point(s);
    if (!std::isnan(p.x)) {
      if (!(std::abs(p.x) < 0x1p400 && std::abs(p.y) < 0x1p400)) return nullptr;
      outside += !w.Contains(p);
      slots.push_back(s);
      points.push_back(p);
    } else if (sites.get(s) != nullptr) {
      return nullptr;  // a live site that is not a plain point
    }
  }
  // Points outside the window crowd the buckets at its edge: where they are many (a window
  // on part of a scene), the index's path, which finds only those within reach.
  if (slots.empty() || outside * 4 > slots.size()) return nullptr;
  // Buckets about as wide as the points' mean spacing (a point or two each), at least four
  // pixels: a tile's search then visits a few dozen buckets.
  const double spacing = std::sqrt(double(grid.pixel_count()) / double(slots.size()));
  uint32_t bucket_px = 4;
  while (bucket_px < spacing && bucket_px < 1024) bucket_px *= 2;
  std::unique_ptr<PointCover> cover(new PointCover(grid, bucket_px));
  PointCover& c = *cover;
  std::vector<uint32_t> bucket(slots.size());
  c.start_.assign(size_t{c.columns_} * c.rows_ + 1, 0);
  for (size_t k = 0; k < slots.size(); ++k) {
    const Vec2 p = points[k];
    bucket[k] = c.Row(p.y) * c.columns_ + c.Column(p.x);
    ++c.start_[bucket[k] + 1];
  }
  for (size_t b = 1; b < c.start_.size(); ++b) c.start_[b] += c.start_[b - 1];
  c.x_.resize(slots.size());
  c.y_.resize(slots.size());
  c.slot_.resize(slots.size());
  std::vector<uint32_t> next(c.start_.begin(), c.start_.end() - 1);
  for (size_t k = 0; k < slots.size(); ++k) {
    const uint32_t at = next[bucket[k]]++;
    c.x_[at] = points[k].x;
    c.y_[at] = points[k].y;
    c.slot_[at] = slots[k];
  }
  return cover;
}

PointCover::PointCover(const Grid& grid, uint32_t bucket_px)
    : grid_(grid),
      columns_((grid.width + bucket_px - 1) / bucket_px),
      rows_((grid.height + bucket_px - 1) / bucket_px),
      bucket_w_(bucket_px * grid.pixel_width()),
      bucket_h_(bucket_px * grid.pixel_height()) {}

uint32_t PointCover::Column(double x) const {
  const double f = std::floor((x - grid_.window.min_x) / bucket_w_);
  return !(f > 0) ? 0 : f >= columns_ - 1 ? columns_ - 1 : static_cast<uint32_t>(f);
}

uint32_t PointCover::Row(double y) const {
  const double f = std::floor((y - grid_.window.min_y) / bucket_h_);
  return !(f > 0) ? 0 : f >= rows_ - 1 ? rows_ - 1 : static_cast<uint32_t>(f);
}

double PointCover::Cover(PixelRect tile, std::vector<uint32_t>* slots,
                         std::vector<double>* radii) const {
  const Vec2 lo = grid_.Center(tile.x0, tile.y0), hi = grid_.Center(tile.x1 - 1, tile.y1 - 1);
  const Vec2 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2};
  const double h = Distance(lo, hi) / 2 + Rounding(c);
  const double slack = 2 * Rounding(c);
  auto squared = [&](uint32_t k, Vec2 q) {
    const double dx = x_[k] - q.x, dy = y_[k] - q.y;
    return dx * dx + dy * dy;
  };
  // The point nearest to c, ring by ring of buckets around c's, until no bucket beyond the
  // rings can hold a nearer one. (One found a hair's breadth from the nearest by rounding
  // serves as well: any plain point gives a valid U and valid bisectors.)
  const int64_t cx = Column(c.x), cy = Row(c.y);
  const int64_t columns = columns_, rows = rows_;
  double near2 = INFINITY;
  uint32_t nearest = 0;
  auto visit = [&](int64_t i, int64_t j) {
    const size_t b = static_cast<size_t>(j * columns + i);
    for (uint32_t k = start_[b]; k < start_[b + 1]; ++k) {
      const double d2 = squared(k, c);
      if (d2 < near2) {
        near2 = d2;
        nearest = k;
      }
    }
  };
  for (int64_t r = 0;; ++r) {
    const int64_t i0 = cx - r, i1 = cx + r, j0 = cy - r, j1 = cy + r;
    for (int64_t j = std::max<int64_t>(j0, 0); j <= std::min(j1, rows - 1); ++j) {
      if (j == j0 || j == j1) {
        for (int64_t i = std::max<int64_t>(i0, 0); i <= std::min(i1, columns - 1); ++i) visit(i, j);
      } else {
        if (i0 >= 0) visit(i0, j);
        if (i1 < columns) visit(i1, j);
      }
    }
    // How near c a bucket beyond the rings can come.
    double beyond = INFINITY;
    if (i0 > 0) beyond = std::min(beyond, c.x - (grid_.window.min_x + i0 * bucket_w_));
    if (i1 + 1 < columns) {
      beyond = std::min(beyond, grid_.window.min_x + (i1 + 1) * bucket_w_ - c.x);
    }
    if (j0 > 0) beyond = std::min(beyond, c.y - (grid_.window.min_y + j0 * bucket_h_));
    if (j1 + 1 < rows) beyond = std::min(beyond, grid_.window.min_y + (j1 + 1) * bucket_h_ - c.y);
    if (beyond == INFINITY) break;  // every bucket visited
    beyond = std::max(beyond, 0.0);
    if (near2 <= beyond * beyond) break;
  }
  // U, from the nearest point (present on all of C); the points whose least value over C,
  // d - h, can reach it lie within U + h of c (with Keep's rounding slack, and more).
  const double upper = std::sqrt(near2) + h;
  const double reach = (upper * (1 + 1e-12) + h) * (1 + 1e-12) + slack;
  const double reach2 = reach * reach;
  const Vec2 corners[4] = {lo, {hi.x, lo.y}, {lo.x, hi.y}, hi};
  // The points within reach, as columns: where they are, then their squared distances from
  // the corners (loops the compiler vectorizes).
  thread_local std::vector<double> gx, gy, at[4];
  thread_local std::vector<uint32_t> gk;
  const uint32_t ci0 = Column(c.x - reach), ci1 = Column(c.x + reach);
  const uint32_t cj0 = Row(c.y - reach), cj1 = Row(c.y + reach);
  size_t n = 0;
  for (uint32_t j = cj0; j <= cj1; ++j) {
    const uint32_t from = start_[size_t{j} * columns_ + ci0];
    const uint32_t to = start_[size_t{j} * columns_ + ci1 + 1];
    if (gx.size() < n + (to - from)) {
      for (auto* v : {&gx, &gy}) v->resize(2 * (n + (to - from)));
      gk.resize(gx.size());
    }
    for (uint32_t k = from; k < to; ++k) {
      gx[n] = x_[k];
      gy[n] = y_[k];
      gk[n] = k;
      n += squared(k, c) <= reach2;
    }
  }
  for (auto& a : at) {
    if (a.size() < n) a.resize(gx.size());
  }
  // The point nearest to each corner, among them (any point would do).
  double witness[5][2] = {{x_[nearest], y_[nearest]}};
  for (int i = 0; i < 4; ++i) {
    double* a = at[i].data();
    const double qx = corners[i].x, qy = corners[i].y;
    for (size_t m = 0; m < n; ++m) {
      const double dx = gx[m] - qx, dy = gy[m] - qy;
      a[m] = dx * dx + dy * dy;
    }
    size_t best = 0;
    for (size_t m = 1; m < n; ++m) best = a[m] < a[best] ? m : best;
    witness[i + 1][0] = gx[best];
    witness[i + 1][1] = gy[best];
  }
  // The bisector tests of Keep on squared distances: a point is dropped when, for one of
  // the five witnesses w (the nearest to c and to each corner), at every corner x its squared
  // distance exceeds (|x w| (1 + 1e-12) + slack)^2 (Keep's test, squared) with room for the
  // squares' rounding (1e-14, far above their few ulps). So a point dropped here is one that
  // Keep's tests drop with the same witnesses.
  double beaten[5][4];
  for (int w = 0; w < 5; ++w) {
    for (int i = 0; i < 4; ++i) {
      const double dx = witness[w][0] - corners[i].x, dy = witness[w][1] - corners[i].y;
      const double b = std::sqrt(dx * dx + dy * dy) * (1 + 1e-12) + slack;
      beaten[w][i] = b * b * (1 + 1e-14);
    }
  }
  const double *a0 = at[0].data(), *a1 = at[1].data(), *a2 = at[2].data(), *a3 = at[3].data();
  for (size_t m = 0; m < n; ++m) {
    bool dropped = false;
    for (int w = 0; w < 5; ++w) {
      dropped |= (a0[m] > beaten[w][0]) & (a1[m] > beaten[w][1]) & (a2[m] > beaten[w][2]) &
                 (a3[m] > beaten[w][3]);
    }
    if (dropped) continue;
    slots->push_back(slot_[gk[m]]);
    // Its distance from the farthest centre, as RadiusFor's.
    radii->push_back(std::sqrt(std::max(std::max(a0[m], a1[m]), std::max(a2[m], a3[m]))) *
                     (1 + 0x1p-40));
  }
  return upper;
}

namespace {

// The proof of ComputeCoverage, tile by tile: calls keep(slot, radius, leaf) for every site
// that must cover some pixel centre of a smallest tile `leaf`, with the radius that tile
// needs (a site may be kept by several tiles). Returns the smallest tiles' side.
template <class KeepFn>
uint32_t CoverTiles(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                    PixelRect region, uint32_t tile_px, Diagram diagram, KeepFn&& keep) {
  tile_px = tile_px ? tile_px : DefaultTilePx(grid, index.size());
  if (region.empty()) return tile_px;
  const TileCover cover(grid, sites, index, diagram);
  // kFarthest: every site is a candidate at first, so the region is one tile, split down.
  const uint32_t top = diagram == Diagram::kFarthest
                           ? std::max(region.width(), region.height())
                           : TopTilePx(grid, index.size(), tile_px);
  const TileCover::Leaf leaf = [&](PixelRect rect, std::span<const uint32_t> slots,
                                   std::span<const double> radii, double upper) {
    for (size_t k = 0; k < slots.size(); ++k) keep(slots[k], radii[k], rect, upper);
  };
  for (uint32_t ty = region.y0; ty < region.y1; ty += top) {
    for (uint32_t tx = region.x0; tx < region.x1; tx += top) {
      cover.CoverDown({tx, ty, std::min(tx + top, region.x1), std::min(ty + top, region.y1)},
                      tile_px, leaf);
    }
  }
  return tile_px;
}

}  // namespace

Coverage ComputeCoverage(const Grid& grid, const SlotTable& sites, const SiteIndex& index,
                         PixelRect region, uint32_t tile_px, Diagram diagram, bool pieces) {
  Coverage cov;
  cov.radius.assign(sites.size(), -1);
  cov.clip.assign(sites.size(), PixelRect{});
  pieces = pieces && diagram == Diagram::kNearest;  // kFarthest draws no site by pieces
  if (pieces) cov.pieces.resize(sites.size());
  PieceCover piece_cover(grid);
  cov.tile_px = CoverTiles(grid, sites, index, region, tile_px, diagram,
                           [&](uint32_t slot, double radius, PixelRect rect, double upper) {
                             cov.radius[slot] = std::max(cov.radius[slot], radius);
                             cov.clip[slot] = cov.clip[slot].Union(rect);
                             ++cov.pairs;
                             if (pieces) {
                               piece_cover.Cover(sites, slot, rect, upper, &cov.pieces[slot]);
                             }
                           });
  return cov;
}

std::vector<SiteDraw> SparseCoverage(const Grid& grid, const SlotTable& sites,
                                     const SiteIndex& index, PixelRect region, uint32_t tile_px,
                                     Diagram diagram, bool pieces) {
  DrawsBySlot drawn;
  pieces = pieces && diagram == Diagram::kNearest;  // kFarthest draws no site by pieces
  PieceCover piece_cover(grid);
  CoverTiles(grid, sites, index, region, tile_px, diagram,
             [&](uint32_t slot, double r, PixelRect rect, double upper) {
               SiteDraw& d = drawn.Add(slot, r, rect);
               if (pieces) piece_cover.Cover(sites, slot, rect, upper, &d.pieces);
             });
  return drawn.Take();
}

SiteDraw& DrawsBySlot::Add(uint32_t slot, double radius, PixelRect tile) {
  auto [it, fresh] = drawn_.try_emplace(slot, SiteDraw{slot, radius, tile});
  if (!fresh) {
    it->second.radius = std::max(it->second.radius, radius);
    it->second.clip = it->second.clip.Union(tile);
  }
  return it->second;
}

std::vector<SiteDraw> DrawsBySlot::Take() {
  std::vector<SiteDraw> out;
  out.reserve(drawn_.size());
  for (auto& [slot, d] : drawn_) out.push_back(std::move(d));
  drawn_.clear();
  std::sort(out.begin(), out.end(),
            [](const SiteDraw& a, const SiteDraw& b) { return a.slot < b.slot; });
  return out;
}

Coverage ParallelCoverage(const Grid& grid, const SiteSnapshot& snapshot, PixelRect region,
                          Diagram diagram, bool pieces) {
  const SlotTable& slots = snapshot.sites();
  const SiteIndex& index = snapshot.index();
  const uint32_t leaf = DefaultTilePx(grid, snapshot.size(), snapshot.ink());
  const uint32_t top = TopTilePx(grid, index.size(), leaf);
  const size_t bands = (size_t{region.height()} + top - 1) / top;
  if (bands < 2) {
    return ComputeCoverage(grid, slots, index, region, leaf, diagram, pieces);
  }
  std::mutex mu;
  std::vector<Coverage> parts;
  ParallelFor(bands, 1, [&](size_t begin, size_t end) {
    PixelRect band{region.x0, static_cast<uint32_t>(region.y0 + begin * top), region.x1,
                   static_cast<uint32_t>(std::min<size_t>(region.y0 + end * top, region.y1))};
    Coverage part = ComputeCoverage(grid, slots, index, band, leaf, diagram, pieces);
    std::lock_guard<std::mutex> lock(mu);
    parts.push_back(std::move(part));
  });
  Coverage cov = std::move(parts[0]);
  for (size_t p = 1; p < parts.size(); ++p) {
    const Coverage& part = parts[p];
    cov.pairs += part.pairs;
    for (uint32_t s = 0; s < slots.size(); ++s) {
      if (part.radius[s] < 0) continue;
      cov.radius[s] = std::max(cov.radius[s], part.radius[s]);
      cov.clip[s] = cov.clip[s].Union(part.clip[s]);
      if (s >= part.pieces.size() || part.pieces[s].empty()) continue;
      std::vector<PieceDraw>& into = cov.pieces[s];
      into.resize(std::max(into.size(), part.pieces[s].size()));
      for (size_t k = 0; k < part.pieces[s].size(); ++k) {
        into[k].radius = std::max(into[k].radius, part.pieces[s][k].radius);
        into[k].clip = into[k].clip.Union(part.pieces[s][k].clip);
        into[k].from = std::min(into[k].from, part.pieces[s][k].from);
        into[k].to = std::max(into[k].to, part.pieces[s][k].to);
      }
    }
  }
  return cov;
}

}  // namespace gvd
