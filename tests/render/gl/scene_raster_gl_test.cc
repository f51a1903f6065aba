// Incremental rendering on a real EGL context: after any sequence of adds, moves and deletes,
// the incrementally maintained frame equals a from-scratch render of the same sites, pixel
// for pixel (ties aside), and holds against the exact oracle.
#include "render/gl/scene_raster.h"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <random>

#include "absl/cleanup/cleanup.h"
#include "render/gl/context.h"
#include "tests/support/gl_fixture.h"
#include "tests/support/oracle.h"
#include "render/kernel/exact2.h"

namespace gvd {
namespace {

class SceneRasterGLTest : public GlTest {
 protected:
  // The sites of a frame, by slot, as the oracle sees them.
  static SiteTable Live(const std::map<std::string, Vec2>& sites) {
    SiteTable t;
    for (const auto& [id, p] : sites) t.push_back({id, PointSite{p}});
    return t;
  }

  // Compares the incremental frame with a fresh render at every pixel, and with the oracle
  // at every `oracle_stride`-th pixel (1: all of them).
  static void ExpectEquivalent(const Frame& inc, const std::map<std::string, Vec2>& sites,
                               const std::string& when, uint32_t oracle_stride = 1) {
    const Grid& g = inc.grid();
    SiteTable live = Live(sites);
    const RenderMode mode = inc.error().max_excess == 0 ? RenderMode::kExact : RenderMode::kMesh;
    auto full = RenderOnce(*rasterizer_, g, inc.eps(), inc.version(), live, nullptr, mode);
    ASSERT_TRUE(full.ok()) << full.status();
    const Frame& ref = **full;
    ASSERT_EQ(inc.site_count(), live.size());
    int failures = 0;
    for (uint32_t j = 0; j < g.height && failures < 5; ++j) {
      for (uint32_t i = 0; i < g.width && failures < 5; ++i) {
        Vec2 p = g.Center(i, j);
        uint32_t a = inc.id_at(i, j), b = ref.id_at(i, j);
        if (a == 0 || b == 0) {
          ADD_FAILURE() << when << ": pixel " << i << "," << j << " has no site";
          ++failures;
          continue;
        }
        const Site* sa = inc.sites().get(a - 1);
        const Site* sb = ref.sites().get(b - 1);
        ASSERT_TRUE(sa && sb) << when << ": pixel " << i << "," << j << " names a free slot";
        double da = oracle::DrawnDistance(p, sa->geometry), db = oracle::DrawnDistance(p, sb->geometry);
        const bool checked = (j * g.width + i) % oracle_stride == 0;
        double truth = checked ? oracle::BestSite(p, live).value : std::min(da, db);
        double eps = inc.error().max_excess, slack = inc.error().Slack(inc.distance_at(i, j));
        // The same site, or a tie within the meshes' error; distances within eps of each other.
        bool same = sa->id == sb->id || std::abs(da - db) <= 2 * eps + slack;
        bool close = std::abs(inc.distance_at(i, j) - ref.distance_at(i, j)) <= eps + 2 * slack;
        bool sound = da <= truth + 2 * eps + slack &&
                     (!checked || inc.error().LowerBound(inc.distance_at(i, j)) <= truth);
        if (!same || !close || !sound) {
          ++failures;
          ADD_FAILURE() << when << ": pixel " << i << "," << j << " incremental " << sa->id << " "
                        << inc.distance_at(i, j) << " (exact " << da << "), from scratch "
                        << sb->id << " " << ref.distance_at(i, j) << " (exact " << db
                        << "), nearest " << truth;
        }
      }
    }
  }

};

// Seeds 1 and 2 draw the updates into the target; 3 and 4 compute them on the CPU, as a
// software device does by default (Rasterizer::native_scan).
TEST_F(SceneRasterGLTest, RandomUpdateSequencesMatchRendersFromScratch) {
  const bool native = rasterizer_->native_scan();
  absl::Cleanup restore = [&] { rasterizer_->set_native_scan(native); };
  for (uint64_t seed : {1, 2, 3, 4}) {
    rasterizer_->set_native_scan(seed > 2);
    const RenderMode mode = seed % 2 ? RenderMode::kMesh : RenderMode::kExact;
    Grid grid{{0, 0, 4, 3}, 128, 96};
    auto raster = SceneRaster::Create(grid, grid.pixel_size(), mode);
    ASSERT_TRUE(raster.ok());
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> ux(-0.5, 4.5), uy(-0.5, 3.5);  // some outside
    std::map<std::string, Vec2> sites;
    int next = 0;
    auto snapshot = SiteSnapshot::Empty(1);
    std::vector<uint32_t> free_slots;
    auto apply = [&](std::vector<SiteChange> changes, const std::string& what) {
      snapshot = Advance(snapshot, std::move(changes), &free_slots);
      auto f = (*raster)->Apply(*rasterizer_, snapshot);
      ASSERT_TRUE(f.ok()) << f.status();
      ExpectEquivalent(**f, sites, what + " (seed " + std::to_string(seed) + ", version " +
                                       std::to_string(snapshot->version()) + ")");
    };
    std::vector<SiteChange> initial;
    for (int i = 0; i < 150; ++i) {
      std::string id = "s" + std::to_string(next++);
      sites[id] = {ux(rng), uy(rng)};
      initial.push_back({id, PointSite{sites[id]}});
    }
    apply(std::move(initial), "initial");
    for (int step = 0; step < 40 && !HasFailure(); ++step) {
      std::vector<SiteChange> changes;
      int kind = step % 4;
      int count = 1 + static_cast<int>(rng() % 3);
      for (int c = 0; c < count; ++c) {
        auto pick = [&] {
          auto it = sites.begin();
          std::advance(it, rng() % sites.size());
          return it->first;
        };
        if (kind == 0 || sites.size() < 10) {  // add
          std::string id = "s" + std::to_string(next++);
          sites[id] = {ux(rng), uy(rng)};
          changes.push_back({id, PointSite{sites[id]}});
        } else if (kind == 1) {  // move
          std::string id = pick();
          sites[id] = {ux(rng), uy(rng)};
          changes.push_back({id, PointSite{sites[id]}});
        } else if (kind == 2) {  // delete
          std::string id = pick();
          sites.erase(id);
          changes.push_back({id, std::nullopt});
        } else {  // a burst: add, move the new one, delete another
          std::string id = "s" + std::to_string(next++);
          changes.push_back({id, PointSite{{ux(rng), uy(rng)}}});
          sites[id] = {ux(rng), uy(rng)};
          changes.push_back({id, PointSite{sites[id]}});
          std::string gone = pick();
          if (gone != id) {
            sites.erase(gone);
            changes.push_back({gone, std::nullopt});
          }
        }
      }
      apply(std::move(changes), "step " + std::to_string(step));
    }
  }
}

// In a large scene, an update of many changes at once (changes gathered while a render was
// busy) still redraws windows, more than a small scene's few dozen, and matches a render
// from scratch. Only the first update is held to redraw windows: later ones choose by what
// the scene's renders took (UpdateCost), which is the machine's to say.
TEST_F(SceneRasterGLTest, ManyChangesInALargeSceneRedrawWindows) {
  Grid grid{{0, 0, 4, 3}, 512, 384};
  auto raster = SceneRaster::Create(grid, grid.pixel_size(), RenderMode::kMesh);
  ASSERT_TRUE(raster.ok());
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> ux(0, 4), uy(0, 3);
  std::map<std::string, Vec2> sites;
  std::vector<SiteChange> initial;
  constexpr int kSites = 36000;  // n / 512 = 70 windows, past the 64 a small scene is held to
  for (int i = 0; i < kSites; ++i) {
    const std::string id = "s" + std::to_string(i);
    sites[id] = {ux(rng), uy(rng)};
    initial.push_back({id, PointSite{sites[id]}});
  }
  auto snapshot = SiteSnapshot::Empty(1);
  std::vector<uint32_t> free_slots;
  snapshot = Advance(snapshot, std::move(initial), &free_slots);
  ASSERT_TRUE((*raster)->Apply(*rasterizer_, snapshot).ok());
  for (int round = 0; round < 2 && !HasFailure(); ++round) {
    // 34 moves: 68 windows (each move's old reach and its new place: with these sites, each
    // moved one held pixels), more than 64; more moves would merge into windows over half
    // the grid, which is redrawn whole.
    std::vector<SiteChange> moves;
    std::set<std::string> moved;
    while (moves.size() < 34) {
      const std::string id = "s" + std::to_string(rng() % kSites);
      if (!moved.insert(id).second) continue;
      sites[id] = {ux(rng), uy(rng)};
      moves.push_back({id, PointSite{sites[id]}});
    }
    snapshot = Advance(snapshot, std::move(moves), &free_slots);
    RenderStats stats;
    auto f = (*raster)->Apply(*rasterizer_, snapshot, &stats);
    ASSERT_TRUE(f.ok()) << f.status();
    if (round == 0) {
      EXPECT_FALSE(stats.full);
      EXPECT_GT(stats.windows, 0u);
    }
    ExpectEquivalent(**f, sites, "round " + std::to_string(round), /*oracle_stride=*/509);
  }
}

// A long sequence of single and burst updates, compared every 50 steps and at the end.
TEST_F(SceneRasterGLTest, LongUpdateSequencesStayEquivalent) {
  for (RenderMode mode : {RenderMode::kMesh, RenderMode::kExact}) {
    Grid grid{{-1, -1, 1, 1}, 96, 96};
    auto raster = SceneRaster::Create(grid, grid.pixel_size(), mode);
    ASSERT_TRUE(raster.ok());
    std::mt19937_64 rng(mode == RenderMode::kMesh ? 11 : 12);
    std::uniform_real_distribution<double> u(-1.2, 1.2);
    std::map<std::string, Vec2> sites;
    auto snapshot = SiteSnapshot::Empty(1);
    std::vector<uint32_t> free_slots;
    int next = 0;
    std::shared_ptr<const Frame> frame;
    for (int step = 0; step < 400 && !HasFailure(); ++step) {
      std::vector<SiteChange> changes;
      int count = step % 10 == 0 ? 20 : 1;
      for (int c = 0; c < count; ++c) {
        uint64_t what = rng() % 3;
        if (what == 0 || sites.size() < 20) {
          std::string id = "s" + std::to_string(next++);
          sites[id] = {u(rng), u(rng)};
          changes.push_back({id, PointSite{sites[id]}});
        } else {
          auto it = sites.begin();
          std::advance(it, rng() % sites.size());
          std::string id = it->first;
          if (what == 1) {
            sites[id] = {u(rng), u(rng)};
            changes.push_back({id, PointSite{sites[id]}});
          } else {
            sites.erase(id);
            changes.push_back({id, std::nullopt});
          }
        }
      }
      snapshot = Advance(snapshot, std::move(changes), &free_slots);
      auto f = (*raster)->Apply(*rasterizer_, snapshot);
      ASSERT_TRUE(f.ok()) << f.status();
      frame = *f;
      if (step % 50 == 49) ExpectEquivalent(*frame, sites, "step " + std::to_string(step));
    }
  }
}

TEST_F(SceneRasterGLTest, DeletingEverySiteAndStartingAgain) {
  Grid grid{{0, 0, 1, 1}, 64, 64};
  auto raster = SceneRaster::Create(grid, grid.pixel_size());
  ASSERT_TRUE(raster.ok());
  auto snapshot = SiteSnapshot::Empty(1);
  std::vector<uint32_t> free_slots;
  auto apply = [&](std::vector<SiteChange> changes) {
    snapshot = Advance(snapshot, std::move(changes), &free_slots);
    return (*raster)->Apply(*rasterizer_, snapshot);
  };
  auto f = apply({{"a", PointSite{{0.2, 0.2}}}, {"b", PointSite{{0.8, 0.7}}}});
  ASSERT_TRUE(f.ok());
  f = apply({{"a", std::nullopt}, {"b", std::nullopt}});
  ASSERT_TRUE(f.ok());
  EXPECT_TRUE((*f)->empty());
  f = apply({{"c", PointSite{{0.5, 0.5}}}});
  ASSERT_TRUE(f.ok());
  ExpectEquivalent(**f, {{"c", {0.5, 0.5}}}, "after emptying");
}

// A one-site change in a dense scene redraws a small window and shares the other tiles.
TEST_F(SceneRasterGLTest, SmallChangesRedrawSmallWindowsAndShareTiles) {
  Grid grid{{0, 0, 1, 1}, 256, 256};
  auto raster = SceneRaster::Create(grid, grid.pixel_size());
  ASSERT_TRUE(raster.ok());
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<SiteChange> all;
  std::map<std::string, Vec2> sites;
  for (int i = 0; i < 1500; ++i) {
    std::string id = std::to_string(i);
    sites[id] = {u(rng), u(rng)};
    all.push_back({id, PointSite{sites[id]}});
  }
  auto snapshot = SiteSnapshot::Empty(1);
  std::vector<uint32_t> free_slots;
  auto next = [&](std::vector<SiteChange> changes) {
    snapshot = Advance(snapshot, std::move(changes), &free_slots);
    return snapshot;
  };
  auto before = (*raster)->Apply(*rasterizer_, next(all));
  ASSERT_TRUE(before.ok());
  RenderStats stats;
  sites["7"] = {0.25, 0.75};
  auto after = (*raster)->Apply(*rasterizer_, next({{"7", PointSite{sites["7"]}}}), &stats);
  ASSERT_TRUE(after.ok());
  EXPECT_FALSE(stats.full);
  EXPECT_LT(stats.pixels, grid.pixel_count() / 8) << stats.windows << " windows";
  int shared = 0;
  for (uint32_t ty = 0; ty < (*after)->tiles_y(); ++ty) {
    for (uint32_t tx = 0; tx < (*after)->tiles_x(); ++tx) shared += (*after)->SharesTile(**before, tx, ty);
  }
  EXPECT_GE(shared, 48);  // of 64: only the tiles the windows touch are copied
  ExpectEquivalent(**after, sites, "after the move");
  // An addition alone draws only the new site.
  sites["new"] = {0.5, 0.5};
  auto added = (*raster)->Apply(*rasterizer_, next({{"new", PointSite{sites["new"]}}}), &stats);
  ASSERT_TRUE(added.ok());
  EXPECT_EQ(stats.sites_drawn, 1u);
  ExpectEquivalent(**added, sites, "after the addition");
}

// A site dragged about (one site moved again and again, as a UI does) keeps redrawing small
// windows: each move clears only the pixels its last position won, not the coarse tiles its
// placement was bounded by. Every frame still equals a render from scratch.
TEST_F(SceneRasterGLTest, ASiteMovedAgainAndAgainRedrawsSmallWindows) {
  for (RenderMode mode : {RenderMode::kMesh, RenderMode::kExact}) {
    Grid grid{{0, 0, 1, 1}, 128, 128};
    auto raster = SceneRaster::Create(grid, grid.pixel_size(), mode);
    ASSERT_TRUE(raster.ok());
    std::mt19937_64 rng(mode == RenderMode::kMesh ? 21 : 22);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<SiteChange> all;
    std::map<std::string, Vec2> sites;
    for (int i = 0; i < 400; ++i) {
      std::string id = std::to_string(i);
      sites[id] = {u(rng), u(rng)};
      all.push_back({id, PointSite{sites[id]}});
    }
    auto snapshot = SiteSnapshot::Empty(1);
    std::vector<uint32_t> free_slots;
    snapshot = Advance(snapshot, std::move(all), &free_slots);
    ASSERT_TRUE((*raster)->Apply(*rasterizer_, snapshot).ok());
    uint64_t drawn = 0;
    for (int step = 0; step < 30 && !HasFailure(); ++step) {
      sites["7"] = {u(rng), u(rng)};
      snapshot = Advance(snapshot, {{"7", PointSite{sites["7"]}}}, &free_slots);
      RenderStats stats;
      auto f = (*raster)->Apply(*rasterizer_, snapshot, &stats);
      ASSERT_TRUE(f.ok()) << f.status();
      ASSERT_FALSE(stats.full) << Name(mode) << " move " << step << ": " << stats.windows
                               << " windows, " << stats.pixels << " pixels";
      drawn += stats.sites_drawn;
      if (step % 6 == 5) {  // the oracle scans every site at every pixel
        ExpectEquivalent(**f, sites, std::string(Name(mode)) + " move " + std::to_string(step));
      }
    }
    // A site's cell here spans about 41 pixels. Were the old position's window bounded by
    // 32-pixel tiles, the second move would already clear over half the grid and render
    // everything (the assertion above); with it bounded by the pixels won, a move redraws
    // a few dozen sites.
    std::printf("%s: %.1f sites drawn per move\n", Name(mode), drawn / 30.0);
    EXPECT_LT(drawn, 30u * 80) << Name(mode);
  }
}

}  // namespace
}  // namespace gvd
