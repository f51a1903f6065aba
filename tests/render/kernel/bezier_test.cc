// The nearest point of a Bezier curve (render/kernel/bezier.h) against the tests' oracle
// (tests/support/oracle.h: long double, the Bernstein polynomials written out, bisection on
// the derivative's signs at 1,024 steps and golden-section search near each sampled
// minimum): random curves; adversarial ones (near-degenerate, cusped, looped, collinear with
// the curve doubling back, tiny far from the origin, huge); and the outlines of real glyphs,
// TrueType's quadratics (DejaVu Sans) and CFF's cubics (Cantarell), read by FreeType.
#include "render/kernel/bezier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "render/kernel/exact2.h"
#include "tests/support/glyphs.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

double Extent(const std::vector<Vec2>& control) {
  double e = 0;
  for (Vec2 p : control) e = std::max(e, Length(p));
  return e;
}

// The answer against the oracle: its distance within the stated bound of the true one, its
// point on the curve (within the same bound) at that distance from q, its t that point's.
void Check(Vec2 q, const std::vector<Vec2>& control, const std::string& what) {
  SCOPED_TRACE(::testing::Message() << what << " q (" << q.x << ", " << q.y << ")");
  const CurvePoint got = NearestOnBezier(q, control);
  const double truth = static_cast<double>(oracle::CurveDistance(q, control));
  const double bound = BezierDistanceError(got.distance, Extent(control));
  ASSERT_NEAR(got.distance, truth, bound);
  ASSERT_EQ(got.distance, Distance(q, got.point));
  ASSERT_GE(got.t, 0);
  ASSERT_LE(got.t, 1);
  ASSERT_LE(static_cast<double>(oracle::CurveDistance(got.point, control)), bound);
  // The feature the kernel names for it: an end, or the curve.
  const Geometry curve = MakeBezier(control, 0);
  const FeatureHit f = NearestFeature(q, curve);
  ASSERT_EQ(f.distance, got.distance);
  ASSERT_NEAR(oracle::FeatureDistance(q, curve, f.kind, f.index), truth, bound)
      << "feature " << int(f.kind) << " " << f.index;
}

// Queries around a curve: random ones over its box and beyond, points of the curve, points
// just off it along its normal, the centres of curvature (where nearby points of the curve
// are all nearly equally near), and far away.
std::vector<Vec2> Around(const std::vector<Vec2>& control, std::mt19937_64& rng, int random) {
  Window box{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (Vec2 p : control) {
    box = {std::min(box.min_x, p.x), std::min(box.min_y, p.y), std::max(box.max_x, p.x),
           std::max(box.max_y, p.y)};
  }
  const double size = std::max({box.width(), box.height(), 1e-300});
  std::uniform_real_distribution<double> u(-0.5, 1.5);
  std::vector<Vec2> out;
  for (int k = 0; k < random; ++k) {
    out.push_back({box.min_x + u(rng) * size, box.min_y + u(rng) * size});
  }
  const int n = static_cast<int>(control.size()) - 1;
  for (double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
    const Vec2 b = BezierPoint(control, t);
    // The derivative and second derivative, by differences of the control points.
    std::vector<Vec2> d, dd;
    for (int j = 0; j < n; ++j) d.push_back(double(n) * (control[j + 1] - control[j]));
    for (int j = 0; j + 1 < n; ++j) dd.push_back(double(n - 1) * (d[j + 1] - d[j]));
    auto at = [t](const std::vector<Vec2>& c) {
      Vec2 s(0);
      const double w2[2] = {1 - t, t}, w3[3] = {(1 - t) * (1 - t), 2 * (1 - t) * t, t * t};
      for (size_t i = 0; i < c.size(); ++i) s += (c.size() == 1 ? 1.0 : c.size() == 2 ? w2[i] : w3[i]) * c[i];
      return s;
    };
    const Vec2 b1 = at(d), b2 = at(dd);
    out.push_back(b);
    const double speed = Length(b1);
    if (!(speed > 0)) continue;
    const Vec2 normal{-b1.y / speed, b1.x / speed};
    for (double off : {1e-12, 1e-6, 1e-3, 0.3}) out.push_back(b + off * size * normal);
    const double cross = b1.x * b2.y - b1.y * b2.x;
    if (cross != 0) out.push_back(b + speed * speed * speed / cross * normal);  // curvature centre
  }
  out.push_back({box.min_x + 1e3 * size, box.min_y - 7e2 * size});
  return out;
}

TEST(BezierNearest, RandomCurvesAgreeWithTheOracle) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u(0, 1);
  int checked = 0;
  for (int k = 0; k < 400; ++k) {
    std::vector<Vec2> control;
    for (size_t i = 0; i < (k % 2 ? 4u : 3u); ++i) control.push_back({u(rng), u(rng)});
    for (Vec2 q : Around(control, rng, 10)) {
      Check(q, control, "random curve " + std::to_string(k));
      ++checked;
    }
  }
  EXPECT_GT(checked, 8000);
}

TEST(BezierNearest, AdversarialCurvesAgreeWithTheOracle) {
  const std::vector<std::pair<std::string, std::vector<Vec2>>> curves = {
      // The issue's: a glyph's quadratic, far (for its size) from the origin.
      {"glyph quadratic",
       {{3.74755859375, 0.68017578125}, {3.74755859375, 0.70263671875}, {3.763916015625, 0.71923828125}}},
      {"cusp", {{0, 0}, {1, 1}, {0, 1}, {1, 0}}},
      {"loop", {{0, 0}, {3, 3}, {-2, 3}, {1, 0}}},
      {"collinear, doubling back", {{0, 0}, {2, 0}, {-1, 0}, {1, 0}}},
      {"collinear quadratic, doubling back", {{0, 0}, {3, 0}, {1, 0}}},
      {"coincident ends", {{0.5, 0.5}, {1, 2}, {0, 2}, {0.5, 0.5}}},
      {"all one point", {{0.25, 0.75}, {0.25, 0.75}, {0.25, 0.75}, {0.25, 0.75}}},
      {"near-degenerate", {{0.25, 0.75}, {0.25 + 1e-13, 0.75}, {0.25, 0.75 + 1e-13}, {0.25, 0.75}}},
      {"tiny, far out", {{1e6, -1e6}, {1e6 + 1e-6, -1e6 + 2e-6}, {1e6 + 3e-6, -1e6}}},
      {"huge", {{-3e7, 1e7}, {5e7, 9e7}, {9e7, -4e7}, {2e7, 2e7}}},
      {"a near circle's quarter", {{1, 0}, {1, 0.5522847498}, {0.5522847498, 1}, {0, 1}}},
  };
  std::mt19937_64 rng(5);
  int checked = 0;
  for (const auto& [name, control] : curves) {
    std::vector<Vec2> queries = Around(control, rng, 200);
    queries.push_back({0, 0});  // the near circle's centre: every point nearly equally near
    queries.push_back({3.5394, 0.73453});
    for (Vec2 q : queries) {
      Check(q, control, name);
      ++checked;
    }
  }
  EXPECT_GT(checked, 2000);
  // The numbers: the true distance is 0.21365062 (the flattening's was 0.21368067).
  const CurvePoint p = NearestOnBezier({3.5394, 0.73453}, curves[0].second);
  EXPECT_NEAR(p.distance, 0.21365062, 5e-9);
}

TEST(BezierNearest, GlyphOutlinesAgreeWithTheOracle) {
  const struct {
    const char* path;
    size_t degree;
  } fonts[] = {{testing::kTrueTypeFont, 3},
               {testing::kCffFont, 4}};
  std::mt19937_64 rng(11);
  for (const auto& font : fonts) {
    const auto curves = testing::GlyphCurves(font.path, "gvd&Q@8sS");
    ASSERT_GT(curves.size(), 40u) << font.path;
    int checked = 0;
    for (const auto& control : curves) {
      ASSERT_EQ(control.size(), font.degree) << font.path;
      for (Vec2 q : Around(control, rng, 8)) {
        Check(q, control, font.path);
        ++checked;
      }
    }
    EXPECT_GT(checked, 1000) << font.path;
  }
}

}  // namespace
}  // namespace gvd
