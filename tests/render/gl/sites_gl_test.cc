// Every site kind and diagram variant on a real EGL context, both render modes, against the
// exact double-precision oracle: every pixel of random and adversarial scenes, and queries.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "absl/cleanup/cleanup.h"
#include "render/plan/coverage.h"
#include "render/kernel/exact2.h"
#include "render/kernel/path2.h"
#include "render/gl/scene_raster.h"
#include "tests/support/gl_fixture.h"
#include "tests/support/oracle.h"
#include "tests/support/pixel_oracle.h"

namespace gvd {
namespace {

class SitesGLTest : public GlTest {
 protected:
  // Renders in both modes and both paths, the computed one both in native code and in the
  // compute shader (Rasterizer::native_scan), and checks every pixel.
  void RenderAndCheck(const Grid& grid, const SiteTable& sites, const std::string& what,
                      Diagram diagram = Diagram::kNearest, PixelReport* report = nullptr) {
    const std::vector<oracle::Best> truths = Truths(grid, sites, diagram);
    for (RenderMode mode : kModes) {
      for (FullRender path : kPaths) {
        for (bool other_scan : {false, true}) {
          if (other_scan && path != FullRender::kCompute) continue;
          const bool native = rasterizer_->native_scan();
          if (other_scan) rasterizer_->set_native_scan(!native);
          auto f = Render(grid, sites, mode, diagram, path);
          rasterizer_->set_native_scan(native);
          ASSERT_NE(f, nullptr);
          const std::string scan = path != FullRender::kCompute ? ""
                                   : native != other_scan     ? ", native"
                                                              : ", shader";
          PixelReport r = CheckEveryPixel(
              *f, sites, what + " (" + Name(mode) + ", " + Name(path) + scan + ")", &truths);
          if (report) *report = r;
        }
      }
    }
  }
};

const Grid kGrid{{0, 0, 1, 1}, 96, 96};

TEST_F(SitesGLTest, EachKindAgainstTheOracle) {
  for (int kind = 1; kind < Generator::kKinds; ++kind) {
    for (uint64_t seed = 1; seed <= 2; ++seed) {
      Generator gen(seed * 100 + kind);
      SiteTable sites;
      for (int s = 0; s < 10; ++s) sites.push_back({std::to_string(s), gen.Kind(kind)});
      // A few points, so that one-sided polygons leave something to find elsewhere.
      for (int s = 0; s < 3; ++s) sites.push_back({"p" + std::to_string(s), gen.Kind(0)});
      RenderAndCheck(kGrid, sites, std::string(Generator::kKindNames[kind]) + " seed " + std::to_string(seed));
    }
  }
}

// Sites long enough for their segment trees (render/kernel/segment_tree.h), through which the
// coverage finds the pieces and segments near each tile: random walks, scribbles crossing
// the window and one another, many-sided polygons of each side, a finely flattened curve,
// weights and max_distance, among points and short sites.
TEST_F(SitesGLTest, LongSitesAgainstTheOracle) {
  for (uint64_t seed = 1; seed <= 2; ++seed) {
    Generator gen(seed + 900);
    SiteTable sites;
    for (int s = 0; s < 8; ++s) {
      Site site{"long" + std::to_string(s), PointSite{}};
      const int n = 40 + 30 * (s % 3);
      switch (s % 4) {
        case 0: {
          PolylineSite walk{{gen.P()}};
          for (int k = 0; k < n; ++k) walk.points.push_back(gen.Near(walk.points.back(), 0.05));
          site.geometry = walk;
          break;
        }
        case 1: {
          PolylineSite scribble;
          for (int k = 0; k < n; ++k) scribble.points.push_back(gen.P());
          site.geometry = scribble;
          break;
        }
        case 2: {
          const Vec2 c = gen.P();
          PolygonSite poly;
          for (int k = 0; k < n; ++k) {
            const double t = 2 * M_PI * k / n, r = gen.U(0.1, 0.2);
            poly.vertices.push_back({c.x + r * std::cos(t), c.y + r * std::sin(t)});
          }
          poly.side = static_cast<Side>(s / 4 % 3 + seed - 1);
          site.geometry = poly;
          break;
        }
        default: {
          const Vec2 a = gen.P();
          site.geometry = MakeBezier({a, gen.Near(a, 0.4), gen.Near(a, 0.4), gen.Near(a, 0.4)},
                                     1e-5);
          break;
        }
      }
      if (s == 5) site.multiplicative = 1.6;
      if (s == 6) site.additive = 0.01;
      if (s == 7) site.max_distance = 0.1;
      sites.push_back(site);
    }
    for (int s = 0; s < 6; ++s) sites.push_back({"p" + std::to_string(s), gen.Kind(s % 3)});
    SlotTable slots(sites);
    for (uint32_t s = 0; s < 8; ++s) ASSERT_NE(slots.get(s)->segment_tree, nullptr) << s;
    RenderAndCheck(kGrid, sites, "long sites seed " + std::to_string(seed));
  }
}

TEST_F(SitesGLTest, PolygonSidesClaimOnlyTheirSide) {
  // A concave U; inside-only, its pixels are exactly those inside it (beyond the margin).
  PolygonSite u{{{0.2, 0.2}, {0.8, 0.2}, {0.8, 0.8}, {0.6, 0.8}, {0.6, 0.4}, {0.4, 0.4},
                 {0.4, 0.8}, {0.2, 0.8}},
                Side::kInside};
  SiteTable sites = {{"u", u}, {"p", PointSite{{0.5, 0.9}}}};
  for (RenderMode mode : kModes) {
    auto f = Render(kGrid, sites, mode);
    CheckEveryPixel(*f, sites, "U inside");
    size_t inside = 0, owned = 0;
    for (uint32_t j = 0; j < kGrid.height; ++j) {
      for (uint32_t i = 0; i < kGrid.width; ++i) {
        Vec2 p = kGrid.Center(i, j);
        if (oracle::Distance(p, u) <= DrawMargin(kGrid)) continue;
        bool in = oracle::Inside(p, u.vertices);
        inside += in;
        owned += f->id_at(i, j) == 1;
        EXPECT_EQ(f->id_at(i, j) == 1, in) << Name(mode) << " pixel " << i << "," << j;
      }
    }
    EXPECT_GT(inside, 1000u);
    EXPECT_EQ(owned, inside);
  }
}

// Paths restricted to a side, by each fill rule, on every path of the rasterizer: two squares
// turning the same way, a smaller one within a larger one, whose inner square is inside by
// the nonzero rule (winding 2) and a hole by the even-odd rule; and a ring of curves (a
// rounded square of lines and cubics) around a hole of quadratics turning the other way. Of
// the pixels farther than the margin from the outline, the path holds none on the side it
// leaves out, and every one on its side where it is clearly nearer than a point beside it.
TEST_F(SitesGLTest, PathSidesFollowTheirFillRule) {
  const Subpath outer{{{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.1, 0.9}}, {1, 1, 1}, true};
  const Subpath inner{{{0.3, 0.3}, {0.7, 0.3}, {0.7, 0.7}, {0.3, 0.7}}, {1, 1, 1}, true};
  const double k = 0.5523 * 0.2;
  const Subpath rounded{{{0.3, 0.1}, {0.7, 0.1}, {0.7 + k, 0.1}, {0.9, 0.3 - k}, {0.9, 0.3},
                         {0.9, 0.9}, {0.1, 0.9}, {0.1, 0.3}, {0.1, 0.3 - k}, {0.3 - k, 0.1}, {0.3, 0.1}},
                        {1, 3, 1, 1, 1, 3}, true};
  const Subpath hole{{{0.6, 0.5}, {0.6, 0.4}, {0.5, 0.4}, {0.4, 0.4}, {0.4, 0.5}, {0.4, 0.6},
                      {0.5, 0.6}, {0.6, 0.6}, {0.6, 0.5}},
                     {2, 2, 2, 2}, true};
  struct Case {
    std::vector<Subpath> subpaths;
    FillRule fill;
    const char* what;
  };
  for (const Case& c : {Case{{outer, inner}, FillRule::kNonZero, "nested, nonzero"},
                        Case{{outer, inner}, FillRule::kEvenOdd, "nested, even-odd"},
                        Case{{rounded, hole}, FillRule::kNonZero, "rounded ring"}}) {
    for (Side side : {Side::kInside, Side::kOutside}) {
      const PathSite path = MakePath(c.subpaths, c.fill, side, kGrid.pixel_size() / 4);
      const SiteTable sites = {{"path", path}, {"p", PointSite{{0.5, 0.95}}}};
      const std::string what = std::string(c.what) + (side == Side::kInside ? ", inside" : ", outside");
      RenderAndCheck(kGrid, sites, what);
      for (RenderMode mode : kModes) {
        for (FullRender full : kPaths) {
          auto f = Render(kGrid, sites, mode, Diagram::kNearest, full);
          size_t owned = 0, want = 0;
          for (uint32_t j = 0; j < kGrid.height; ++j) {
            for (uint32_t i = 0; i < kGrid.width; ++i) {
              const Vec2 p = kGrid.Center(i, j);
              if (oracle::DrawnDistance(p, path) <= DrawMargin(kGrid)) continue;
              // Present on its side; there it is the best where clearly nearer than the point.
              const bool in = oracle::InsidePath(p, path) == (side == Side::kInside);
              const bool nearer = oracle::Distance(p, path) + 2 * kGrid.pixel_size() <
                                  oracle::Distance(p, sites[1].geometry);
              ASSERT_TRUE(in || f->id_at(i, j) != 1) << what << " (" << Name(mode) << ", "
                                                     << Name(full) << ") pixel " << i << "," << j;
              want += in && nearer;
              owned += in && nearer && f->id_at(i, j) == 1;
            }
          }
          EXPECT_GT(want, 500u) << what;
          EXPECT_EQ(owned, want) << what;
        }
      }
    }
  }
}

TEST_F(SitesGLTest, WeightsAgainstTheOracle) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    Generator gen(seed);
    SiteTable sites;
    for (int s = 0; s < 14; ++s) {
      Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
      site.additive = gen.U(0, 1) < 0.5 ? gen.U(0, 0.3) : 0;
      site.multiplicative = gen.U(0, 1) < 0.5 ? gen.U(0.3, 3) : 1;
      sites.push_back(site);
    }
    RenderAndCheck(kGrid, sites, "weights seed " + std::to_string(seed));
  }
}

TEST_F(SitesGLTest, MaxDistanceLeavesPixelsEmpty) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    Generator gen(seed + 50);
    SiteTable sites;
    for (int s = 0; s < 12; ++s) {
      Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
      site.max_distance = gen.U(0.02, 0.2);
      if (s % 3 == 0) site.multiplicative = gen.U(0.5, 2);
      sites.push_back(site);
    }
    PixelReport r;
    RenderAndCheck(kGrid, sites, "max_distance seed " + std::to_string(seed), Diagram::kNearest,
                   &r);
    EXPECT_GT(r.empty, 100u) << "the scene should leave empty pixels";
    // Queries there say so, certainly; elsewhere they find a candidate.
    auto f = Render(kGrid, sites, RenderMode::kMesh);
    size_t empty = 0;
    for (int k = 0; k < 4000; ++k) {
      Vec2 q{gen.U(0, 1), gen.U(0, 1)};
      auto a = f->Nearest(q);
      ASSERT_TRUE(a.has_value());
      oracle::Best truth = oracle::BestSite(q, sites);
      ASSERT_EQ(a->found, truth.found) << q.x << "," << q.y;
      empty += !a->found;
    }
    EXPECT_GT(empty, 100u);
  }
}

TEST_F(SitesGLTest, FarthestAgainstTheOracle) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    Generator gen(seed + 70);
    SiteTable sites;
    for (int s = 0; s < 10; ++s) {
      Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
      if (s % 2) site.multiplicative = gen.U(0.5, 2);
      if (s % 3 == 0) site.additive = gen.U(0, 0.2);
      if (s == 4) site.max_distance = 0.5;
      sites.push_back(site);
    }
    RenderAndCheck(kGrid, sites, "farthest seed " + std::to_string(seed), Diagram::kFarthest);
  }
}

TEST_F(SitesGLTest, AdversarialScenes) {
  std::vector<std::pair<std::string, SiteTable>> scenes;
  scenes.push_back({"zero-length segment and a point on a segment",
                    {{"z", SegmentSite{{0.3, 0.3}, {0.3, 0.3}}},
                     {"s", SegmentSite{{0.1, 0.7}, {0.9, 0.7}}},
                     {"on", PointSite{{0.5, 0.7}}},
                     {"p", PointSite{{0.7, 0.2}}}}});
  scenes.push_back({"repeated and collinear vertices",
                    {{"l", PolylineSite{{{0.1, 0.1}, {0.1, 0.1}, {0.5, 0.5}, {0.7, 0.7},
                                         {0.7, 0.7}, {0.9, 0.2}}}},
                     {"g", PolygonSite{{{0.2, 0.8}, {0.4, 0.8}, {0.6, 0.8}, {0.6, 0.8},
                                        {0.6, 0.95}, {0.2, 0.95}}}},
                     {"p", PointSite{{0.8, 0.5}}}}});
  scenes.push_back({"self-touching and self-intersecting polygons",
                    {{"touch", PolygonSite{{{0.1, 0.1}, {0.5, 0.1}, {0.3, 0.3}, {0.5, 0.5},
                                            {0.1, 0.5}, {0.3, 0.3}},
                                           Side::kOutside}},
                     {"bowtie", PolygonSite{{{0.55, 0.55}, {0.95, 0.95}, {0.95, 0.55},
                                             {0.55, 0.95}},
                                            Side::kInside}},
                     {"p", PointSite{{0.8, 0.2}}}}});
  scenes.push_back({"zero-area polygon, inside only",
                    {{"flat", PolygonSite{{{0.2, 0.5}, {0.5, 0.5}, {0.8, 0.5}}, Side::kInside}},
                     {"flat2", PolygonSite{{{0.2, 0.3}, {0.5, 0.3}, {0.8, 0.3}}}},
                     {"p", PointSite{{0.5, 0.8}}}}});
  Site huge_m{"huge_m", PointSite{{0.2, 0.2}}};
  huge_m.multiplicative = 1e6;
  Site huge_a{"huge_a", SegmentSite{{0.5, 0.5}, {0.6, 0.9}}};
  huge_a.additive = 1e15;
  Site tiny_m{"tiny_m", PointSite{{0.9, 0.9}}};
  tiny_m.multiplicative = 1e-6;
  scenes.push_back({"huge and tiny weights",
                    {huge_m, huge_a, tiny_m, {"p", PointSite{{0.5, 0.1}}}}});
  scenes.push_back({"sites partly and wholly outside the window",
                    {{"across", PolygonSite{{{-0.5, 0.4}, {0.3, 0.45}, {-0.2, 0.9}}}},
                     {"far", SegmentSite{{5, -3}, {6, 9}}},
                     {"curve", MakeBezier({{-0.3, -0.3}, {0.5, 2}, {1.5, -1}, {1.4, 0.6}}, 0.001)},
                     {"p", PointSite{{0.7, 0.7}}}}});
  scenes.push_back({"ties: coincident segments, symmetric sites",
                    {{"a", SegmentSite{{0.2, 0.5}, {0.8, 0.5}}},
                     {"b", SegmentSite{{0.8, 0.5}, {0.2, 0.5}}},
                     {"c", PointSite{{0.5, 0.2}}},
                     {"d", PointSite{{0.5, 0.8}}}}});
  for (const auto& [name, sites] : scenes) {
    RenderAndCheck(kGrid, sites, name);
    RenderAndCheck(kGrid, sites, name + ", farthest", Diagram::kFarthest);
  }
}

// A scene mixing every kind, weights, max_distance and sides: 10,000 random queries, inside
// the window and around it, are answered within their reported bound, nearest and farthest.
TEST_F(SitesGLTest, MixedSceneAnswersWithinBound) {
  const Grid grid{{0, 0, 1, 1}, 256, 256};
  Generator gen(2026);
  SiteTable sites;
  for (int s = 0; s < 28; ++s) {
    Site site{std::to_string(s), gen.Kind(s % Generator::kKinds)};
    if (s % 4 == 1) site.additive = gen.U(0, 0.1);
    if (s % 4 == 2) site.multiplicative = gen.U(0.5, 2);
    if (s % 5 == 3) site.max_distance = gen.U(0.1, 0.3);
    sites.push_back(site);
  }
  for (Diagram diagram : {Diagram::kNearest, Diagram::kFarthest}) {
    for (RenderMode mode : kModes) {
      auto f = Render(grid, sites, mode, diagram);
      ASSERT_NE(f, nullptr);
      size_t empty = 0;
      double worst_bound = 0;
      for (int k = 0; k < 10000; ++k) {
        Vec2 q{gen.U(-0.1, 1.1), gen.U(-0.1, 1.1)};
        auto a = f->Nearest(q);
        ASSERT_TRUE(a.has_value());
        oracle::Best truth = oracle::BestSite(q, sites, diagram);
        ASSERT_EQ(a->found, truth.found) << "query " << q.x << "," << q.y;
        if (!a->found) {
          ++empty;
          continue;
        }
        const Site& s = *f->sites().get(a->site_index);
        const double tolerance = oracle::Tolerance(q, a->distance, s.multiplicative);
        ASSERT_NEAR(a->distance, oracle::Value(q, s), tolerance) << "the answer's value is exact";
        double gap = diagram == Diagram::kNearest ? a->distance - truth.value
                                                  : truth.value - a->distance;
        ASSERT_GE(gap, -tolerance);
        ASSERT_LE(gap, a->error_bound + tolerance) << Name(mode) << " query " << q.x << "," << q.y;
        worst_bound = std::max(worst_bound, a->error_bound);
      }
      // The bound is a few pixels of weighted distance at most, not a vacuous one.
      EXPECT_LT(worst_bound, 16 * grid.pixel_size() * 2 + 0.01) << Name(mode);
    }
  }
}

// Updates of every kind: in mesh mode computed on the CPU from the frame, as on a software
// device (where full renders are computed in native code: Rasterizer::native_scan); in exact
// mode drawn into the target and read back, as on a GPU.
TEST_F(SitesGLTest, IncrementalUpdatesOfEveryKindHoldAgainstTheOracle) {
  const bool native = rasterizer_->native_scan();
  absl::Cleanup restore = [&] { rasterizer_->set_native_scan(native); };
  for (RenderMode mode : kModes) {
    const bool computed = mode == RenderMode::kMesh;
    rasterizer_->set_native_scan(computed);
    const std::string what = std::string(Name(mode)) + (computed ? ", computed" : ", drawn");
    // The full render's path: computed where the device is software or the mode exact.
    const bool full_computed = rasterizer_->software() || mode == RenderMode::kExact;
    auto raster = SceneRaster::Create(kGrid, kGrid.pixel_size(), mode);
    ASSERT_TRUE(raster.ok());
    Generator gen(mode == RenderMode::kMesh ? 11 : 12);
    std::map<std::string, Site> live;
    auto snapshot = SiteSnapshot::Empty(1);
    std::vector<uint32_t> free_slots;
    int updates = 0;
    for (int step = 0; step < 24; ++step) {
      std::vector<SiteChange> changes;
      int n = step == 0 ? 12 : 1 + int(gen.U(0, 3));
      for (int c = 0; c < n; ++c) {
        std::string id = std::to_string(int(gen.U(0, 16)));
        if (live.count(id) && gen.U(0, 1) < 0.3 && live.size() > 1) {
          live.erase(id);
          changes.emplace_back(id, std::nullopt);
          continue;
        }
        Site s{id, gen.Kind(int(gen.U(0, Generator::kKinds)))};
        if (gen.U(0, 1) < 0.3) s.multiplicative = gen.U(0.5, 2);
        if (gen.U(0, 1) < 0.3) s.max_distance = gen.U(0.1, 0.4);
        live[id] = s;
        changes.emplace_back(id, s);
      }
      snapshot = Advance(snapshot, std::move(changes), &free_slots);
      RenderStats stats;
      auto f = (*raster)->Apply(*rasterizer_, snapshot, &stats);
      ASSERT_TRUE(f.ok()) << f.status();
      if (!stats.full) {
        ++updates;
        EXPECT_EQ(stats.computed, computed && full_computed) << what << " step " << step;
      }
      CheckEveryPixel(**f, OracleSites((*f)->sites()), what + " step " + std::to_string(step));
      if (HasFailure()) return;
    }
    // The others render everything: their windows cover half the grid.
    std::printf("%s: %d updates of 23 redrew windows\n", what.c_str(), updates);
    EXPECT_GT(updates, 0) << what;
  }
}

TEST(Bezier, FlatteningStaysWithinTolerance) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    std::vector<Vec2> control;
    for (int c = 0; c < 3 + k % 2; ++c) control.push_back({u(rng), u(rng)});
    double tol = std::pow(10, -1 - k % 5);
    BezierSite b = MakeBezier(control, tol);
    EXPECT_EQ(b.tolerance, tol);
    PolylineSite flat{b.flat};
    for (int s = 0; s <= 2000; ++s) {  // the curve lies within tol of its flattening
      oracle::Real x, y;
      oracle::CurveAt(control, oracle::Real(s) / 2000, &x, &y);
      const Vec2 p{double(x), double(y)};
      ASSERT_LE(oracle::Distance(p, flat), tol * (1 + 1e-9)) << "curve " << k << " t " << s / 2000.0;
    }
    for (Vec2 p : b.flat) {  // the flattening's points lie on the curve
      ASSERT_LE(oracle::CurveDistance(p, control), 1e-9) << "curve " << k << " at " << p.x << ", " << p.y;
    }
  }
}

}  // namespace
}  // namespace gvd
