// The computed full render's CPU half, with no GL: the candidate lists of the coverage proof
// (TileCandidates) scanned in native code (ScanTiles) must give every pixel centre the site
// the double-precision oracle finds best there, within the frame's own error model
// (ErrorTally), for every site kind, weights, max_distance, sides, ties and sites outside
// the window.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "render/plan/error_tally.h"
#include "render/plan/scan.h"
#include "render/plan/site_shape.h"
#include "render/plan/tile_lists.h"
#include "render/plan/update_windows.h"
#include "render/scene/frame.h"
#include "render/scene/snapshot.h"
#include "tests/support/oracle.h"
#include "tests/support/pixel_oracle.h"

namespace gvd {
namespace {

// The frame the scan gives for `snapshot` on `grid`, its error model as a computed render's;
// `params` gets the render's.
std::shared_ptr<const Frame> Scan(const Grid& grid, std::shared_ptr<const SiteSnapshot> snapshot,
                                  DrawParams* params) {
  const SlotTable& slots = snapshot->sites();
  TileLists lists;
  Coverage cov = TileCandidates(grid, slots, snapshot->index(), &lists);
  *params = {grid.pixel_size(), RenderMode::kExact, Diagram::kNearest, 1};
  ErrorTally tally;
  std::vector<SiteDraw> draws;
  double max_value = 0;
  for (uint32_t s = 0; s < slots.size(); ++s) {
    if (slots.get(s) == nullptr) continue;
    tally.Live(*slots.get(s));
    if (cov.radius[s] < 0) continue;
    const SiteDraw& d = draws.emplace_back(SiteDraw{s, cov.radius[s], cov.clip[s]});
    const SiteShape shape = ShapeOf(grid, *params, *slots.get(s), d);
    tally.Drawn(grid, *slots.get(s), shape);
    max_value = std::max(max_value, shape.max_value);
  }
  params->depth_scale = std::max(2 * max_value, 4 * grid.window.diagonal());
  IndexByDraw(draws, slots.size(), &lists);
  std::vector<uint32_t> ids;
  std::vector<float> values;
  ScanTiles(grid, grid.all(), lists, ScanSitesOf(grid, *params, slots, draws),
            static_cast<float>(params->depth_scale), &ids, &values);
  return std::make_shared<const Frame>(grid, params->eps, tally.Model(grid, *params), ids.data(),
                                       values.data(), snapshot);
}

std::shared_ptr<const Frame> Scan(const Grid& grid, const SiteTable& sites) {
  DrawParams params;
  return Scan(grid, SiteSnapshot::Of(1, sites), &params);
}

// Sites: ten of one kind (or of every kind, kind Generator::kKinds) around the unit window, some weighted,
// some with a max_distance, and three points so that one-sided polygons leave something
// elsewhere.
SiteTable RandomSites(uint64_t seed, int kind) {
  Generator gen(seed);
  SiteTable sites;
  for (int s = 0; s < 10; ++s) {
    Site& site = sites.emplace_back(Site{std::to_string(s), gen.Kind(kind == Generator::kKinds ? s % Generator::kKinds : kind)});
    if (gen.U(0, 1) < 0.3) site.multiplicative = gen.U(0.5, 3);
    if (gen.U(0, 1) < 0.3) site.additive = gen.U(0, 0.2);
    if (gen.U(0, 1) < 0.2) site.max_distance = gen.U(0.05, 0.5);
  }
  for (int s = 0; s < 3; ++s) sites.push_back({"p" + std::to_string(s), gen.Kind(0)});
  return sites;
}

// Pixels that are not square, and a grid that is not a multiple of the scan's tiles.
const Grid kGrid{{0, 0, 1, 1}, 90, 61};

TEST(ScanTest, EveryKindAgainstTheOracle) {
  for (int kind = 0; kind <= Generator::kKinds; ++kind) {
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      const SiteTable sites = RandomSites(seed * 100 + kind, kind);
      auto frame = Scan(kGrid, sites);
      CheckEveryPixel(*frame, sites,
                      "kind " + std::to_string(kind) + " seed " + std::to_string(seed));
    }
  }
}

TEST(ScanTest, TiesAndCoincidentSites) {
  // Sites: (0.25, 0.5) twice, (0.75, 0.5), and a segment on the bisector x = 0.5 of the
  // first two points, so that whole columns of pixel centres are ties.
  SiteTable sites = {{"a", PointSite{{0.25, 0.5}}},
                     {"b", PointSite{{0.25, 0.5}}},
                     {"c", PointSite{{0.75, 0.5}}},
                     {"d", SegmentSite{{0.5, 0.1}, {0.5, 0.9}}}};
  const Grid grid{{0, 0, 1, 1}, 64, 64};
  auto frame = Scan(grid, sites);
  CheckEveryPixel(*frame, sites, "ties");
  // Of two coincident points, the lower slot wins every pixel (the scan's tie rule).
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) EXPECT_NE(frame->id_at(i, j), 2u) << i << "," << j;
  }
}

TEST(ScanTest, PointScenesThroughTheirUniformGrid) {
  // Plain points only (PointCover's lists): random ones, some outside the window, points on
  // the pixel-centre lattice (ties along whole rows and columns), and each of some points
  // twice.
  Generator gen(21);
  SiteTable sites;
  for (int k = 0; k < 1500; ++k) {
    sites.push_back({"r" + std::to_string(k), PointSite{{gen.U(-0.1, 1.1), gen.U(-0.1, 1.1)}}});
  }
  // On pixel centres 8 pixels apart: their bisectors run through pixel centres.
  for (int k = 0; k < 40; ++k) {
    const Vec2 p{(8 * (k % 8) + 0.5) / 96, (8 * (k / 8) + 0.5) / 80};
    sites.push_back({"l" + std::to_string(k), PointSite{p}});
  }
  for (int k = 0; k < 300; ++k) {
    const Site copy{"c" + std::to_string(k), sites[k * 5].geometry};
    sites.push_back(copy);
  }
  const Grid grid{{0, 0, 1, 1}, 96, 80};
  auto frame = Scan(grid, sites);
  CheckEveryPixel(*frame, sites, "points");
  // Of two coincident points, the lower slot wins every pixel (the scan's tie rule).
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      const uint32_t id = frame->id_at(i, j);
      EXPECT_FALSE(id > 1540 && id <= 1840) << "the copy " << id - 1 << " at " << i << "," << j;
    }
  }
}

TEST(ScanTest, SitesOutsideTheWindowAndHugeWeights) {
  // Sites: points and a polyline far outside the window, a point with a huge additive
  // weight inside it, and one with a huge multiplicative weight.
  SiteTable sites = {{"far", PointSite{{-30, 40}}},
                     {"line", PolylineSite{{{2, -3}, {5, 1}, {9, 9}}}},
                     {"heavy", PointSite{{0.5, 0.5}}, 1e6, 1},
                     {"steep", PointSite{{0.3, 0.7}}, 0, 1e6},
                     {"near", PointSite{{1.2, 0.4}}}};
  const Grid grid{{0, 0, 1, 1}, 40, 40};
  auto frame = Scan(grid, sites);
  CheckEveryPixel(*frame, sites, "outside and huge weights");
}

// An incremental render's windows scanned on the CPU, as SceneRaster computes them on a
// software device: after additions alone (windows the new sites are drawn over:
// AddedCandidates, OverFrame), then moves, a deletion and additions (windows cleared and
// computed again: WindowCandidates) of every kind, the frame holds against the oracle at
// every pixel.
TEST(ScanTest, UpdatedWindowsAgainstTheOracle) {
  int cleared = 0, drawn_over = 0;
  for (int kind = 0; kind <= Generator::kKinds; ++kind) {
    const std::string what = "kind " + std::to_string(kind);
    Generator gen(1000 + kind);
    const SiteTable sites = RandomSites(300 + kind, kind);
    auto snapshot = SiteSnapshot::Of(1, sites);
    DrawParams params;
    std::shared_ptr<const Frame> frame = Scan(kGrid, snapshot, &params);
    std::vector<uint32_t> free_slots;
    auto update = [&](std::vector<SiteChange> changes, const std::string& when) {
      auto after = Advance(snapshot, std::move(changes), &free_slots);
      const SlotTable& slots = after->sites();
      // The old pixels of what moved or went: there, the frame must be computed again.
      std::vector<uint32_t> placed;
      std::vector<bool> changed(slots.size(), false);
      SlotTable::Diff(snapshot->sites(), slots, [&](uint32_t s, const Site*, const Site* now) {
        changed[s] = true;
        if (now) placed.push_back(s);
      });
      PixelRect old_pixels;
      for (uint32_t j = 0; j < kGrid.height; ++j) {
        for (uint32_t i = 0; i < kGrid.width; ++i) {
          const uint32_t id = frame->id_at(i, j);
          if (id != 0 && changed[id - 1]) old_pixels = old_pixels.Union({i, j, i + 1, j + 1});
        }
      }
      std::vector<PixelRect> dirty;
      if (!old_pixels.empty()) dirty.push_back(old_pixels);
      DrawParams scratch;  // the frame keeps the first render's depth scale, as SceneRaster does
      const ErrorModel error = Scan(kGrid, after, &scratch)->error();
      for (UpdateWindow& w : UpdateWindows(kGrid, *frame, slots, placed, dirty)) {
        TileLists lists;
        std::vector<SiteDraw> draws;
        if (w.clear) {
          draws = WindowCandidates(kGrid, slots, after->index(), w.rect, &lists);
          ++cleared;
        } else {
          draws = std::move(w.added);
          lists = AddedCandidates(kGrid, slots, *frame, w.rect, draws);
          ++drawn_over;
        }
        std::vector<uint32_t> ids;
        std::vector<float> values;
        ScanTiles(kGrid, w.rect, lists, ScanSitesOf(kGrid, params, slots, draws),
                  static_cast<float>(params.depth_scale), &ids, &values);
        if (!w.clear) OverFrame(*frame, w.rect, &ids, &values);
        frame = std::make_shared<const Frame>(*frame, error, w.rect, ids.data(),
                                              values.data(), after);
      }
      snapshot = after;
      CheckEveryPixel(*frame, OracleSites(slots), what + ", " + when);
    };
    auto geometry = [&] {
      return gen.Kind(kind == Generator::kKinds ? int(gen.U(0, Generator::kKinds)) : kind);
    };
    update({{"new1", geometry()}, {"new2", geometry()}}, "after additions");
    update({{sites[1].id, geometry()},
            {sites[4].id, geometry()},
            {sites[7].id, std::nullopt},
            {"new3", geometry()}},
           "after moves");
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GE(cleared, Generator::kKinds);
  EXPECT_GE(drawn_over, Generator::kKinds);
}

}  // namespace
}  // namespace gvd
