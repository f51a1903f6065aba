#include "render/plan/distance_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace gvd {
namespace {

// The paper's figures (sec. 4.1.1): eps = one pixel, R = the grid's diagonal.
TEST(ConeSegments, PaperFigures) {
  EXPECT_EQ(ConeSegments(512 * std::sqrt(2.0), 1), 60u);
  EXPECT_EQ(ConeSegments(1024 * std::sqrt(2.0), 1), 85u);
}

TEST(ConeSegments, ScaleInvariant) {
  // The count depends only on R / eps.
  EXPECT_EQ(ConeSegments(1024 * std::sqrt(2.0) * 0.001, 0.001), 85u);
  EXPECT_EQ(ConeSegments(1024 * std::sqrt(2.0) * 1e6, 1e6), 85u);
}

TEST(ConeSegments, CoarseAndDegenerate) {
  EXPECT_EQ(ConeSegments(1, 1), 3u);
  EXPECT_EQ(ConeSegments(1, 50), 3u);
  EXPECT_EQ(ConeSegments(1e30, 1e-30), kMaxConeSegments);
}

// The count is the smallest whose polygon edges stay within eps of the base circle.
TEST(ConeSegments, MinimalAndSufficient) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ratio(1.5, 1e5);
  for (int t = 0; t < 2000; ++t) {
    double r = ratio(rng), eps = 1;
    uint32_t n = ConeSegments(r, eps);
    ASSERT_LE(r - r * std::cos(std::numbers::pi / n), eps * (1 + 1e-12)) << r;
    if (n > 3) {
      ASSERT_GT(r - r * std::cos(std::numbers::pi / (n - 1)), eps) << r;
    }
  }
}

// The unit cone's height over any point it covers is between the distance and
// `overestimate` times it; checked by sampling each triangle's plane.
TEST(BuildUnitCone, HeightWithinOverestimate) {
  for (uint32_t n : {3u, 4u, 7u, 60u, 85u, 1000u}) {
    ConeMesh m = BuildUnitCone(n);
    ASSERT_EQ(m.vertices.size(), n * 9u);
    EXPECT_DOUBLE_EQ(m.overestimate, 1 / std::cos(std::numbers::pi / n));
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<double> u(0, 1);
    for (uint32_t t = 0; t < n; ++t) {
      const float* v = &m.vertices[t * 9];
      EXPECT_EQ(v[0], 0.f);
      EXPECT_EQ(v[2], 0.f);
      EXPECT_EQ(v[5], 1.f);
      EXPECT_EQ(v[8], 1.f);
      for (int s = 0; s < 50; ++s) {
        double a = u(rng), b = u(rng);
        if (a + b > 1) a = 1 - a, b = 1 - b;
        double x = a * v[3] + b * v[6], y = a * v[4] + b * v[7], h = a + b;
        double d = std::hypot(x, y);
        EXPECT_LE(d, h + 1e-6);
        EXPECT_LE(h, d * m.overestimate + 1e-6);
      }
    }
  }
}

// ConeForReach keeps the error at `reach` within eps.
TEST(ConeForReach, ErrorAtReachWithinEps) {
  for (double reach : {1.0, 10.0, 724.0, 1448.2, 5000.0}) {
    for (double eps : {0.05, 1.0, 3.0}) {
      ConeMesh m = ConeForReach(reach, eps);
      EXPECT_LE(reach * (m.overestimate - 1), eps * (1 + 1e-12)) << reach << " " << eps;
    }
  }
}

}  // namespace
}  // namespace gvd
