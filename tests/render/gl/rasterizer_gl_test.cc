// Property tests of the rasterizer on a real EGL context (llvmpipe when there is no GPU):
// every pixel of random and adversarial scenes against the exact double-precision oracle.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <random>

#include "render/gl/context.h"
#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"
#include "tests/support/gl_fixture.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

class RenderGLTest : public GlTest {
 protected:
  // Renders from scratch; the frame's slot i holds sites[i] (ids are distinct).
  std::shared_ptr<const Frame> Render(const Grid& grid, double eps, const std::vector<Site>& sites,
                                      RenderStats* stats = nullptr,
                                      RenderMode mode = RenderMode::kMesh,
                                      FullRender path = FullRender::kAuto) {
    auto frame = RenderOnce(*rasterizer_, grid, eps, 1, sites, stats, mode, Diagram::kNearest,
                            path);
    EXPECT_TRUE(frame.ok()) << frame.status();
    for (uint32_t i = 0; i < sites.size(); ++i) EXPECT_EQ((*frame)->sites().get(i)->id, sites[i].id);
    return *frame;
  }

  // Checks every pixel against the oracle:
  //  - the stored distance is within eps (+ arithmetic slack) of the stored site's exact
  //    distance, and never below it by more than the slack (meshes overestimate);
  //  - the stored site is within 2 eps of the exact nearest (paper sec. 6.3), and
  //  - the frame's lower bound holds for the exact nearest distance (what queries rely on).
  // Returns the largest |stored - exact| seen, in pixels.
  static double CheckEveryPixel(const Frame& f, const SiteTable& sites) {
    const Grid& g = f.grid();
    const double eps = f.error().max_excess;  // the mesh's eps; 0 in exact mode
    const ErrorModel& e = f.error();
    double worst = 0;
    int failures = 0;
    for (uint32_t j = 0; j < g.height && failures < 5; ++j) {
      for (uint32_t i = 0; i < g.width && failures < 5; ++i) {
        Vec2 p = g.Center(i, j);
        uint32_t id = f.id_at(i, j);
        if (id == 0 || id > sites.size()) {
          ADD_FAILURE() << "pixel " << i << "," << j << " has id " << id;
          ++failures;
          continue;
        }
        double stored = f.distance_at(i, j);
        double to_stored = oracle::DrawnDistance(p, sites[id - 1].geometry);
        oracle::Best truth = oracle::BestSite(p, sites);
        double slack = e.Slack(stored);
        worst = std::max(worst, std::abs(stored - to_stored) / g.pixel_size());
        bool ok = stored <= to_stored + eps + slack && stored >= to_stored - slack &&
                  to_stored <= truth.value + 2 * eps + slack &&
                  e.LowerBound(stored) <= truth.value;
        if (!ok) {
          ++failures;
          ADD_FAILURE() << "pixel " << i << "," << j << " at (" << p.x << "," << p.y
                        << "): stored site " << id - 1 << " distance " << stored
                        << ", exact to it " << to_stored << ", exact nearest " << truth.index
                        << " at " << truth.value << ", eps " << eps << ", slack " << slack;
        }
      }
    }
    return worst;
  }

  static std::vector<Site> RandomPoints(size_t n, const Window& w, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
    std::vector<Site> sites;
    for (size_t s = 0; s < n; ++s) sites.push_back({std::to_string(s), PointSite{{ux(rng), uy(rng)}}});
    return sites;
  }

};

TEST_F(RenderGLTest, ContextReportsItsDevice) {
  EXPECT_FALSE(context_->info().gl_renderer.empty());
  EXPECT_NE(context_->info().gl_version.find("4."), std::string::npos);
}

TEST_F(RenderGLTest, SinglePointIsItsOwnCone) {
  // Sites: (0.3, 0.6) in the unit square at 64 x 64.
  Grid grid{{0, 0, 1, 1}, 64, 64};
  SiteTable sites = {{"a", PointSite{{0.3, 0.6}}}};
  CheckEveryPixel(*Render(grid, grid.pixel_size(), sites), sites);
}

// Exact mode: the same scenes, every stored distance within the arithmetic slack alone.
TEST_F(RenderGLTest, ExactModeRandomAndAdversarialScenes) {
  Window w{-2, 1, 3, 5};
  for (FullRender path : kPaths) {
    SCOPED_TRACE(Name(path));
    for (size_t n : {1, 100, 3000}) {
      Grid grid{w, 200, 160};
      auto sites = RandomPoints(n, w, n + 7);
      RenderStats stats;
      auto f = Render(grid, grid.pixel_size(), sites, &stats, RenderMode::kExact, path);
      EXPECT_EQ(stats.computed, path == FullRender::kCompute);
      EXPECT_EQ(f->error().max_excess, 0);
      EXPECT_EQ(f->error().overestimate, 1);
      CheckEveryPixel(*f, sites);
    }
    SiteTable outside = {{"left", PointSite{{-0.5, 0.5}}}, {"far", PointSite{{30, -40}}},
                         {"same1", PointSite{{0.7, 0.2}}}, {"same2", PointSite{{0.7, 0.2}}}};
    Grid unit{{0, 0, 1, 1}, 96, 64};
    CheckEveryPixel(*Render(unit, unit.pixel_size(), outside, nullptr, RenderMode::kExact, path),
                    outside);
    Grid far{{1e7, -1e7, 1e7 + 2, -1e7 + 1}, 200, 100};
    auto sites = RandomPoints(300, far.window, 5);
    CheckEveryPixel(*Render(far, far.pixel_size(), sites, nullptr, RenderMode::kExact, path),
                    sites);
  }
}

// A computed render whose buffers exceed the GL's storage-buffer limit (llvmpipe's 128 MiB:
// 32M pixels of ids) is drawn with meshes instead: the scene still renders, and right.
TEST_F(RenderGLTest, LargeExactScenesRenderWhateverTheStorageLimit) {
  Grid grid{{0, 0, 2, 1}, 8192, 4100};
  SiteTable sites = {{"a", PointSite{{0.3, 0.4}}}, {"b", PointSite{{1.7, 0.6}}},
                     {"c", PointSite{{1.0, 0.9}}}};
  RenderStats stats;
  auto frame = Render(grid, grid.pixel_size(), sites, &stats, RenderMode::kExact,
                      FullRender::kCompute);
  ASSERT_NE(frame, nullptr);
  RecordProperty("computed", stats.computed ? "yes" : "no");
  for (uint32_t j = 0; j < grid.height; j += 97) {
    for (uint32_t i = 0; i < grid.width; i += 89) {
      Vec2 p = grid.Center(i, j);
      auto best = oracle::BestSite(p, sites);
      ASSERT_EQ(frame->id_at(i, j), best.index + 1) << i << "," << j;
    }
  }
}

TEST_F(RenderGLTest, RandomScenesAtSeveralResolutions) {
  struct Case {
    size_t sites;
    uint32_t w, h;
  };
  // sites x pixels is kept near 1e8 so the brute-force oracle stays quick.
  for (Case c : {Case{1, 256, 256}, Case{10, 512, 512}, Case{100, 512, 384}, Case{1000, 256, 256},
                 Case{10000, 96, 96}}) {
    Window w{-2, 1, 3, 5};
    Grid grid{w, c.w, c.h};
    auto sites = RandomPoints(c.sites, w, c.sites);
    double worst = CheckEveryPixel(*Render(grid, grid.pixel_size(), sites), sites);
    RecordProperty("worst_px_" + std::to_string(c.sites), std::to_string(worst));
  }
}

TEST_F(RenderGLTest, NonSquarePixelsAndCoarseAndFineErrors) {
  Window w{0, 0, 10, 1};
  for (double eps_px : {0.0625, 1.0, 6.0}) {
    Grid grid{w, 100, 80};  // pixels 0.1 x 0.0125
    auto sites = RandomPoints(50, w, 9);
    CheckEveryPixel(*Render(grid, eps_px * grid.pixel_size(), sites), sites);
  }
}

TEST_F(RenderGLTest, TiesOnALatticeAndCoincidentSites) {
  // Sites on a lattice whose bisectors pass through rows of pixel centres, plus three sites
  // at one place.
  Grid grid{{0, 0, 64, 64}, 64, 64};
  std::vector<Site> sites;
  for (int y = 0; y <= 64; y += 8) {
    for (int x = 0; x <= 64; x += 8) {
      sites.push_back({std::to_string(sites.size()), PointSite{{double(x), double(y)}}});
    }
  }
  for (int d = 0; d < 3; ++d) sites.push_back({"same" + std::to_string(d), PointSite{{20.5, 20.5}}});
  CheckEveryPixel(*Render(grid, grid.pixel_size(), sites), sites);
}

TEST_F(RenderGLTest, SitesOutsideTheWindow) {
  Window w{0, 0, 1, 1};
  Grid grid{w, 128, 128};
  std::vector<Site> sites = {{"left", PointSite{{-0.5, 0.5}}},
                             {"far", PointSite{{30, -40}}},
                             {"corner", PointSite{{1.2, 1.3}}},
                             {"inside", PointSite{{0.7, 0.2}}}};
  CheckEveryPixel(*Render(grid, grid.pixel_size(), sites), sites);
}

TEST_F(RenderGLTest, WindowFarFromTheOrigin) {
  // Float vertex positions would lose the site's position at 1e7 if taken absolute.
  Window w{1e7, -1e7, 1e7 + 2, -1e7 + 1};
  Grid grid{w, 200, 100};
  auto sites = RandomPoints(300, w, 5);
  CheckEveryPixel(*Render(grid, grid.pixel_size(), sites), sites);
}

TEST_F(RenderGLTest, LoneSiteConeHasAtLeastThePapersTriangleCount) {
  // A lone site in a corner must reach the whole 1024 x 1024 grid with one pixel of error:
  // at least the paper's 85 triangles (sec. 4.1.1), rounded up to a shared bucket.
  Grid grid{{0, 0, 1, 1}, 1024, 1024};
  RenderStats stats;
  auto f = Render(grid, grid.pixel_size(), {{"corner", PointSite{{0, 0}}}}, &stats);
  EXPECT_GE(stats.cone_segments, 85u);
  EXPECT_LE(stats.cone_segments, 96u);
  EXPECT_EQ(stats.sites_drawn, 1u);
}

TEST_F(RenderGLTest, QueriesHonourTheirBound) {
  Window w{0, 0, 1, 1};
  Grid grid{w, 256, 256};
  auto sites = RandomPoints(2000, w, 21);
  auto f = Render(grid, grid.pixel_size(), sites);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  double worst_bound = 0;
  for (int t = 0; t < 20000; ++t) {
    Vec2 q{u(rng), u(rng)};
    auto a = f->Nearest(q);
    ASSERT_TRUE(a.has_value());
    oracle::Best truth = oracle::BestSite(q, sites);
    const double tolerance = oracle::Tolerance(q, a->distance);
    ASSERT_NEAR(a->distance, oracle::Distance(q, sites[a->site_index].geometry), tolerance);
    ASSERT_GE(truth.value + tolerance, a->distance - a->error_bound) << q.x << "," << q.y;
    worst_bound = std::max(worst_bound, a->error_bound);
  }
  // The bound is about a pixel diagonal plus the mesh's eps, not more.
  EXPECT_LE(worst_bound, grid.pixel_diagonal() + 2 * f->eps());
}

}  // namespace
}  // namespace gvd
