// Motion planning on rendered frames: corridors, gaps and mazes whose bottleneck clearance is
// known, every path checked against the exact oracle.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "render/kernel/exact2.h"
#include "render/analysis/planning.h"
#include "tests/support/gl_fixture.h"
#include "tests/support/maze.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

// The exact clearance at q: the distance to the nearest site, 0 inside a solid polygon.
double TrueClearance(Vec2 q, const SiteTable& sites) {
  double best = INFINITY;
  for (const Site& s : sites) {
    if (const auto* poly = std::get_if<PolygonSite>(&s.geometry)) {
      if (poly->side != Side::kInside && oracle::Inside(q, poly->vertices)) return 0;
    }
    best = std::min(best, oracle::Distance(q, s.geometry));
  }
  return best;
}

bool Cross(Vec2 a, Vec2 b, Vec2 c, Vec2 d) {
  auto side = [](Vec2 o, Vec2 u, Vec2 v) { return (u.x - o.x) * (v.y - o.y) - (u.y - o.y) * (v.x - o.x); };
  return side(a, b, c) * side(a, b, d) < 0 && side(c, d, a) * side(c, d, b) < 0;
}

// The path's clearance, sampled every 1/20 pixel: at least its proven bound and the radius,
// and no step crosses a site.
void CheckPath(const Plan& plan, const SiteTable& sites, double radius, const Grid& grid,
               const std::string& what) {
  ASSERT_GE(plan.path.size(), 2u) << what;
  EXPECT_GE(plan.min_clearance, radius) << what;
  double worst = INFINITY;
  for (size_t k = 1; k < plan.path.size(); ++k) {
    Vec2 a = plan.path[k - 1], b = plan.path[k];
    int n = std::max(1, int(Distance(a, b) / grid.pixel_size() * 20));
    for (int t = 0; t <= n; ++t) worst = std::min(worst, TrueClearance(a + (double(t) / n) * (b - a), sites));
    for (const Site& s : sites) {
      ForEachSegment(s.geometry, [&](Vec2 c, Vec2 d) {
        EXPECT_FALSE(Cross(a, b, c, d)) << what << ": step " << k << " crosses site " << s.id;
      });
    }
  }
  EXPECT_GE(worst, plan.min_clearance * (1 - 1e-9)) << what << ": the bound is not proven";
}

using PlanGLTest = GlTest;

const Grid kGrid{{0, 0, 1, 1}, 512, 512};

TEST_F(PlanGLTest, AGapInAWallLetsThroughWhatFits) {
  // Sites: a wall across the window at y = 0.5 with a gap of 0.1 between x = 0.45 and 0.55.
  SiteTable sites = {{"left", SegmentSite{{0, 0.5}, {0.45, 0.5}}},
                     {"right", SegmentSite{{0.55, 0.5}, {1, 0.5}}}};
  auto f = Render(kGrid, sites);
  ClearanceField field = MakeClearanceField(*f);
  PlanRequest req{{0.3, 0.2}, {0.7, 0.85}, 0.04};
  auto plan = PlanPath(*f, field, req);
  ASSERT_TRUE(plan.ok()) << plan.status();
  CheckPath(*plan, sites, req.radius, kGrid, "gap");
  // The pixels' staircase is simplified away: a handful of turns, not one per pixel.
  EXPECT_LT(plan->path.size(), 20u) << plan->path.size() << " points";
  // Through the gap, at its middle (its clearance is 0.05 there, the widest there is).
  EXPECT_NEAR(plan->best_clearance, 0.05, 3 * kGrid.pixel_size());
  EXPECT_LE(plan->best_clearance, 0.05);
  bool through = false;
  for (size_t k = 1; k < plan->path.size(); ++k) {
    Vec2 a = plan->path[k - 1], b = plan->path[k];
    if ((a.y - 0.5) * (b.y - 0.5) <= 0 && a.y != b.y) {
      double x = a.x + (0.5 - a.y) / (b.y - a.y) * (b.x - a.x);
      through = std::abs(x - 0.5) < 2 * kGrid.pixel_size();
    }
  }
  EXPECT_TRUE(through);
  // A robot wider than the gap gets NOT_FOUND, with the widest passage in the message.
  req.radius = 0.051;
  auto none = PlanPath(*f, field, req);
  EXPECT_EQ(none.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(none.status().message().find("widest passage"), std::string::npos) << none.status();
}

TEST_F(PlanGLTest, MaxClearanceTakesTheWideGapShortestTheNarrowOne) {
  // Sites: a wall at y = 0.5 with a narrow gap (0.06 wide, at x = 0.2) and a wide one (0.16,
  // at x = 0.75).
  SiteTable sites = {{"a", SegmentSite{{0, 0.5}, {0.17, 0.5}}},
                     {"b", SegmentSite{{0.23, 0.5}, {0.67, 0.5}}},
                     {"c", SegmentSite{{0.83, 0.5}, {1, 0.5}}}};
  auto f = Render(kGrid, sites);
  ClearanceField field = MakeClearanceField(*f);
  auto crossing_x = [](const Plan& p) {
    for (size_t k = 1; k < p.path.size(); ++k) {
      Vec2 a = p.path[k - 1], b = p.path[k];
      if ((a.y - 0.5) * (b.y - 0.5) <= 0 && a.y != b.y) return a.x + (0.5 - a.y) / (b.y - a.y) * (b.x - a.x);
    }
    return -1.0;
  };
  PlanRequest req{{0.2, 0.3}, {0.2, 0.7}, 0.01, PathPreference::kMaxClearance};
  auto wide = PlanPath(*f, field, req);
  ASSERT_TRUE(wide.ok()) << wide.status();
  CheckPath(*wide, sites, req.radius, kGrid, "max clearance");
  EXPECT_NEAR(crossing_x(*wide), 0.75, 0.01);
  EXPECT_NEAR(wide->min_clearance, 0.08, 3 * kGrid.pixel_size());
  req.prefer = PathPreference::kShortest;
  auto narrow = PlanPath(*f, field, req);
  ASSERT_TRUE(narrow.ok()) << narrow.status();
  CheckPath(*narrow, sites, req.radius, kGrid, "shortest");
  EXPECT_NEAR(crossing_x(*narrow), 0.2, 0.01);
  EXPECT_LT(narrow->length, wide->length);
  // Too wide for the narrow gap: the shortest path that fits goes round through the wide one.
  req.radius = 0.035;
  auto fits = PlanPath(*f, field, req);
  ASSERT_TRUE(fits.ok()) << fits.status();
  CheckPath(*fits, sites, req.radius, kGrid, "shortest that fits");
  EXPECT_NEAR(crossing_x(*fits), 0.75, 0.03);
}

TEST_F(PlanGLTest, MazesAreSolvedWithHalfACellOfClearance) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const int k = 8;
    const double half = 0.5 / k;
    SiteTable sites = testing::Maze(k, seed);
    auto f = Render(kGrid, sites);
    ClearanceField field = MakeClearanceField(*f);
    // From the centre of the first cell to the centre of the last.
    PlanRequest req{{half, half}, {1 - half, 1 - half}, half - 3 * kGrid.pixel_size()};
    auto plan = PlanPath(*f, field, req);
    ASSERT_TRUE(plan.ok()) << "maze " << seed << ": " << plan.status();
    CheckPath(*plan, sites, req.radius, kGrid, "maze " + std::to_string(seed));
    EXPECT_LE(plan->best_clearance, half);
    // Wider than a corridor: no way through.
    req.radius = half + kGrid.pixel_size();
    EXPECT_EQ(PlanPath(*f, field, req).status().code(), absl::StatusCode::kNotFound);
  }
}

TEST_F(PlanGLTest, SolidPolygonsAreObstaclesAndStartsInsideThemFail) {
  // Sites: a concave L-shaped block and a triangle between start and goal; the room's walls
  // as a polygon restricted to its inside.
  SiteTable sites = {
      {"L", PolygonSite{{{0.3, 0.2}, {0.6, 0.2}, {0.6, 0.35}, {0.45, 0.35}, {0.45, 0.8}, {0.3, 0.8}}}},
      {"tri", PolygonSite{{{0.65, 0.5}, {0.9, 0.55}, {0.7, 0.75}}, Side::kOutside}},
      {"room", PolygonSite{{{0.05, 0.05}, {0.95, 0.05}, {0.95, 0.95}, {0.05, 0.95}}, Side::kInside}}};
  auto f = Render(kGrid, sites);
  ClearanceField field = MakeClearanceField(*f);
  PlanRequest req{{0.15, 0.5}, {0.8, 0.3}, 0.03};
  auto plan = PlanPath(*f, field, req);
  ASSERT_TRUE(plan.ok()) << plan.status();
  CheckPath(*plan, sites, req.radius, kGrid, "polygons");
  for (Vec2 p : plan->path) {
    EXPECT_FALSE(oracle::Inside(p, std::get<PolygonSite>(sites[0].geometry).vertices));
    EXPECT_TRUE(oracle::Inside(p, std::get<PolygonSite>(sites[2].geometry).vertices));
  }
  req.start = {0.35, 0.5};  // inside the L
  auto inside = PlanPath(*f, field, req);
  EXPECT_EQ(inside.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(inside.status().message().find("\"L\""), std::string::npos) << inside.status();
  req.start = {1.5, 0.5};
  EXPECT_EQ(PlanPath(*f, field, req).status().code(), absl::StatusCode::kInvalidArgument);
  req.start = {0.15, 0.5};
  req.radius = -1;
  EXPECT_EQ(PlanPath(*f, field, req).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace gvd
