// The memory budget's parts: sizes as flags give them, the default from a cgroup, and
// reservations that never pass the limit, also from many threads.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <random>
#include <thread>
#include <vector>

#include "server/app/memory.h"

namespace gvd {
namespace {

TEST(MemoryBudgetUnit, SizesParseAsPeopleWriteThem) {
  EXPECT_EQ(ParseBytes("1073741824"), uint64_t{1} << 30);
  EXPECT_EQ(ParseBytes("4G"), uint64_t{4} << 30);
  EXPECT_EQ(ParseBytes("4GiB"), uint64_t{4} << 30);
  EXPECT_EQ(ParseBytes("4GB"), uint64_t{4} << 30);
  EXPECT_EQ(ParseBytes("512M"), uint64_t{512} << 20);
  EXPECT_EQ(ParseBytes("64k"), uint64_t{64} << 10);
  EXPECT_EQ(ParseBytes("64K"), uint64_t{64} << 10);
  EXPECT_EQ(ParseBytes("1.5G"), uint64_t{3} << 29);
  EXPECT_EQ(ParseBytes("2T"), uint64_t{2} << 40);
  for (const char* bad : {"", "0", "0.4", "G", "-1", "4X", "4Gx", "4 G", "1e3", "..", "99999999999T"}) {
    EXPECT_EQ(ParseBytes(bad), std::nullopt) << bad;
  }
}

class CgroupTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char dir_template[] = "/tmp/gvd-cgroup-XXXXXX";
    root_ = mkdtemp(dir_template);
  }
  void TearDown() override { std::system(("rm -rf " + root_).c_str()); }
  void Write(const std::string& path, const std::string& text) {
    std::system(("mkdir -p $(dirname " + root_ + path + ")").c_str());
    std::ofstream(root_ + path) << text;
  }
  std::string root_;
};

TEST_F(CgroupTest, DefaultIsThreeQuartersOfTheCgroupLimit) {
  std::string source;
  Write("/memory.max", "4294967296\n");
  EXPECT_EQ(DefaultMaxMemory(root_, &source), uint64_t{3} << 30);
  EXPECT_EQ(source, "cgroup");
  // cgroup v1 beside it: the smaller limit holds.
  Write("/memory/memory.limit_in_bytes", "2147483648\n");
  EXPECT_EQ(DefaultMaxMemory(root_, &source), uint64_t{3} << 29);
}

TEST_F(CgroupTest, WithoutALimitThePhysicalMemory) {
  std::string source;
  Write("/memory.max", "max\n");
  Write("/memory/memory.limit_in_bytes", "9223372036854771712\n");  // v1's "no limit"
  const uint64_t physical = uint64_t(sysconf(_SC_PHYS_PAGES)) * uint64_t(sysconf(_SC_PAGE_SIZE));
  EXPECT_EQ(DefaultMaxMemory(root_, &source), physical / 4 * 3);
  EXPECT_EQ(source, "physical memory");
  EXPECT_EQ(DefaultMaxMemory(root_ + "/nowhere", &source), physical / 4 * 3);
}

TEST(MemoryBudgetUnit, ReservationsStopAtTheLimit) {
  uint64_t in_scenes = 600;
  MemoryBudget budget(1000, [&] { return in_scenes; });
  EXPECT_TRUE(budget.Reserve(400, "x").ok());
  EXPECT_EQ(budget.used(), 1000u);
  absl::Status refused = budget.Reserve(1, "one more site");
  EXPECT_EQ(refused.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(refused.message(),
            "one more site needs 1 bytes; the memory budget (--max-memory) is 1000 bytes, of "
            "which 1000 bytes is in use");
  budget.Release(400);
  in_scenes = 1000;  // the change published: the scene holds the bytes now
  EXPECT_FALSE(budget.Reserve(1, "x").ok());
  in_scenes = 0;
  EXPECT_TRUE(budget.Reserve(1000, "x").ok());
  EXPECT_FALSE(budget.Reserve(UINT64_MAX, "x").ok());  // no overflow past the limit
  { MemoryBudget::Reservation r(&budget, 1000); }
  EXPECT_EQ(budget.used(), 0u);
}

// Many threads reserving and releasing, each holding several reservations at a time: what
// is reserved at once never passes the limit, and everything is given back.
TEST(MemoryBudgetUnit, ConcurrentReservationsNeverPassTheLimit) {
  constexpr uint64_t kLimit = 10000;
  MemoryBudget budget(kLimit, [] { return uint64_t{0}; });
  std::atomic<uint64_t> held{0}, worst{0};
  std::atomic<int> granted{0}, refused{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      std::mt19937_64 rng(t);
      std::uniform_int_distribution<uint64_t> size(1, 3000);
      std::vector<uint64_t> mine;
      for (int k = 0; k < 4000; ++k) {
        if (mine.size() < 6 && rng() % 3 != 0) {
          const uint64_t bytes = size(rng);
          if (!budget.Reserve(bytes, "x").ok()) {
            ++refused;
            continue;
          }
          ++granted;
          const uint64_t now = held += bytes;
          uint64_t w = worst.load();
          while (now > w && !worst.compare_exchange_weak(w, now)) {
          }
          mine.push_back(bytes);
        } else if (!mine.empty()) {
          held -= mine.back();
          budget.Release(mine.back());
          mine.pop_back();
        }
      }
      for (uint64_t bytes : mine) {
        held -= bytes;
        budget.Release(bytes);
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_LE(worst.load(), kLimit);
  EXPECT_GT(granted.load(), 1000);
  EXPECT_GT(refused.load(), 0);  // six of up to 3,000 bytes pass 10,000 even on one thread
  EXPECT_EQ(budget.used(), 0u);
}

}  // namespace
}  // namespace gvd
