// Zoom windows, boundaries and refined neighbours on rendered frames, against the exact
// oracle and against Qhull's Delaunay triangulation.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <set>

#include "render/analysis/analysis.h"
#include "render/kernel/exact2.h"
#include "render/analysis/refine.h"
#include "render/gl/zoom.h"
#include "tests/support/gl_fixture.h"
#include "tests/support/oracle.h"
#include "tests/support/pixel_oracle.h"
#include "tests/support/qhull_delaunay.h"


namespace gvd {
namespace {

class AnalysisGLTest : public GlTest {
 protected:
  ZoomFn Zoomer(const std::shared_ptr<const Frame>& frame, RenderMode mode) {
    return [this, frame, mode](const std::vector<Grid>& grids) {
      return zoom_.Render(*rasterizer_, *frame, mode, grids);
    };
  }
  ZoomRenderer zoom_;
};

// Zoom windows inside, across and far outside the window, and one so deep that the far
// sites' fans hit the triangle cap and float coordinates lose the pixel: every pixel of each
// still holds against the oracle within the bound the zoomed frame reports.
TEST_F(AnalysisGLTest, ZoomWindowsHoldAgainstTheOracle) {
  Generator gen(41);
  SiteTable sites;
  for (int s = 0; s < 21; ++s) {
    Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
    if (s % 4 == 1) site.additive = gen.U(0, 0.1);
    if (s % 4 == 2) site.multiplicative = gen.U(0.5, 2);
    if (s % 5 == 3) site.max_distance = gen.U(0.1, 0.4);
    sites.push_back(site);
  }
  const std::vector<Grid> zooms = {
      {{0.3, 0.3, 0.45, 0.42}, 120, 96},         // inside
      {{-0.2, 0.8, 0.2, 1.3}, 64, 80},           // across the border
      {{3, 3, 3.5, 3.2}, 50, 20},                // far outside: only far sites reach it
      {{0.5, 0.5, 0.5001, 0.5001}, 64, 64},      // 10,000 times finer
      {{0.61, 0.27, 0.61 + 1e-7, 0.27 + 1e-7}, 32, 32},  // beyond float precision
  };
  for (Diagram diagram : {Diagram::kNearest, Diagram::kFarthest}) {
    for (RenderMode mode : kModes) {
      auto base = Render({{0, 0, 1, 1}, 96, 96}, sites, mode, diagram);
      ASSERT_NE(base, nullptr);
      auto frames = zoom_.Render(*rasterizer_, *base, mode, zooms);
      ASSERT_TRUE(frames.ok()) << frames.status();
      for (size_t k = 0; k < zooms.size(); ++k) {
        const Frame& f = *(*frames)[k];
        EXPECT_EQ(f.version(), base->version());
        EXPECT_EQ(f.grid().width, zooms[k].width);
        CheckEveryPixel(f, sites, std::string(Name(mode)) + " zoom " + std::to_string(k) +
                                      (diagram == Diagram::kFarthest ? " farthest" : ""));
      }
    }
  }
}

// Sites: random points, segments and triangles, none inside another's box: convex sites, so
// the continuation method finds exactly what the full scan finds.
SiteTable ConvexScene(uint64_t seed, int n) {
  Generator gen(seed);
  SiteTable sites;
  std::vector<Window> boxes;
  while (int(sites.size()) < n) {
    Geometry g;
    int kind = int(sites.size()) % 3;
    Vec2 c = gen.P();
    if (kind == 0) {
      g = PointSite{c};
    } else if (kind == 1) {
      g = SegmentSite{c, gen.Near(c, 0.15)};
    } else {
      double r = gen.U(0.02, 0.08), t = gen.U(0, 2 * M_PI);
      g = PolygonSite{{{c.x + r * std::cos(t), c.y + r * std::sin(t)},
                       {c.x + r * std::cos(t + 2.1), c.y + r * std::sin(t + 2.1)},
                       {c.x + r * std::cos(t + 4.2), c.y + r * std::sin(t + 4.2)}}};
    }
    Window b = BoundingBox(g);
    bool clear = true;
    for (const Window& o : boxes) {
      clear = clear && (b.max_x < o.min_x || o.max_x < b.min_x || b.max_y < o.min_y ||
                        o.max_y < b.min_y);
    }
    if (!clear) continue;
    boxes.push_back(b);
    sites.push_back({std::to_string(sites.size()), g});
  }
  return sites;
}

TEST_F(AnalysisGLTest, ContinuationAgreesWithTheFullScanOnConvexSites) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    SiteTable sites = ConvexScene(seed, 12);
    for (RenderMode mode : kModes) {
      auto f = Render({{0, 0, 1, 1}, 200, 160}, sites, mode);
      IdImage image = IdsOf(*f, f->grid().all());
      BoundaryEdges full = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
      BoundaryEdges walk = FindBoundaryEdges(image, BoundaryMethod::kContinuation);
      EXPECT_GT(full.count, 100u);
      EXPECT_EQ(full.horizontal, walk.horizontal) << "seed " << seed << " " << Name(mode);
      EXPECT_EQ(full.vertical, walk.vertical) << "seed " << seed << " " << Name(mode);
      EXPECT_LT(walk.cells_visited, full.cells_visited / 4);
      // Each crossing between sites lies on their exact boundary, up to the pixel labels'
      // error: where both pixels are right, the two sites' distances agree there.
      auto lines = TraceBoundaries(image, full, f->sites(), Diagram::kNearest);
      for (const auto& l : lines) {
        const Site *a = f->sites().get(l.a - 1), *b = f->sites().get(l.b - 1);
        for (size_t k = 1; k + 1 < l.points.size(); ++k) {
          Vec2 p = l.points[k];
          double da = oracle::Distance(p, a->geometry), db = oracle::Distance(p, b->geometry);
          oracle::Best best = oracle::BestSite(p, sites);
          // On the a|b boundary (or, where a pixel's label was off by the mesh's error, within
          // a pixel of it) and no site much nearer.
          EXPECT_LT(std::abs(da - db), 2 * f->grid().pixel_diagonal());
          EXPECT_LE(std::min(da, db) - best.value, 2 * f->eps() + 1e-9);
        }
      }
    }
  }
}

TEST_F(AnalysisGLTest, ContinuationMissesAnIslandInsideAConcaveSite) {
  // Sites: a point inside the cup of a concave polyline, and points outside: the inner
  // point's region is an island that no boundary from the window's border reaches.
  SiteTable sites = {
      {"cup", PolylineSite{{{0.6, 0.3}, {0.3, 0.3}, {0.3, 0.7}, {0.7, 0.7}, {0.7, 0.35}}}},
      {"in", PointSite{{0.5, 0.5}}},
      {"p", PointSite{{0.9, 0.1}}},
      {"q", PointSite{{0.1, 0.9}}}};
  for (RenderMode mode : kModes) {
    auto f = Render({{0, 0, 1, 1}, 160, 160}, sites, mode);
    IdImage image = IdsOf(*f, f->grid().all());
    BoundaryEdges full = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
    BoundaryEdges walk = FindBoundaryEdges(image, BoundaryMethod::kContinuation);
    NeighborCounts all = NeighborPairs(image, full), walked = NeighborPairs(image, walk);
    EXPECT_TRUE(all.count({1, 2})) << "the full scan finds the island";
    EXPECT_FALSE(walked.count({1, 2})) << "the walk cannot reach it";
    EXPECT_LT(walk.count, full.count);
  }
}

Vec2 Circumcentre(Vec2 a, Vec2 b, Vec2 c) {
  double d = 2 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
  double a2 = glm::dot(a, a), b2 = glm::dot(b, b), c2 = glm::dot(c, c);
  return {(a2 * (b.y - c.y) + b2 * (c.y - a.y) + c2 * (a.y - b.y)) / d,
          (a2 * (c.x - b.x) + b2 * (a.x - c.x) + c2 * (b.x - a.x)) / d};
}

// Length of the part of segment pq (or of the ray from p through q, when `ray`) inside w.
double ClippedLength(Vec2 p, Vec2 q, bool ray, const Window& w) {
  double t0 = 0, t1 = ray ? 1e9 : 1;
  Vec2 d = q - p;
  auto clip = [&](double num, double den) {
    if (den == 0) return num >= 0;
    double t = num / den;
    if (den < 0) t0 = std::max(t0, t);
    else t1 = std::min(t1, t);
    return true;
  };
  if (!clip(p.x - w.min_x, -d.x) || !clip(w.max_x - p.x, d.x) || !clip(p.y - w.min_y, -d.y) ||
      !clip(w.max_y - p.y, d.y) || t0 >= t1) {
    return 0;
  }
  return (t1 - t0) * Length(d);
}

// The length inside the window of the exact Voronoi edge dual to each Delaunay edge.
std::map<std::pair<uint32_t, uint32_t>, double> VoronoiEdgeLengths(
    const std::vector<Vec2>& pts, const std::vector<std::array<uint32_t, 3>>& tris,
    const Window& window) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<Vec2, uint32_t>>> sides;
  for (const auto& t : tris) {
    Vec2 o = Circumcentre(pts[t[0]], pts[t[1]], pts[t[2]]);
    for (int a = 0; a < 3; ++a) {
      uint32_t x = t[a], y = t[(a + 1) % 3], z = t[(a + 2) % 3];
      sides[{std::min(x, y), std::max(x, y)}].push_back({o, z});
    }
  }
  std::map<std::pair<uint32_t, uint32_t>, double> out;
  for (const auto& [e, s] : sides) {
    if (s.size() == 2) {
      out[e] = ClippedLength(s[0].first, s[1].first, false, window);
    } else {  // a hull edge: a ray away from the third vertex
      Vec2 a = pts[e.first], b = pts[e.second], mid = 0.5 * (a + b);
      Vec2 n{-(b.y - a.y), b.x - a.x};
      if (glm::dot(n, pts[s[0].second] - mid) > 0) n = -1.0 * n;
      out[e] = ClippedLength(s[0].first, s[0].first + n, true, window);
    }
  }
  return out;
}

struct Agreement {
  size_t edges = 0, missing = 0, extra = 0;
  // The longest Voronoi edge of a missing pair, and of a true pair crossed by an extra one:
  // over the window, and over the span of the pixel centres (what the raster samples).
  double worst_missing_px = 0, worst_missing_sampled_px = 0;
  double worst_extra_sampled_px = 0;
};

// Our pairs (ids, slot + 1) against Qhull's edges. `window_px` and `sampled_px` give each
// Delaunay edge's Voronoi edge length inside the window and inside the pixel centres' span.
Agreement Compare(const std::vector<Vec2>& pts, const std::set<std::pair<uint32_t, uint32_t>>& qhull,
                  const std::map<std::pair<uint32_t, uint32_t>, double>& window_px,
                  const std::map<std::pair<uint32_t, uint32_t>, double>& sampled_px,
                  const NeighborCounts& ours) {
  Agreement a;
  std::set<std::pair<uint32_t, uint32_t>> mine;
  for (const auto& [pair, n] : ours) mine.insert({pair.first - 1, pair.second - 1});
  a.edges = mine.size();
  for (const auto& e : qhull) {
    double len = window_px.count(e) ? window_px.at(e) : 0;
    if (len == 0 || mine.count(e)) continue;  // outside the window, or found
    ++a.missing;
    a.worst_missing_px = std::max(a.worst_missing_px, len);
    a.worst_missing_sampled_px = std::max(a.worst_missing_sampled_px, sampled_px.at(e));
  }
  for (const auto& e : mine) {
    if (qhull.count(e)) continue;
    ++a.extra;
    // Trace it to the true edge it crosses: the other diagonal of their quadrilateral.
    Vec2 p = pts[e.first], q = pts[e.second];
    double crossed = 0;
    for (const auto& t : qhull) {
      Vec2 r = pts[t.first], s = pts[t.second];
      auto side = [](Vec2 o, Vec2 u, Vec2 v) {
        return (u.x - o.x) * (v.y - o.y) - (u.y - o.y) * (v.x - o.x);
      };
      if (side(p, q, r) * side(p, q, s) < 0 && side(r, s, p) * side(r, s, q) < 0) {
        crossed = std::max(crossed, sampled_px.at(t));
      }
    }
    a.worst_extra_sampled_px = std::max(a.worst_extra_sampled_px, crossed);
  }
  return a;
}

// Delaunay from the diagram of random points at 2048x2048, against Qhull. The raster's own
// pairs (paper sec. 5) disagree where regions are thinner than the pixels (resolution error,
// sec. 6.2). Refined by zoom windows, every edge whose Voronoi edge crosses the window
// matches, but for edges shorter than the finest zoom's pixel; no pair is spurious.
TEST_F(AnalysisGLTest, DelaunayMatchesQhull) {
  const Grid grid{{0, 0, 1, 1}, 2048, 2048};
  const RefineOptions options;
  const double finest_px = std::pow(double(options.factor), -double(options.max_depth));
  const Window centres{grid.Center(0, 0).x, grid.Center(0, 0).y,
                       grid.Center(grid.width - 1, 0).x, grid.Center(0, grid.height - 1).y};
  for (int n : {1000, 10000}) {
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Vec2> pts(n);
    SiteTable sites;
    for (int i = 0; i < n; ++i) {
      pts[i] = {u(rng), u(rng)};
      sites.push_back({std::to_string(i), PointSite{pts[i]}});
    }
    std::vector<std::array<uint32_t, 3>> tris;
    auto qhull = testing::QhullEdges(pts, &tris);
    auto window_px = VoronoiEdgeLengths(pts, tris, grid.window);
    auto sampled_px = VoronoiEdgeLengths(pts, tris, centres);
    for (auto* m : {&window_px, &sampled_px}) {
      for (auto& [e, len] : *m) len /= grid.pixel_size();
    }
    auto f = Render(grid, sites, RenderMode::kMesh);
    ASSERT_NE(f, nullptr);
    auto raw = RefineNeighbors(*f, grid.all(), nullptr);
    ASSERT_TRUE(raw.ok());
    auto start = std::chrono::steady_clock::now();
    auto refined = RefineNeighbors(*f, grid.all(), Zoomer(f, RenderMode::kExact), options);
    ASSERT_TRUE(refined.ok()) << refined.status();
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    Agreement before = Compare(pts, qhull, window_px, sampled_px, raw->pairs);
    Agreement after = Compare(pts, qhull, window_px, sampled_px, refined->pairs);
    std::printf("%d points: Qhull %zu edges; raster %zu pairs, %zu missing (longest %.3g px, "
                "%.3g px between centres), %zu extra (crossing %.3g px); refined with %zu "
                "windows to depth %u in %.2f s: %zu missing (longest %.3g px), %zu extra\n",
                n, qhull.size(), before.edges, before.missing, before.worst_missing_px,
                before.worst_missing_sampled_px, before.extra, before.worst_extra_sampled_px,
                refined->windows, refined->depth, seconds, after.missing,
                after.worst_missing_px, after.extra);
    // The raster alone gets nearly every pair, and misses where regions are thinner than the
    // pixels: short Voronoi edges, or longer ones between slivers.
    EXPECT_LT(before.missing + before.extra, qhull.size() / 30);
    EXPECT_LT(after.worst_missing_px, finest_px) << after.missing << " missing";
    EXPECT_EQ(after.extra, 0u);
    EXPECT_TRUE(refined->complete);
    // The triangles from the refined pairs are Qhull's.
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
    for (const auto& [p, c] : refined->pairs) pairs.push_back({p.first - 1, p.second - 1});
    auto ours = TrianglesFromEdges(pts, pairs);
    std::set<std::array<uint32_t, 3>> theirs;
    for (auto t : tris) {
      std::sort(t.begin(), t.end());
      theirs.insert(t);
    }
    size_t matched = 0;
    for (auto t : ours) {
      std::sort(t.begin(), t.end());
      matched += theirs.count(t);
    }
    EXPECT_EQ(matched, ours.size());
    EXPECT_GT(ours.size(), tris.size() * 9 / 10);
  }
}

// A site whose region falls between pixel centres holds no pixel: the refinement names it
// and finds it by zooming, with its neighbours.
TEST_F(AnalysisGLTest, HiddenSitesAreFoundByZooming) {
  // Sites: a point ringed by six others 1/10 pixel away, among a few far ones.
  const Grid grid{{0, 0, 1, 1}, 64, 64};
  const double r = grid.pixel_size() / 10;
  const Vec2 c{0.5 + 0.3 * grid.pixel_size(), 0.5 + 0.2 * grid.pixel_size()};
  SiteTable sites = {{"centre", PointSite{c}}};
  for (int k = 0; k < 6; ++k) {
    double t = k * M_PI / 3;
    sites.push_back({"ring" + std::to_string(k), PointSite{{c.x + r * std::cos(t), c.y + r * std::sin(t)}}});
  }
  sites.push_back({"far1", PointSite{{0.1, 0.1}}});
  sites.push_back({"far2", PointSite{{0.9, 0.8}}});
  for (RenderMode mode : kModes) {
    auto f = Render(grid, sites, mode);
    auto plain = RefineNeighbors(*f, grid.all(), nullptr);
    ASSERT_TRUE(plain.ok());
    ASSERT_EQ(plain->hidden, std::vector<uint32_t>{0}) << "the centre holds no pixel";
    EXPECT_TRUE(plain->recovered.empty());
    auto refined = RefineNeighbors(*f, grid.all(), Zoomer(f, RenderMode::kExact));
    ASSERT_TRUE(refined.ok());
    EXPECT_EQ(refined->recovered, std::vector<uint32_t>{0}) << Name(mode);
    // The centre's neighbours are exactly its ring.
    std::set<uint32_t> around;
    for (const auto& [p, n] : refined->pairs) {
      if (p.first == 1) around.insert(p.second - 1);
    }
    EXPECT_EQ(around, (std::set<uint32_t>{1, 2, 3, 4, 5, 6})) << Name(mode);
  }
}

}  // namespace
}  // namespace gvd
