// Frame lookups on frames built on the CPU from the exact oracle (no GL): the query contract
// must hold whatever mesh overestimate the frame carries.
#include "render/scene/frame.h"

#include <gtest/gtest.h>

#include <random>

#include "render/kernel/exact2.h"
#include "tests/support/oracle.h"
#include "tests/support/pixel_oracle.h"

namespace gvd {
namespace {

// A frame as a renderer with overestimate k would leave it: every site's mesh height at a
// pixel is its exact distance times a factor in [1, k] (drawn at random per site and pixel),
// and the pixel keeps the smallest.
std::shared_ptr<const Frame> EmulatedFrame(const Grid& grid, std::vector<Site> sites, double k,
                                           uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> factor(1, k);
  std::vector<uint32_t> ids(grid.pixel_count());
  std::vector<float> dist(grid.pixel_count());
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      double best = INFINITY;
      uint32_t id = 0;
      for (size_t s = 0; s < sites.size(); ++s) {
        double h = oracle::Distance(grid.Center(i, j), sites[s].geometry) * factor(rng);
        if (h < best) best = h, id = static_cast<uint32_t>(s + 1);
      }
      ids[size_t{j} * grid.width + i] = id;
      dist[size_t{j} * grid.width + i] = static_cast<float>(best);
    }
  }
  ErrorModel error{Diagram::kNearest, k, INFINITY, 0, 0x1p-22};  // float storage of D
  return std::make_shared<const Frame>(grid, 1, error, ids.data(), dist.data(),
                                       SiteSnapshot::Of(1, sites));
}

void ExpectContract(const Frame& frame, const SiteTable& sites, Vec2 q) {
  auto answer = frame.Nearest(q);
  ASSERT_TRUE(answer.has_value());
  const Site& site = sites[answer->site_index];
  const double tolerance = oracle::Tolerance(q, answer->distance);
  EXPECT_NEAR(answer->distance, oracle::Distance(q, site.geometry), tolerance);
  oracle::Best truth = oracle::BestSite(q, sites);
  EXPECT_GE(truth.value + tolerance, answer->distance - answer->error_bound)
      << "q=(" << q.x << "," << q.y << ") site " << site.id;
  EXPECT_GE(answer->error_bound, 0);
}

TEST(Frame, EmptyFrameHasNoAnswer) {
  auto f = Frame::Empty(Grid{{0, 0, 1, 1}, 4, 4}, 0.25, SiteSnapshot::Empty(3));
  EXPECT_TRUE(f->empty());
  EXPECT_EQ(f->version(), 3u);
  EXPECT_FALSE(f->Nearest({0.5, 0.5}).has_value());
}

TEST(Frame, PixelOfMapsCoordinatesToPixels) {
  // Window [10, 20] x [0, 5] at 10 x 5 pixels: pixel (i, j) covers [10+i, 11+i) x [j, j+1).
  auto f = EmulatedFrame(Grid{{10, 0, 20, 5}, 10, 5}, {{"a", PointSite{{12, 2}}}}, 1, 1);
  uint32_t i, j;
  f->PixelOf({10, 0}, &i, &j);
  EXPECT_EQ(i, 0u);
  EXPECT_EQ(j, 0u);
  f->PixelOf({13.99, 2.5}, &i, &j);
  EXPECT_EQ(i, 3u);
  EXPECT_EQ(j, 2u);
  f->PixelOf({20, 5}, &i, &j);  // the max corner belongs to the last pixel
  EXPECT_EQ(i, 9u);
  EXPECT_EQ(j, 4u);
  f->PixelOf({-1e9, 1e9}, &i, &j);
  EXPECT_EQ(i, 0u);
  EXPECT_EQ(j, 4u);
}

TEST(Frame, ExactFrameBoundIsAtMostAPixelDiagonal) {
  // With exact distances stored (k = 1) the answer's bound comes from the distance between
  // the query and the pixel centres around it alone.
  Grid grid{{0, 0, 1, 1}, 32, 32};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site> sites;
  for (int s = 0; s < 40; ++s) sites.push_back({std::to_string(s), PointSite{{u(rng), u(rng)}}});
  auto f = EmulatedFrame(grid, sites, 1, 2);
  for (int t = 0; t < 5000; ++t) {
    Vec2 q{u(rng), u(rng)};
    ExpectContract(*f, sites, q);
    EXPECT_LE(f->Nearest(q)->error_bound, grid.pixel_diagonal() * (1 + 1e-6));
  }
}

TEST(Frame, ContractHoldsWithOverestimatingMeshes) {
  for (double k : {1.001, 1.05, 1.5}) {
    Grid grid{{-3, 2, 5, 4}, 40, 13};  // non-square pixels
    std::mt19937_64 rng(static_cast<uint64_t>(k * 1000));
    std::uniform_real_distribution<double> ux(-5, 7), uy(0, 6);
    std::vector<Site> sites;
    for (int s = 0; s < 30; ++s) sites.push_back({std::to_string(s), PointSite{{ux(rng), uy(rng)}}});
    sites.push_back({"dup", std::get<PointSite>(sites[0].geometry)});  // coincident sites
    auto f = EmulatedFrame(grid, sites, k, 3);
    std::uniform_real_distribution<double> qx(-3, 5), qy(2, 4);
    for (int t = 0; t < 5000; ++t) ExpectContract(*f, sites, {qx(rng), qy(rng)});
    // Corners and edges of the window.
    for (Vec2 q : {Vec2{-3, 2}, Vec2{5, 4}, Vec2{-3, 4}, Vec2{5, 2}, Vec2{1, 2}}) {
      ExpectContract(*f, sites, q);
    }
  }
}

TEST(Frame, QueryOutsideTheWindowStillHonoursTheContract) {
  Grid grid{{0, 0, 1, 1}, 16, 16};
  SiteTable sites = {{"a", PointSite{{0.2, 0.2}}}, {"b", PointSite{{3, 3}}}};
  auto f = EmulatedFrame(grid, sites, 1.01, 4);
  ExpectContract(*f, sites, {2.9, 2.9});
  ExpectContract(*f, sites, {-10, 0.5});
}

// An answer with its feature asked for is the answer without (each candidate's value then
// comes from its nearest feature: one search of a curve or a tree for both), and the feature
// is the oracle's nearest part of the answer's site: sites of every kind, some with a
// max_distance (no candidate where the frame holds them: every site is scored), plain
// points (their feature is the slot table's point), random queries and queries on the sites.
TEST(Frame, AnAnswersFeatureIsTheOraclesAndLeavesTheAnswerAsItIs) {
  Generator gen(31);
  SiteTable sites;
  for (int s = 0; s < 30; ++s) {
    Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
    if (s % 7 == 3) site.max_distance = gen.U(0.02, 0.2);
    sites.push_back(std::move(site));
  }
  auto f = EmulatedFrame(Grid{{0, 0, 1, 1}, 24, 24}, sites, 1.05, 6);
  std::vector<Vec2> queries;
  for (int t = 0; t < 2000; ++t) queries.push_back(gen.P());
  for (const Site& site : sites) {  // (every fifth segment's start: a path has hundreds)
    const auto segments = oracle::Segments(site.geometry);
    for (size_t k = 0; k < segments.size(); k += 5) queries.push_back(gen.Near(segments[k].first, 0.01));
  }
  int features = 0;
  for (Vec2 q : queries) {
    SCOPED_TRACE(::testing::Message() << "q (" << q.x << ", " << q.y << ")");
    const auto plain = f->Nearest(q);
    FeatureHit hit;
    const auto with = f->Nearest(q, &hit);
    ASSERT_EQ(plain.has_value(), with.has_value());
    ASSERT_EQ(plain->found, with->found);
    if (!plain->found) continue;
    ASSERT_EQ(plain->site_index, with->site_index);
    ASSERT_EQ(plain->distance, with->distance);
    ASSERT_EQ(plain->error_bound, with->error_bound);
    ASSERT_EQ(plain->exact, with->exact);
    const Geometry& g = sites[with->site_index].geometry;
    ASSERT_NEAR(hit.distance, oracle::Distance(q, g), oracle::Tolerance(q, hit.distance));
    ASSERT_TRUE(oracle::IsNearestFeature(q, g, hit.kind, hit.index))
        << "site " << with->site_index << " feature " << int(hit.kind) << " " << hit.index;
    ASSERT_TRUE(oracle::IsClosestPoint(q, g, hit.kind, hit.index, hit.closest));
    ++features;
  }
  EXPECT_GT(features, 2000);
}

}  // namespace
}  // namespace gvd

namespace gvd {
namespace {

// What a frame says changed: all of it for a frame from whole buffers or an empty one; a
// frame made from a base of an earlier version, its own window; from a base of the same
// version (a render that writes several windows), both windows joined.
TEST(FrameChanged, WholeWindowsAndJoinedWindowsOfOneRender) {
  const Grid grid{{0, 0, 1, 1}, 40, 30};
  const std::vector<uint32_t> ids(grid.pixel_count(), 1);
  const std::vector<float> dist(grid.pixel_count(), 0.5f);
  const SiteTable sites = {{"a", PointSite{{0.5, 0.5}}}};
  auto v1 = std::make_shared<const Frame>(grid, 1, ErrorModel{}, ids.data(), dist.data(),
                                          SiteSnapshot::Of(1, sites));
  EXPECT_EQ(v1->changed(), grid.all());
  EXPECT_EQ(Frame::Empty(grid, 1, SiteSnapshot::Empty(3))->changed(), grid.all());
  const PixelRect a{2, 3, 10, 7}, b{20, 15, 25, 30};
  auto v2 = SiteSnapshot::Of(2, sites);
  auto first = std::make_shared<const Frame>(*v1, ErrorModel{}, a, ids.data(), dist.data(), v2);
  EXPECT_EQ(first->changed(), a);
  auto second = std::make_shared<const Frame>(*first, ErrorModel{}, b, ids.data(), dist.data(), v2);
  EXPECT_EQ(second->changed(), a.Union(b));
  auto next = std::make_shared<const Frame>(*second, ErrorModel{}, b, ids.data(), dist.data(),
                                            SiteSnapshot::Of(4, sites));
  EXPECT_EQ(next->changed(), b);
  auto nothing = std::make_shared<const Frame>(*next, ErrorModel{}, PixelRect{}, ids.data(),
                                               dist.data(), SiteSnapshot::Of(5, sites));
  EXPECT_TRUE(nothing->changed().empty());
}

}  // namespace
}  // namespace gvd
