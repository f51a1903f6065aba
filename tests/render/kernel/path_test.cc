// Path sites (render/kernel/path2.h) against the tests' own oracle: distances to the true
// pieces (tests/support/oracle.h: long double, CurveDistance's own root finding), and a
// winding number of its own, written apart from the code it judges: each curve's crossings
// of q's level found by bisection between the signs of y(t) - q.y at 2,048 steps, counted
// where x(t) > q.x. On random paths of lines, quadratics and cubics, open and closed; on the
// outlines of real glyphs (one path per glyph, holes included), TrueType's quadratics and
// CFF's cubics read by FreeType; and on paths whose features and insides are worked out by
// hand.
#include "render/kernel/path2.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "tests/support/glyphs.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

using oracle::Real;

std::vector<Vec2> Control(const PathPiece& p) {
  return {p.control.begin(), p.control.begin() + p.degree + 1};
}

// The oracle's distance from q to one piece.
Real PieceDistance(Vec2 q, const PathPiece& p) {
  return p.degree == 1 ? oracle::ToSegment(q, p.control[0], p.control[1])
                       : oracle::CurveDistance(q, Control(p));
}

Real OracleDistance(Vec2 q, const PathSite& path) {
  Real best = INFINITY;
  for (const PathPiece& p : path.pieces) best = std::min(best, PieceDistance(q, p));
  return best;
}

// The oracle's winding number of the closed pieces around q.
int OracleWinding(Vec2 q, const PathSite& path) {
  int winding = 0;
  for (const PathPiece& p : path.pieces) {
    if (!p.closed) continue;
    const std::vector<Vec2> c = Control(p);
    auto at = [&](Real t, Real* x, Real* y) {
      if (p.degree == 1) {
        *x = c[0].x + t * (Real(c[1].x) - c[0].x);
        *y = c[0].y + t * (Real(c[1].y) - c[0].y);
      } else {
        oracle::CurveAt(c, t, x, y);
      }
    };
    constexpr int kSteps = 2048;
    Real x0, y0;
    at(0, &x0, &y0);
    for (int k = 1; k <= kSteps; ++k) {
      Real x1, y1;
      at(Real(k) / kSteps, &x1, &y1);
      if ((y0 > q.y) != (y1 > q.y)) {
        Real lo = Real(k - 1) / kSteps, hi = Real(k) / kSteps;
        const bool rising = y1 > y0;
        for (int i = 0; i < 80; ++i) {
          const Real mid = (lo + hi) / 2;
          Real x, y;
          at(mid, &x, &y);
          ((y > q.y) == rising ? hi : lo) = mid;
        }
        Real x, y;
        at((lo + hi) / 2, &x, &y);
        if (x > q.x) winding += rising ? 1 : -1;
      }
      x0 = x1;
      y0 = y1;
    }
  }
  return winding;
}

// Checks the path's distance, feature and winding at q against the oracle; the winding only
// where q is farther than the path's tolerance from it (path2.h: nearer, the drawn outline
// may put it on the other side) and than `margin` (the oracle's steps could miss a crossing
// there).
void Check(Vec2 q, const PathSite& path, double margin, const std::string& what) {
  const FeatureHit hit = PathNearestFeature(q, path);
  const Real truth = OracleDistance(q, path);
  double extent = 0;
  for (const PathPiece& p : path.pieces) {
    for (int i = 0; i <= p.degree; ++i) extent = std::max({extent, std::abs(p.control[i].x), std::abs(p.control[i].y)});
  }
  const double bound = 2 * BezierDistanceError(double(truth), extent) + 1e-12 * double(truth);
  ASSERT_NEAR(hit.distance, double(truth), bound) << what << " q " << q.x << "," << q.y;
  ASSERT_EQ(PathDistance(q, path), hit.distance) << what;
  // The feature named holds the closest point given, at the distance given.
  ASSERT_NEAR(Distance(q, hit.closest), hit.distance, 1e-12 * (1 + hit.distance)) << what;
  if (hit.kind == FeatureKind::kVertex) {
    // Joint j as path2.h numbers them, from the subpaths as given: each piece's start, and an
    // open subpath's end.
    std::vector<Vec2> joints;
    for (const Subpath& sub : path.subpaths) {
      size_t at = 0;
      for (uint8_t d : sub.degrees) {
        joints.push_back(sub.points[at]);
        at += d;
      }
      if (!sub.closed) joints.push_back(sub.points[at]);
    }
    ASSERT_LT(hit.index, joints.size()) << what;
    ASSERT_EQ(joints[hit.index], hit.closest) << what << ": vertex " << hit.index;
  } else {
    ASSERT_LT(hit.index, path.pieces.size()) << what;
    const PathPiece& p = path.pieces[hit.index];
    ASSERT_EQ(hit.kind, p.degree == 1 ? FeatureKind::kEdge : FeatureKind::kCurve) << what;
    ASSERT_LE(double(PieceDistance(hit.closest, p)), 1e-9 * (1 + extent)) << what;
  }
  if (truth > margin && truth > path.tolerance) {
    const int winding = OracleWinding(q, path);
    ASSERT_EQ(PathWinding(q, path), winding) << what << " q " << q.x << "," << q.y;
    ASSERT_EQ(InsidePath(q, path),
              path.fill == FillRule::kEvenOdd ? (winding & 1) != 0 : winding != 0) << what;
  }
}

Subpath RandomSubpath(std::mt19937_64& rng, bool closed) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> degree(1, 3), count(1, 5);
  Subpath s;
  s.closed = closed;
  s.points.push_back({u(rng), u(rng)});
  for (int k = count(rng); k > 0; --k) {
    const int d = degree(rng);
    s.degrees.push_back(static_cast<uint8_t>(d));
    for (int i = 0; i < d; ++i) s.points.push_back({u(rng), u(rng)});
  }
  return s;
}

TEST(PathSite, RandomPathsAgreeWithTheOracle) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int n = 0; n < 150; ++n) {
    std::vector<Subpath> subpaths;
    for (int k = 1 + n % 3; k > 0; --k) subpaths.push_back(RandomSubpath(rng, (n + k) % 4 != 0));
    const PathSite path = MakePath(subpaths, n % 2 ? FillRule::kEvenOdd : FillRule::kNonZero,
                                   Side::kBoth, 0);
    for (int i = 0; i < 40; ++i) Check({u(rng), u(rng)}, path, 1e-6, "path " + std::to_string(n));
  }
}

TEST(PathSite, GlyphOutlinesAgreeWithTheOracle) {
  std::mt19937_64 rng(17);
  for (const char* font : {testing::kTrueTypeFont, testing::kCffFont}) {
    const auto glyphs = testing::GlyphOutlines(font, "gvd&Q@8oB");
    for (size_t g = 0; g < glyphs.size(); ++g) {
      const PathSite path = MakePath(glyphs[g], FillRule::kNonZero, Side::kOutside, 0);
      const Window box = PathBox(path);
      std::uniform_real_distribution<double> x(box.min_x - 0.1, box.max_x + 0.1),
          y(box.min_y - 0.1, box.max_y + 0.1);
      int inside = 0;
      for (int i = 0; i < 100; ++i) {
        const Vec2 q{x(rng), y(rng)};
        Check(q, path, 1e-6, std::string(font) + " glyph " + std::to_string(g));
        inside += InsidePath(q, path);
      }
      EXPECT_GT(inside, 0) << font << " glyph " << g;  // every glyph has ink
    }
  }
}

// An open subpath of two pieces (a line, then a quadratic) and a closed square of three
// given pieces and the line that closes it: the features as path2.h numbers them.
TEST(PathSite, FeaturesAreNumberedAcrossSubpaths) {
  Subpath open{{{0, 0}, {1, 0}, {2, 1}, {3, 0}}, {1, 2}, false};
  Subpath square{{{10, 0}, {11, 0}, {11, 1}, {10, 1}}, {1, 1, 1}, true};
  const PathSite path = MakePath({open, square}, FillRule::kNonZero, Side::kBoth, 0);
  ASSERT_EQ(path.pieces.size(), 6u);  // 2 + 3 + the closing line
  EXPECT_EQ(path.joints, 7u);          // 3 + 4
  const std::pair<uint32_t, uint32_t> joints[6] = {{0, 1}, {1, 2}, {3, 4}, {4, 5}, {5, 6}, {6, 3}};
  for (size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(std::pair(path.pieces[k].first_joint, path.pieces[k].last_joint), joints[k]) << k;
  }
  auto feature = [&](Vec2 q) {
    const FeatureHit h = PathNearestFeature(q, path);
    return std::pair{h.kind, h.index};
  };
  EXPECT_EQ(feature({-1, -1}), std::pair(FeatureKind::kVertex, 0u));  // the open start
  EXPECT_EQ(feature({0.5, -1}), std::pair(FeatureKind::kEdge, 0u));
  EXPECT_EQ(feature({2, 2}), std::pair(FeatureKind::kCurve, 1u));     // the quadratic's apex is (2, 0.5)
  EXPECT_EQ(feature({4, -1}), std::pair(FeatureKind::kVertex, 2u));   // the open end
  EXPECT_EQ(feature({9, -1}), std::pair(FeatureKind::kVertex, 3u));   // the square's start
  EXPECT_EQ(feature({12, 2}), std::pair(FeatureKind::kVertex, 5u));   // (11, 1)
  EXPECT_EQ(feature({9, 0.5}), std::pair(FeatureKind::kEdge, 5u));    // the closing line
  EXPECT_EQ(feature({10.5, 2}), std::pair(FeatureKind::kEdge, 4u));
  EXPECT_NEAR(PathDistance({2, 2}, path), 1.5, 1e-15);
}

// Two nested squares turning the same way: inside the inner one the winding is 2, inside
// by the nonzero rule and a hole by even-odd; the inner one reversed makes a hole by both.
TEST(PathSite, FillRulesOfNestedContours) {
  Subpath outer{{{0, 0}, {4, 0}, {4, 4}, {0, 4}}, {1, 1, 1}, true};
  Subpath inner{{{1, 1}, {3, 1}, {3, 3}, {1, 3}}, {1, 1, 1}, true};
  Subpath reversed{{{1, 1}, {1, 3}, {3, 3}, {3, 1}}, {1, 1, 1}, true};
  const PathSite nonzero = MakePath({outer, inner}, FillRule::kNonZero, Side::kBoth, 0);
  const PathSite evenodd = MakePath({outer, inner}, FillRule::kEvenOdd, Side::kBoth, 0);
  const PathSite holed = MakePath({outer, reversed}, FillRule::kNonZero, Side::kBoth, 0);
  EXPECT_EQ(PathWinding({2, 2}, nonzero), 2);
  EXPECT_EQ(PathWinding({0.5, 2}, nonzero), 1);
  EXPECT_EQ(PathWinding({5, 2}, nonzero), 0);
  EXPECT_TRUE(InsidePath({2, 2}, nonzero));
  EXPECT_FALSE(InsidePath({2, 2}, evenodd));
  EXPECT_TRUE(InsidePath({0.5, 2}, evenodd));
  EXPECT_FALSE(InsidePath({2, 2}, holed));
  EXPECT_TRUE(InsidePath({0.5, 0.5}, holed));
  // A circle of four cubics (the usual 0.5523 handles) bounds what is within it.
  const double h = 0.5522847498;
  Subpath circle{{{1, 0}, {1, h}, {h, 1}, {0, 1}, {-h, 1}, {-1, h}, {-1, 0}, {-1, -h}, {-h, -1},
                  {0, -1}, {h, -1}, {1, -h}, {1, 0}},
                 {3, 3, 3, 3}, true};
  const PathSite disc = MakePath({circle}, FillRule::kNonZero, Side::kBoth, 0);
  EXPECT_EQ(disc.pieces.size(), 4u);  // it ends at its start: no closing line
  EXPECT_TRUE(InsidePath({0.7, 0.7}, disc));    // radius 0.99
  EXPECT_FALSE(InsidePath({0.72, 0.72}, disc));  // radius 1.018
  EXPECT_NEAR(PathDistance({0, 0}, disc), 1, 3e-4);
}

// The drawn polylines stay within the tolerance of the pieces, and the farthest-distance
// bound holds at points of random rectangles.
TEST(PathSite, DrawnPolylinesAndFarthestBound) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1), t(0, 1);
  for (int n = 0; n < 40; ++n) {
    const PathSite path = MakePath({RandomSubpath(rng, n % 2 == 0)}, FillRule::kNonZero,
                                   Side::kBoth, n % 3 == 0 ? 0.0 : 0.01);
    for (uint32_t k = 0; k < path.pieces.size(); ++k) {
      ForEachPieceSegment(path, k, [&](Vec2 a, Vec2 b) {
        for (double s : {0.0, 0.5, 1.0}) {
          EXPECT_LE(double(PieceDistance(a + s * (b - a), path.pieces[k])), path.tolerance * (1 + 1e-9));
        }
      });
    }
    const Window rect{u(rng), u(rng), 0, 0};
    const Window r{rect.min_x, rect.min_y, rect.min_x + t(rng), rect.min_y + t(rng)};
    const double bound = PathFarthestDistance(r, path);
    for (int i = 0; i < 50; ++i) {
      const Vec2 q{r.min_x + t(rng) * (r.max_x - r.min_x), r.min_y + t(rng) * (r.max_y - r.min_y)};
      EXPECT_LE(double(OracleDistance(q, path)), bound * (1 + 1e-12)) << n;
    }
  }
}

}  // namespace
}  // namespace gvd
