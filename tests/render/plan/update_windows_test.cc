// update_windows.h. UpdateWindows' windows for placed sites: each the union of the frame's
// tiles where the site can now be best, found by testing every tile, whatever frame values,
// weights and presence make the site's reach; only the tiles near a site are tested now, so a
// reach cut too short leaves out tiles it can win. UpdateCost, the choice between an update's
// windows and a full render, against costs worked out by hand: the static cap before both
// paths are measured, the break-even of the measured costs, updates weighted by their changes,
// old updates fading, and the floor of 64 changes.
#include "render/plan/update_windows.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "render/kernel/exact2.h"
#include "render/scene/frame.h"
#include "render/scene/snapshot.h"
#include "tests/support/pixel_oracle.h"

namespace gvd {
namespace {

// One placed site's window by its definition: every tile of the frame whose pixel centres'
// box lies near enough the site's bounding box for the site's value there, m d + a, to pass
// the tile's greatest stored value (with the frame's slack), and within its presence
// (max_distance and the draw margin). The window is their union, its radius the farthest
// any of them needs (their farthest centre, at most the presence).
struct Expected {
  bool any = false;
  PixelRect rect;
  double radius = -1;
};
Expected EveryTile(const Grid& grid, const Frame& frame, const Site& site) {
  const ErrorModel& err = frame.error();
  const Window b = BoundingBox(site.geometry);
  const double presence = site.max_distance + DrawMargin(grid);
  Expected e;
  for (uint32_t ty = 0; ty < frame.tiles_y(); ++ty) {
    for (uint32_t tx = 0; tx < frame.tiles_x(); ++tx) {
      const PixelRect rect{tx * Frame::kTile, ty * Frame::kTile,
                           std::min((tx + 1) * Frame::kTile, grid.width),
                           std::min((ty + 1) * Frame::kTile, grid.height)};
      const Window box = grid.CentreBox(rect);
      const double near = std::hypot(std::max({0.0, box.min_x - b.max_x, b.min_x - box.max_x}),
                                     std::max({0.0, box.min_y - b.max_y, b.min_y - box.max_y}));
      const double m = frame.tile_max(tx, ty);
      if (site.multiplicative * near + site.additive > m + err.Slack(m) || near > presence) {
        continue;
      }
      e.any = true;
      e.rect = e.rect.Union(rect);
      e.radius = std::max(e.radius,
                          std::min(FarthestDistance(box, site) * (1 + 0x1p-40), presence));
    }
  }
  return e;
}

// Frames whose tiles hold values of very different sizes (most small, as in a crowded scene,
// some tiles of a large empty cell), and sites of every kind with weights that make their
// reach from a few pixels to the whole grid: the window each placed site gets is the one
// testing every tile gives.
TEST(UpdateWindows, PlacedSitesGetEveryTileTheyCanWin) {
  const Grid grid{{0, 0, 1.5, 1}, 400, 250};  // 13 x 8 tiles, the last row and column cut
  const uint32_t tiles_x = (grid.width + Frame::kTile - 1) / Frame::kTile;
  const uint32_t tiles_y = (grid.height + Frame::kTile - 1) / Frame::kTile;
  Generator gen(11);
  int windows = 0, wide = 0, few = 0;
  for (int trial = 0; trial < 60; ++trial) {
    SiteTable sites;
    for (int s = 0; s < 12; ++s) {
      Site& site = sites.emplace_back(Site{std::to_string(s), gen.Kind(s % Generator::kKinds)});
      site.multiplicative = gen.U(0, 1) < 0.5 ? gen.U(0.2, 3) : 1;
      site.additive = gen.U(0, 1) < 0.3 ? gen.U(0, 0.05) : 0;
      if (gen.U(0, 1) < 0.3) site.max_distance = gen.U(0.01, 0.4);
    }
    auto snapshot = SiteSnapshot::Of(1, sites);
    // Each tile's values below a level of its own: 0.002 to 0.02 mostly, up to 0.5 in a few.
    std::vector<double> level(size_t{tiles_x} * tiles_y);
    for (double& l : level) l = gen.U(0, 1) < 0.1 ? gen.U(0.05, 0.5) : gen.U(0.002, 0.02);
    std::vector<uint32_t> ids(grid.pixel_count());
    std::vector<float> values(grid.pixel_count());
    for (uint32_t j = 0; j < grid.height; ++j) {
      for (uint32_t i = 0; i < grid.width; ++i) {
        const size_t k = size_t{j} * grid.width + i;
        ids[k] = 1 + static_cast<uint32_t>(gen.U(0, sites.size()));
        const double top = level[(j / Frame::kTile) * tiles_x + i / Frame::kTile];
        values[k] = static_cast<float>(gen.U(0, top));
      }
    }
    // Slack far beyond a real frame's, so that a reach that leaves it out falls short.
    ErrorModel error;
    error.absolute_slack = gen.U(0, 1) < 0.5 ? gen.U(0, 0.1) : 0;
    error.relative_slack = gen.U(0, 1) < 0.5 ? gen.U(0, 1) : 0;
    const Frame frame(grid, grid.pixel_size(), error, ids.data(), values.data(), snapshot);
    for (uint32_t slot = 0; slot < sites.size(); ++slot) {
      const Site& site = *snapshot->sites().get(slot);
      const Expected want = EveryTile(grid, frame, site);
      const uint32_t placed[] = {slot};
      const std::vector<UpdateWindow> got =
          UpdateWindows(grid, frame, snapshot->sites(), placed, {});
      const std::string what = "trial " + std::to_string(trial) + ", site " + site.id;
      if (!want.any) {
        EXPECT_TRUE(got.empty()) << what;
        continue;
      }
      ASSERT_EQ(got.size(), 1u) << what;
      EXPECT_FALSE(got[0].clear) << what;
      EXPECT_EQ(got[0].rect, want.rect) << what;
      ASSERT_EQ(got[0].added.size(), 1u) << what;
      EXPECT_EQ(got[0].added[0].slot, slot) << what;
      EXPECT_EQ(got[0].added[0].radius, want.radius) << what;
      EXPECT_EQ(got[0].added[0].clip, want.rect) << what;
      ++windows;
      few += want.rect.area() <= 4 * Frame::kTile * Frame::kTile;
      wide += want.rect.width() >= grid.width / 2;
    }
  }
  // The trials reach both ends: windows of a few tiles, and windows across half the grid.
  EXPECT_GE(few, 50);
  EXPECT_GE(wide, 50);
  EXPECT_GE(windows, 300);
}

TEST(UpdateCost, UnmeasuredScenesUseTheCapOfPoints) {
  UpdateCost cost;
  EXPECT_FALSE(cost.FullIsCheaper(64, 10));  // never under 64 changes
  EXPECT_TRUE(cost.FullIsCheaper(65, 10));
  EXPECT_FALSE(cost.FullIsCheaper(195, 100'000));  // 100,000 / 512 = 195
  EXPECT_TRUE(cost.FullIsCheaper(196, 100'000));
  cost.Full(0.2);  // one path measured is not enough
  EXPECT_TRUE(cost.FullIsCheaper(196, 100'000));
}

TEST(UpdateCost, MeasuredCostsMeetWhereWindowsTakeAsLongAsAFullRender) {
  UpdateCost cost;
  cost.Full(0.2);
  cost.Update(64, 0.032);  // 0.5 ms a change: 400 changes take 0.2 s
  EXPECT_FALSE(cost.FullIsCheaper(399, 20'000));
  EXPECT_TRUE(cost.FullIsCheaper(401, 20'000));
  // The cap of points would have sent 65 changes of this scene to a full render.
  EXPECT_FALSE(cost.FullIsCheaper(65, 20'000));
  cost.Full(0.1);  // the last full render is the one that counts
  EXPECT_FALSE(cost.FullIsCheaper(199, 20'000));
  EXPECT_TRUE(cost.FullIsCheaper(201, 20'000));
}

TEST(UpdateCost, UpdatesCountByTheirChangesAndOldOnesFade) {
  UpdateCost cost;
  cost.Full(0.2);
  cost.Update(64, 0.032);
  // A one-move update carries the fixed part of a render: 2 ms a change here. Halved, the
  // first counts 32 changes and 16 ms: 20 ms for 34 changes, 340 changes to 0.2 s.
  cost.Update(2, 0.004);
  EXPECT_FALSE(cost.FullIsCheaper(340, 20'000));
  EXPECT_TRUE(cost.FullIsCheaper(341, 20'000));
  // Updates at 1 ms a change: the 0.5 ms of the first ones fades to nothing.
  for (int k = 0; k < 30; ++k) cost.Update(100, 0.1);
  EXPECT_FALSE(cost.FullIsCheaper(199, 20'000));
  EXPECT_TRUE(cost.FullIsCheaper(201, 20'000));
}

TEST(UpdateCost, SlowUpdatesNeverSendFewerThan64ChangesToAFullRender) {
  UpdateCost cost;
  cost.Full(0.001);
  cost.Update(4, 0.04);  // 10 ms a change against a full render of 1 ms
  EXPECT_FALSE(cost.FullIsCheaper(64, 1'000'000));
  EXPECT_TRUE(cost.FullIsCheaper(65, 1'000'000));
}

}  // namespace
}  // namespace gvd
