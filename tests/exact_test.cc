#include "geometry/exact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace gvd {
namespace {

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

TEST(NearestBruteForce, TiesGoToLowestIndex) {
  // Sites: (1, 0), (-1, 0), (1, 0) again. The query (0, 0) is equidistant from all three.
  std::vector<Site> sites = {{"a", PointSite{{1, 0}}}, {"b", PointSite{{-1, 0}}},
                             {"c", PointSite{{1, 0}}}};
  auto n = NearestBruteForce({0, 0}, sites);
  EXPECT_EQ(n.index, 0u);
  EXPECT_DOUBLE_EQ(n.distance, 1);
  n = NearestBruteForce({-0.5, 0}, sites);
  EXPECT_EQ(n.index, 1u);
  EXPECT_DOUBLE_EQ(n.distance, 0.5);
}

}  // namespace
}  // namespace gvd
