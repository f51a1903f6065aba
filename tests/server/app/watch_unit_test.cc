// What a WatchScene stream has yet to tell (server/app/watch.h), without a server: frames noted
// between two events merge into the next one, the newest version with every changed window
// joined.
#include "server/app/watch.h"

#include <gtest/gtest.h>

#include <vector>

namespace gvd {
namespace {

class PendingEventTest : public ::testing::Test {
 protected:
  // A frame of `version` made from the last one, `rect` redrawn (the first: whole).
  std::shared_ptr<const Frame> Next(uint64_t version, PixelRect rect, size_t sites = 1) {
    SiteTable table;
    for (size_t i = 0; i < sites; ++i) table.push_back({std::to_string(i), PointSite{{0.1 * i, 0.5}}});
    auto snapshot = SiteSnapshot::Of(version, table);
    last_ = last_ == nullptr
                ? std::make_shared<const Frame>(grid_, 1, ErrorModel{}, ids_.data(), dist_.data(), snapshot)
                : std::make_shared<const Frame>(*last_, ErrorModel{}, rect, ids_.data(), dist_.data(),
                                                snapshot);
    return last_;
  }
  static Window Changed(const v1::WatchSceneResponse& e) {
    return {e.changed().min_x(), e.changed().min_y(), e.changed().max_x(), e.changed().max_y()};
  }

  const Grid grid_{{0, 0, 2, 1}, 64, 32};
  std::vector<uint32_t> ids_ = std::vector<uint32_t>(64 * 32, 1);
  std::vector<float> dist_ = std::vector<float>(64 * 32, 0.25f);
  std::shared_ptr<const Frame> last_;
};

TEST_F(PendingEventTest, FramesBetweenEventsMerge) {
  PendingEvent p(0);
  EXPECT_FALSE(p.ready());
  p.Note(*Next(1, {}), /*whole=*/true);
  ASSERT_TRUE(p.ready());
  v1::WatchSceneResponse e;
  p.Take(grid_, &e);
  EXPECT_EQ(e.version(), 1u);
  EXPECT_EQ(Changed(e).max_x, 2);
  EXPECT_FALSE(p.ready());
  // Three frames before the next event: the newest version, the windows joined.
  const PixelRect a{1, 1, 4, 4}, b{60, 2, 64, 5}, c{30, 20, 31, 32};
  p.Note(*Next(2, a));
  p.Note(*Next(3, b, 3));
  p.Note(*Next(5, c, 2));
  ASSERT_TRUE(p.ready());
  e.Clear();
  p.Take(grid_, &e);
  EXPECT_EQ(e.version(), 5u);
  EXPECT_EQ(e.site_count(), 2u);
  const Window want = grid_.Area(a.Union(b).Union(c));
  EXPECT_EQ(Changed(e).min_x, want.min_x);
  EXPECT_EQ(Changed(e).min_y, want.min_y);
  EXPECT_EQ(Changed(e).max_x, want.max_x);
  EXPECT_EQ(Changed(e).max_y, want.max_y);
  // Older and repeated versions are not news; a frame that changed nothing says so.
  p.Note(*Next(5, a));
  EXPECT_FALSE(p.ready());
  p.Note(*Next(6, {}));
  ASSERT_TRUE(p.ready());
  e.Clear();
  p.Take(grid_, &e);
  EXPECT_EQ(e.version(), 6u);
  EXPECT_FALSE(e.has_changed());
}

TEST_F(PendingEventTest, AStreamAfterAVersionIgnoresWhatCameBefore) {
  PendingEvent p(7);
  p.Note(*Next(7, {}), /*whole=*/true);
  EXPECT_FALSE(p.ready());
  p.Note(*Next(8, {2, 2, 3, 3}));
  ASSERT_TRUE(p.ready());
  v1::WatchSceneResponse e;
  p.Take(grid_, &e);
  EXPECT_EQ(e.version(), 8u);
  EXPECT_EQ(p.sent(), 8u);
}

}  // namespace
}  // namespace gvd
