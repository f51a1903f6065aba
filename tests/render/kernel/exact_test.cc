#include "render/kernel/exact2.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "render/kernel/segment_tree.h"
#include "tests/support/oracle.h"
#include "tests/support/pixel_oracle.h"

namespace gvd {
namespace {

// The production distance set against the tests' oracle, on random geometry of every kind
// and on adversarial points: vertices, edge midpoints, points just off them, far away.
TEST(ExactVsOracle, DistancesFeaturesSidesAndValues) {
  Generator gen(404);
  int checked = 0;
  for (int k = 0; k < 600; ++k) {
    Site site{"s", gen.Kind(k % Generator::kKinds)};
    if (k % 3 == 1) site.additive = gen.U(0, 0.5);
    if (k % 3 == 2) site.multiplicative = gen.U(0.5, 4);
    if (k % 4 == 3) site.max_distance = gen.U(0.05, 0.5);
    std::vector<Vec2> queries;
    for (int i = 0; i < 20; ++i) queries.push_back(gen.P());
    queries.push_back({1e6, -3e5});
    // (A path's every seventh segment: it has hundreds.)
    const size_t step = std::holds_alternative<PathSite>(site.geometry) ? 7 : 1;
    const auto segments = oracle::Segments(site.geometry);
    for (size_t i = 0; i < segments.size(); i += step) {
      const auto [a, b] = segments[i];
      queries.push_back(a);
      queries.push_back(0.5 * (a + b) + Vec2{1e-3, -2e-3});
      queries.push_back(a + Vec2{1e-9, 1e-9});
    }
    for (Vec2 q : queries) {
      SCOPED_TRACE(::testing::Message() << "site " << k << " q (" << q.x << ", " << q.y << ")");
      const double d = oracle::Distance(q, site.geometry);
      ASSERT_NEAR(ExactDistance(q, site.geometry), d, oracle::Tolerance(q, d));
      FeatureHit f = NearestFeature(q, site.geometry);
      ASSERT_NEAR(f.distance, d, oracle::Tolerance(q, d));
      ASSERT_TRUE(oracle::IsNearestFeature(q, site.geometry, f.kind, f.index))
          << "feature " << int(f.kind) << " " << f.index;
      ASSERT_TRUE(oracle::IsClosestPoint(q, site.geometry, f.kind, f.index, f.closest))
          << "closest (" << f.closest.x << ", " << f.closest.y << ")";
      const double v = oracle::Value(q, site);
      const double got = SiteValue(q, site);
      // Within rounding of max_distance or of a polygon's boundary, either answer is right.
      const bool edge_case = std::abs(d - site.max_distance) < 1e-12 || d < 1e-12;
      if (!edge_case) {
        ASSERT_EQ(std::isfinite(got), std::isfinite(v));
        if (std::isfinite(v)) {
          ASSERT_NEAR(got, v, oracle::Tolerance(q, v, site.multiplicative));
        }
      }
      if (auto* poly = std::get_if<PolygonSite>(&site.geometry); poly && d > 1e-12) {
        ASSERT_EQ(InsidePolygon(q, poly->vertices), oracle::Inside(q, poly->vertices));
      }
      if (auto* path = std::get_if<PathSite>(&site.geometry);
          path && oracle::DrawnDistance(q, site.geometry) > 1e-12) {
        ASSERT_EQ(InsidePath(q, *path), oracle::InsidePath(q, *path));
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 10000);
}

// Long sites, random and adversarial, for the segment tree: a random walk, a scribble of
// segments crossing one another, a regular polygon (every edge ties at its centre), repeated
// and collinear points, a fine Bezier, and the same far from the origin.
std::vector<Site> LongSites(Generator& gen) {
  std::vector<Site> out;
  auto add = [&](Geometry g) {
    Site s{"long", std::move(g)};
    IndexSegments(s);
    out.push_back(std::move(s));
  };
  for (int n : {32, 33, 100, 1000}) {
    PolylineSite walk{{gen.P()}};
    for (int k = 1; k <= n; ++k) walk.points.push_back(gen.Near(walk.points.back(), 0.05));
    add(walk);
    PolylineSite scribble;
    for (int k = 0; k <= n; ++k) scribble.points.push_back(gen.P());
    add(scribble);
    PolygonSite regular;
    for (int k = 0; k < n; ++k) {
      regular.vertices.push_back({0.5 + 0.3 * std::cos(2 * M_PI * k / n),
                                  0.5 + 0.3 * std::sin(2 * M_PI * k / n)});
    }
    add(regular);
  }
  PolylineSite repeats;  // repeated points, a doubled-back collinear run
  for (int k = 0; k < 40; ++k) repeats.points.push_back({0.1 + 0.01 * (k % 10), 0.4});
  for (int k = 0; k < 40; ++k) repeats.points.push_back({0.3, 0.3});
  add(repeats);
  add(MakeBezier({{0, 0}, {1, 2}, {2, -1}, {3, 1}}, 1e-6));
  PolylineSite far;
  for (int k = 0; k <= 200; ++k) far.points.push_back({1e7 + gen.U(0, 1), -1e7 + gen.U(0, 1)});
  add(far);
  return out;
}

// The segment tree against a loop over the segments (it must give the same values, ties to
// the first segment) and against the oracle, on long sites.
TEST(SegmentTree, SameAnswersAsTheLoopAndTheOracle) {
  Generator gen(77);
  int checked = 0;
  for (const Site& site : LongSites(gen)) {
    ASSERT_NE(site.segment_tree, nullptr);
    const auto segments = oracle::Segments(site.geometry);
    ASSERT_EQ(site.segment_tree->size(), segments.size());
    const Window box = BoundingBox(site.geometry);
    const Vec2 mid{(box.min_x + box.max_x) / 2, (box.min_y + box.max_y) / 2};
    std::vector<Vec2> queries{mid, {mid.x + 1e3, mid.y}, {-1e6, 3e5}};
    for (int i = 0; i < 60; ++i) {
      queries.push_back({gen.U(box.min_x - 0.2, box.max_x + 0.2),
                         gen.U(box.min_y - 0.2, box.max_y + 0.2)});
    }
    for (size_t k = 0; k < segments.size(); k += 7) {
      queries.push_back(segments[k].first);
      queries.push_back(0.5 * (segments[k].first + segments[k].second));
    }
    for (Vec2 q : queries) {
      SCOPED_TRACE(::testing::Message() << segments.size() << " segments, q (" << q.x << ", "
                                        << q.y << ")");
      const double d = oracle::Distance(q, site.geometry);
      const double got = ExactDistance(q, site);
      ASSERT_NEAR(got, d, oracle::Tolerance(q, d));
      ASSERT_EQ(got, ExactDistance(q, site.geometry));
      const FeatureHit f = NearestFeature(q, site), loop = NearestFeature(q, site.geometry);
      ASSERT_EQ(f.distance, loop.distance);
      ASSERT_EQ(f.kind, loop.kind);
      ASSERT_EQ(f.index, loop.index);
      ASSERT_EQ(f.closest, loop.closest);
      ASSERT_TRUE(oracle::IsNearestFeature(q, site.geometry, f.kind, f.index));
      ASSERT_TRUE(oracle::IsClosestPoint(q, site.geometry, f.kind, f.index, f.closest));
      // Within: every segment within r of q, for r at the distance and beyond it.
      for (double r : {d, 1.5 * d + 0.01}) {
        std::vector<bool> seen(segments.size(), false);
        site.segment_tree->Within(q, r, [&](uint32_t index, Vec2 a, Vec2 b) {
          ASSERT_LT(index, segments.size());
          ASSERT_EQ(a, segments[index].first);
          ASSERT_EQ(b, segments[index].second);
          seen[index] = true;
        });
        for (size_t k = 0; k < segments.size(); ++k) {
          if (oracle::ToSegment(q, segments[k].first, segments[k].second) <= r) {
            ASSERT_TRUE(seen[k]) << "segment " << k << " within " << r;
          }
        }
      }
      // Farthest over a box around q: min over segments of max over its corners.
      const Window around{q.x - 0.03, q.y - 0.02, q.x + 0.05, q.y + 0.01};
      oracle::Real want = INFINITY;
      for (auto [a, b] : segments) {
        oracle::Real m = 0;
        for (Vec2 c : {Vec2{around.min_x, around.min_y}, Vec2{around.max_x, around.min_y},
                       Vec2{around.min_x, around.max_y}, Vec2{around.max_x, around.max_y}}) {
          m = std::max(m, oracle::ToSegment(c, a, b));
        }
        want = std::min(want, m);
      }
      // A Bezier's segments are its flattening, within its tolerance of the curve.
      if (const auto* b = std::get_if<BezierSite>(&site.geometry)) want += b->tolerance;
      const double far = FarthestDistance(around, site);
      ASSERT_NEAR(far, static_cast<double>(want), oracle::Tolerance(q, far));
      ASSERT_EQ(far, FarthestDistance(around, site.geometry));
      ++checked;
    }
  }
  EXPECT_GT(checked, 1500);
}

// Ties: at the centre of a regular polygon every edge is at the same distance in exact
// arithmetic; the answer is the first of those at the least computed distance, as the loop's.
TEST(SegmentTree, TiesGoToTheFirstSegment) {
  for (int n : {32, 64, 256}) {
    PolygonSite square;
    for (int k = 0; k < n; ++k) {
      const int side = 4 * k / n, step = 4 * k % n;
      const double s = double(step) / n * 2 - 1;
      square.vertices.push_back(side == 0   ? Vec2{s, -1}
                                : side == 1 ? Vec2{1, s}
                                : side == 2 ? Vec2{-s, 1}
                                            : Vec2{-1, -s});
    }
    Site site{"square", square};
    IndexSegments(site);
    ASSERT_NE(site.segment_tree, nullptr);
    for (Vec2 q : {Vec2{0, 0}, Vec2{0.5, 0}, Vec2{0, -0.5}}) {
      const FeatureHit f = NearestFeature(q, site), loop = NearestFeature(q, site.geometry);
      EXPECT_EQ(f.kind, loop.kind) << n;
      EXPECT_EQ(f.index, loop.index) << n;
      EXPECT_EQ(f.distance, loop.distance);
    }
  }
}

TEST(SegmentTree, OnlyLongSitesGetOne) {
  Site point{"p", PointSite{{0, 0}}}, segment{"s", SegmentSite{{0, 0}, {1, 1}}};
  PolylineSite shorter, enough;
  for (size_t k = 0; k < SegmentTree::kMinSegments; ++k) shorter.points.push_back({double(k), 0});
  enough = shorter;
  enough.points.push_back({0, 1});
  Site a{"a", shorter}, b{"b", enough};
  for (Site* s : {&point, &segment, &a, &b}) IndexSegments(*s);
  EXPECT_EQ(point.segment_tree, nullptr);
  EXPECT_EQ(segment.segment_tree, nullptr);
  EXPECT_EQ(a.segment_tree, nullptr);  // kMinSegments - 1 segments
  ASSERT_NE(b.segment_tree, nullptr);
  EXPECT_EQ(b.segment_tree->size(), SegmentTree::kMinSegments);
  // The slot table indexes the sites that enter it.
  SlotTable table(SiteTable{a, b});
  EXPECT_EQ(table.get(0)->segment_tree, nullptr);
  EXPECT_NE(table.get(1)->segment_tree, nullptr);
}

TEST(ExactDistance, Point) {
  // Sites: (0, 0). Queries at a 3-4-5 triangle and at the site itself.
  EXPECT_DOUBLE_EQ(ExactDistance({3, 4}, PointSite{{0, 0}}), 5);
  EXPECT_DOUBLE_EQ(ExactDistance({0, 0}, PointSite{{0, 0}}), 0);
  // No overflow for huge coordinates.
  EXPECT_DOUBLE_EQ(ExactDistance({3e300, 4e300}, PointSite{{0, 0}}), 5e300);
}

TEST(FarthestDistance, InsideAndOutside) {
  Window w{0, 0, 4, 3};
  EXPECT_DOUBLE_EQ(FarthestDistance(w, PointSite{{0, 0}}), 5);
  EXPECT_DOUBLE_EQ(FarthestDistance(w, PointSite{{2, 1.5}}), 2.5);
  EXPECT_DOUBLE_EQ(FarthestDistance(w, PointSite{{-4, 0}}), std::hypot(8, 3));
}

}  // namespace
}  // namespace gvd
