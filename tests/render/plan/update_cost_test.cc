// The choice between an update's windows and a full render (UpdateCost), against costs worked
// out by hand: the static cap before both paths are measured, the break-even of the measured
// costs, updates weighted by their changes, old updates fading, and the floor of 64 changes.
#include <gtest/gtest.h>

#include "render/plan/update_windows.h"

namespace gvd {
namespace {

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
