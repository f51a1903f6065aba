// The process's CPU pool: ParallelFor's pieces, lanes' priorities and limits.
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <chrono>
#include <future>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include <set>

#include <gtest/gtest.h>

#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

// Every index once, whatever n and the piece size, and from inside pool jobs too.
TEST(CpuPool, ParallelForCoversEachIndexOnce) {
  for (size_t n : {0, 1, 7, 100, 1000, 4097, 100000}) {
    for (size_t min : {1, 3, 64, 10000}) {
      std::vector<std::atomic<int>> hits(n);
      ParallelFor(n, min, [&](size_t b, size_t e) {
        ASSERT_LE(b, e);
        ASSERT_LE(e, n);
        for (size_t i = b; i < e; ++i) hits[i]++;
      });
      for (size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << n << " " << min << " " << i;
    }
  }
  // Nested: every piece of the outer loop runs an inner loop; nothing waits for a free thread.
  std::atomic<size_t> total{0};
  ParallelFor(64, 1, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) {
      ParallelFor(1000, 10, [&](size_t ib, size_t ie) { total += ie - ib; });
    }
  });
  EXPECT_EQ(total.load(), 64u * 1000u);
}

// A latch: jobs wait on it until the test opens it.
struct Gate {
  std::promise<void> open;
  std::shared_future<void> opened = open.get_future().share();
};

TEST(CpuPool, HigherLanesGoFirst) {
  CpuPool pool(1);
  std::mutex mu;
  std::vector<std::string> order;
  auto record = [&](std::string what) {
    return [&, what] {
      std::lock_guard<std::mutex> lock(mu);
      order.push_back(what);
    };
  };
  // Declared before the lanes, so that the lanes' destructors (which wait for their jobs)
  // run before these go.
  Gate gate;
  std::promise<void> started;
  {
    CpuPool::Lane low(pool, 0, 8, 8), high(pool, 5, 8, 8);
    EXPECT_TRUE(low.Submit([&] {
      started.set_value();
      gate.opened.wait();
    }));
    // The only thread is busy: what follows queues. (EXPECT, not ASSERT, until the gate
    // opens: a return would leave the lanes waiting for a job that waits for the gate.)
    EXPECT_EQ(started.get_future().wait_for(std::chrono::seconds(30)), std::future_status::ready);
    EXPECT_TRUE(low.Submit(record("low 1")));
    EXPECT_TRUE(low.Submit(record("low 2")));
    EXPECT_TRUE(high.Submit(record("high 1")));
    EXPECT_TRUE(high.Submit(record("high 2")));
    gate.open.set_value();
  }  // the lanes' destructors wait for their jobs
  EXPECT_EQ(order, (std::vector<std::string>{"high 1", "high 2", "low 1", "low 2"}));
}

TEST(CpuPool, LanesKeepTheirLimits) {
  CpuPool pool(4);
  // Declared before the lanes, whose destructors wait for the jobs that use them.
  Gate gate;
  std::promise<void> ran;
  std::atomic<int> running{0}, most{0}, done{0};
  CpuPool::Lane capped(pool, 0, /*max_running=*/2, /*max_queued=*/3);
  CpuPool::Lane other(pool, 0, 8, 8);
  auto job = [&] {
    int now = ++running;
    int seen = most.load();
    while (now > seen && !most.compare_exchange_weak(seen, now)) {
    }
    gate.opened.wait();
    --running;
    ++done;
  };
  // Two run, three wait; the sixth is refused.
  int accepted = capped.Submit(job) + capped.Submit(job);
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (running.load() < 2 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::yield();
  }
  for (int i = 0; i < 4; ++i) accepted += capped.Submit(job);
  EXPECT_EQ(accepted, 5);
  // The lane at its limit leaves the other threads to other lanes.
  EXPECT_TRUE(other.Submit([&] { ran.set_value(); }));
  EXPECT_EQ(ran.get_future().wait_for(std::chrono::seconds(30)), std::future_status::ready);
  gate.open.set_value();
  while (done.load() < 5 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::yield();
  }
  EXPECT_EQ(done.load(), 5);
  EXPECT_EQ(most.load(), 2);
}

// The nice value of each thread that ran a piece of a ParallelFor called on this thread. Each
// piece waits (up to 30 s) until a second thread has run one, so a pool thread always does.
std::map<pid_t, int> NiceOfPieces() {
  std::mutex mu;
  std::condition_variable joined;
  std::map<pid_t, int> nice;
  ParallelFor(64, 1, [&](size_t, size_t) {
    std::unique_lock<std::mutex> lock(mu);
    errno = 0;
    nice[gettid()] = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
    joined.notify_all();
    joined.wait_for(lock, std::chrono::seconds(30), [&] { return nice.size() >= 2; });
  });
  return nice;
}

// A render thread's ParallelFor pieces run at its lower priority, on threads of their own; any
// other thread's, at the process's.
TEST(CpuPool, ARenderThreadsPiecesRunAtItsPriority) {
  const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
  if (base >= kRenderNice) GTEST_SKIP() << "the test runs at nice " << base << " already";
  if (CpuPool::Process().threads() < 2) GTEST_SKIP() << "one core: ParallelFor runs inline";
  const std::map<pid_t, int> plain = NiceOfPieces();
  std::map<pid_t, int> render;
  std::thread([&] {
    CpuPool::BecomeRenderThread();
    render = NiceOfPieces();
  }).join();
  ASSERT_GE(plain.size(), 2u);
  ASSERT_GE(render.size(), 2u);
  for (const auto& [tid, nice] : plain) EXPECT_EQ(nice, base) << "thread " << tid;
  for (const auto& [tid, nice] : render) EXPECT_EQ(nice, kRenderNice) << "thread " << tid;
  // The render's helpers are not the process pool's threads.
  for (const auto& [tid, nice] : render) EXPECT_EQ(plain.count(tid), 0u) << "thread " << tid;
}

}  // namespace
}  // namespace gvd
