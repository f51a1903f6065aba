// Boundaries, neighbours, hidden sites and triangles from id images, against images labelled
// by the exact oracle (no GL).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "render/analysis/analysis.h"
#include "render/kernel/exact2.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

// An image labelled by the oracle: each pixel centre gets its exact nearest site (slot + 1).
IdImage Oracle(const Grid& grid, const SiteTable& sites, Diagram diagram = Diagram::kNearest) {
  IdImage image{grid, std::vector<uint32_t>(grid.pixel_count())};
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      oracle::Best n = oracle::BestSite(grid.Center(i, j), sites, diagram);
      image.ids[size_t{j} * grid.width + i] = n.found ? static_cast<uint32_t>(n.index) + 1 : 0;
    }
  }
  return image;
}

IdImage Labels(uint32_t w, uint32_t h, std::function<uint32_t(uint32_t, uint32_t)> f) {
  IdImage image{Grid{{0, 0, double(w), double(h)}, w, h}, std::vector<uint32_t>(size_t{w} * h)};
  for (uint32_t j = 0; j < h; ++j) {
    for (uint32_t i = 0; i < w; ++i) image.ids[size_t{j} * w + i] = f(i, j);
  }
  return image;
}

bool SameMarks(const BoundaryEdges& a, const BoundaryEdges& b) {
  return a.horizontal == b.horizontal && a.vertical == b.vertical;
}

TEST(BoundaryEdges, FullScanMarksEveryDifferingPair) {
  // Ids: 1 left of column 5, 2 right of it, and a 3x3 island of 3 away from the border.
  IdImage image = Labels(16, 12, [](uint32_t i, uint32_t j) {
    if (i >= 10 && i <= 12 && j >= 4 && j <= 6) return 3u;
    return i < 5 ? 1u : 2u;
  });
  BoundaryEdges full = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
  // 12 pairs across the straight boundary; 12 around the island.
  EXPECT_EQ(full.count, 12u + 12u);
  BoundaryEdges walk = FindBoundaryEdges(image, BoundaryMethod::kContinuation);
  // The island's boundary touches no border: the continuation finds only the straight one.
  EXPECT_EQ(walk.count, 12u);
  for (uint32_t j = 0; j < 12; ++j) EXPECT_TRUE(walk.h(4, j));
  EXPECT_LT(walk.cells_visited, full.cells_visited);
}

TEST(BoundaryEdges, ContinuationAgreesOnPointSites) {
  // The diagram of points is connected and unbounded: every boundary reaches the border.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int round = 0; round < 20; ++round) {
    SiteTable sites;
    int n = 2 + round * 3;
    for (int s = 0; s < n; ++s) sites.push_back({std::to_string(s), PointSite{{u(rng), u(rng)}}});
    IdImage image = Oracle({{0, 0, 1, 1}, 160, 160}, sites);
    BoundaryEdges full = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
    BoundaryEdges walk = FindBoundaryEdges(image, BoundaryMethod::kContinuation);
    EXPECT_TRUE(SameMarks(full, walk)) << n << " points: " << full.count << " vs " << walk.count;
  }
}

TEST(TraceBoundaries, PointsOnTheBisectorsAndJunctions) {
  // Sites: three points; their three bisectors meet at the circumcentre.
  SiteTable sites = {{"a", PointSite{{0.2, 0.3}}},
                     {"b", PointSite{{0.8, 0.25}}},
                     {"c", PointSite{{0.45, 0.85}}}};
  const Grid grid{{0, 0, 1, 1}, 101, 97};
  IdImage image = Oracle(grid, sites);
  BoundaryEdges edges = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
  auto lines = TraceBoundaries(image, edges, SlotTable(sites), Diagram::kNearest);
  ASSERT_EQ(lines.size(), 3u);
  std::set<std::pair<uint32_t, uint32_t>> pairs;
  for (const auto& l : lines) {
    pairs.insert({l.a, l.b});
    EXPECT_FALSE(l.closed);
    ASSERT_GE(l.points.size(), 10u);
    Vec2 pa = std::get<PointSite>(sites[l.a - 1].geometry).p;
    Vec2 pb = std::get<PointSite>(sites[l.b - 1].geometry).p;
    // Every crossing is on the bisector (the junction, the first point, is a mean).
    for (size_t k = 1; k < l.points.size(); ++k) {
      EXPECT_NEAR(Distance(l.points[k], pa), Distance(l.points[k], pb), 1e-12);
    }
    // One end at the junction, near the circumcentre; the other on the window's border.
    Vec2 end = l.points.back();
    EXPECT_TRUE(end.x < 0.01 || end.x > 0.99 || end.y < 0.01 || end.y > 0.99)
        << end.x << "," << end.y;
  }
  EXPECT_EQ(pairs, (std::set<std::pair<uint32_t, uint32_t>>{{1, 2}, {1, 3}, {2, 3}}));
  // The circumcentre of a, b, c.
  Vec2 a{0.2, 0.3}, b{0.8, 0.25}, c{0.45, 0.85};
  double d = 2 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
  Vec2 o{((a.x * a.x + a.y * a.y) * (b.y - c.y) + (b.x * b.x + b.y * b.y) * (c.y - a.y) +
          (c.x * c.x + c.y * c.y) * (a.y - b.y)) / d,
         ((a.x * a.x + a.y * a.y) * (c.x - b.x) + (b.x * b.x + b.y * b.y) * (a.x - c.x) +
          (c.x * c.x + c.y * c.y) * (b.x - a.x)) / d};
  for (const auto& l : lines) EXPECT_LT(Distance(l.points.front(), o), grid.pixel_diagonal());
}

TEST(TraceBoundaries, AnIslandIsAClosedPolyline) {
  // Sites: a point inside a C-shaped polyline (a concave site) whose cup almost closes; and
  // one point outside. The inner point's region is enclosed by the polyline's.
  SiteTable sites = {
      {"cup", PolylineSite{{{0.6, 0.3}, {0.3, 0.3}, {0.3, 0.7}, {0.7, 0.7}, {0.7, 0.35}}}},
      {"in", PointSite{{0.5, 0.5}}},
      {"out", PointSite{{0.9, 0.1}}}};
  const Grid grid{{0, 0, 1, 1}, 128, 128};
  IdImage image = Oracle(grid, sites);
  BoundaryEdges full = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
  BoundaryEdges walk = FindBoundaryEdges(image, BoundaryMethod::kContinuation);
  ASSERT_GT(full.count, walk.count);
  // What the walk found, the full scan found too.
  for (size_t k = 0; k < walk.horizontal.size(); ++k) EXPECT_LE(walk.horizontal[k], full.horizontal[k]);
  for (size_t k = 0; k < walk.vertical.size(); ++k) EXPECT_LE(walk.vertical[k], full.vertical[k]);
  auto lines = TraceBoundaries(image, full, SlotTable(sites), Diagram::kNearest);
  int island = 0;
  for (const auto& l : lines) {
    if (l.a == 1 && l.b == 2) {
      ++island;
      EXPECT_TRUE(l.closed);
      for (Vec2 p : l.points) {  // on the bisector of the cup and the point, by bisection
        EXPECT_NEAR(oracle::Distance(p, sites[0].geometry), oracle::Distance(p, sites[1].geometry), 1e-9);
      }
    }
  }
  EXPECT_EQ(island, 1);
  auto walked = TraceBoundaries(image, walk, SlotTable(sites), Diagram::kNearest);
  for (const auto& l : walked) EXPECT_FALSE(l.a == 1 && l.b == 2) << "the walk reached the island";
}

TEST(NeighborPairs, CountsPixelPairsBetweenSites) {
  // 1 | 2 split at column 3 over 5 rows, with 0 (no site) in the top row of 2's side.
  IdImage image = Labels(6, 5, [](uint32_t i, uint32_t j) {
    if (i >= 3 && j == 4) return 0u;
    return i < 3 ? 1u : 2u;
  });
  BoundaryEdges e = FindBoundaryEdges(image, BoundaryMethod::kFullScan);
  NeighborCounts n = NeighborPairs(image, e);
  ASSERT_EQ(n.size(), 1u);
  EXPECT_EQ((n.at({1, 2})), 4u);  // the top row's pair is 1 | empty
}

TEST(HiddenSites, SitesInTheWindowWithNoPixel) {
  // Sites: two points whose regions cover everything, a point squeezed between pixel centres
  // by four close neighbours, a segment crossing the window, and a point outside it.
  SiteTable sites = {{"a", PointSite{{0.25, 0.5}}},
                     {"b", PointSite{{0.75, 0.5}}},
                     {"tiny", PointSite{{0.5, 0.5}}},
                     {"n", PointSite{{0.5, 0.5 + 1e-4}}},
                     {"s", PointSite{{0.5, 0.5 - 1e-4}}},
                     {"e", PointSite{{0.5 + 1e-4, 0.5}}},
                     {"w", PointSite{{0.5 - 1e-4, 0.5}}},
                     {"outside", PointSite{{2, 2}}}};
  IdImage image = Oracle({{0, 0, 1, 1}, 20, 20}, sites);
  std::vector<uint32_t> hidden = HiddenSites(image, SlotTable(sites));
  EXPECT_NE(std::find(hidden.begin(), hidden.end(), 2u), hidden.end()) << "tiny";
  EXPECT_EQ(std::find(hidden.begin(), hidden.end(), 7u), hidden.end()) << "outside";
  EXPECT_EQ(std::find(hidden.begin(), hidden.end(), 0u), hidden.end()) << "a";
}

TEST(GeometryMeetsBox, SegmentsPolygonsAndPoints) {
  const Window box{0, 0, 1, 1};
  EXPECT_TRUE(GeometryMeetsBox(PointSite{{0.5, 1}}, box));
  EXPECT_FALSE(GeometryMeetsBox(PointSite{{0.5, 1.001}}, box));
  EXPECT_TRUE(GeometryMeetsBox(SegmentSite{{-1, 0.5}, {2, 0.5}}, box));  // crosses, no end inside
  EXPECT_TRUE(GeometryMeetsBox(SegmentSite{{-1, 1.5}, {1.4, -0.1}}, box));
  EXPECT_FALSE(GeometryMeetsBox(SegmentSite{{1.2, -1}, {2, 3}}, box));
  EXPECT_TRUE(GeometryMeetsBox(SegmentSite{{1.5, 0.5}, {0.5, 1.5}}, box));  // grazes the corner
  EXPECT_FALSE(GeometryMeetsBox(SegmentSite{{1.6, 0.5}, {0.5, 1.6}}, box));
  // A polygon around the box: its edges miss it.
  EXPECT_FALSE(GeometryMeetsBox(PolygonSite{{{-1, -1}, {2, -1}, {2, 2}, {-1, 2}}}, box));
}

TEST(TrianglesFromEdges, ASquareWithADiagonal) {
  std::vector<Vec2> p = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  auto t = TrianglesFromEdges(p, {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 2}});
  ASSERT_EQ(t.size(), 2u);
  std::set<std::array<uint32_t, 3>> got(t.begin(), t.end());
  EXPECT_EQ(got, (std::set<std::array<uint32_t, 3>>{{0, 1, 2}, {0, 2, 3}}));
  // Without the diagonal there is no triangle; duplicates and loops are ignored.
  EXPECT_TRUE(TrianglesFromEdges(p, {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {1, 0}, {2, 2}}).empty());
}

}  // namespace
}  // namespace gvd
