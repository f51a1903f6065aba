#include "geometry/exact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "oracle.h"
#include "pixel_oracle.h"

namespace gvd {
namespace {

// The production distance set against the tests' oracle, on random geometry of every kind
// and on adversarial points: vertices, edge midpoints, points just off them, far away.
TEST(ExactVsOracle, DistancesFeaturesSidesAndValues) {
  Generator gen(404);
  int checked = 0;
  for (int k = 0; k < 600; ++k) {
    Site site{"s", gen.Kind(k % 7)};
    if (k % 3 == 1) site.additive = gen.U(0, 0.5);
    if (k % 3 == 2) site.multiplicative = gen.U(0.5, 4);
    if (k % 4 == 3) site.max_distance = gen.U(0.05, 0.5);
    std::vector<Vec2> queries;
    for (int i = 0; i < 20; ++i) queries.push_back(gen.P());
    queries.push_back({1e6, -3e5});
    for (auto [a, b] : oracle::Segments(site.geometry)) {
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
      ++checked;
    }
  }
  EXPECT_GT(checked, 10000);
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
