// The process's CPU pool: ParallelFor's pieces, lanes' priorities and limits, and how render
// threads are scheduled.
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <chrono>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <set>

#include <gtest/gtest.h>

#include "render/scene/cpu_pool.h"
#include "render/scene/renderer.h"

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

TEST(CpuPool, AnIdleLaneRunsAJobOnTheCallingThread) {
  CpuPool pool(2);
  Gate gate;
  std::promise<void> started;
  std::atomic<int> done{0};
  CpuPool::Lane lane(pool, 0, /*max_running=*/1, /*max_queued=*/8);
  // Idle: the job runs here, before the call returns.
  const std::thread::id here = std::this_thread::get_id();
  std::thread::id ran_on;
  EXPECT_TRUE(lane.RunHereIfIdle([&] { ran_on = std::this_thread::get_id(); }));
  EXPECT_EQ(ran_on, here);
  // A job running on the lane: refused, not run.
  EXPECT_TRUE(lane.Submit([&] {
    started.set_value();
    gate.opened.wait();
    ++done;
  }));
  started.get_future().wait();
  bool ran = false;
  EXPECT_FALSE(lane.RunHereIfIdle([&] { ran = true; }));
  // A job waiting: refused too.
  EXPECT_TRUE(lane.Submit([&] { ++done; }));
  EXPECT_FALSE(lane.RunHereIfIdle([&] { ran = true; }));
  EXPECT_FALSE(ran);
  gate.open.set_value();
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (done.load() < 2 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::yield();
  }
  EXPECT_EQ(done.load(), 2);
  // One running here counts against the lane's limit: what is submitted meanwhile waits
  // for it, then runs.
  std::promise<void> inside;
  std::atomic<bool> here_done{false}, after_here{false};
  std::thread caller([&] {
    EXPECT_TRUE(lane.RunHereIfIdle([&] {
      inside.set_value();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      here_done = true;
    }));
  });
  inside.get_future().wait();
  EXPECT_TRUE(lane.Submit([&] { after_here = here_done.load(); ++done; }));
  caller.join();
  while (done.load() < 3 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::yield();
  }
  EXPECT_EQ(done.load(), 3);
  EXPECT_TRUE(after_here.load());
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

// How a thread is scheduled: its policy (SCHED_OTHER, SCHED_IDLE) and nice value, read from
// the kernel.
struct Scheduled {
  int policy;
  int nice;
  bool operator==(const Scheduled& o) const { return policy == o.policy && nice == o.nice; }
};
std::ostream& operator<<(std::ostream& os, const Scheduled& s) {
  return os << (s.policy == SCHED_IDLE ? "SCHED_IDLE" : s.policy == SCHED_OTHER ? "SCHED_OTHER" : "?")
            << " nice " << s.nice;
}
Scheduled SchedulingOf(pid_t tid) {
  errno = 0;
  return {sched_getscheduler(tid), getpriority(PRIO_PROCESS, static_cast<id_t>(tid))};
}

// The render thread and the threads its ParallelFor pieces ran on.
std::map<pid_t, Scheduled> RenderThreadsNow(pid_t render) {
  std::map<pid_t, Scheduled> out{{render, SchedulingOf(render)}};
  for (const auto& [tid, nice] : NiceOfPieces()) out[tid] = SchedulingOf(tid);
  return out;
}

// While nobody waits for a render, render threads and their pieces' threads run in the
// background; while a caller holds a RenderWait (a frame's waiter, a zoom), at kRenderNice;
// and in the background again once the last one is gone.
TEST(CpuPool, RenderThreadsRunInTheBackgroundWhileNoCallerWaits) {
  if (!RenderWait::Background()) {
    GTEST_SKIP() << "this process may not leave SCHED_IDLE (neither CAP_SYS_NICE nor an "
                    "RLIMIT_NICE of 20 - kRenderNice): renders stay at kRenderNice";
  }
  if (CpuPool::Process().threads() < 2) GTEST_SKIP() << "one core: ParallelFor runs inline";
  ASSERT_EQ(RenderWait::held(), 0);
  const Scheduled background{SCHED_IDLE, kRenderNice}, raised{SCHED_OTHER, kRenderNice};
  std::map<pid_t, Scheduled> idle, waited, two, again;
  std::thread([&] {
    CpuPool::BecomeRenderThread();
    CpuPool::RenderInBackground();
    const pid_t self = gettid();
    idle = RenderThreadsNow(self);
    {
      RenderWait wait;
      waited = RenderThreadsNow(self);
      RenderWait second;
      {
        RenderWait moved(std::move(wait));  // the count moves with it
      }
      two = RenderThreadsNow(self);
      EXPECT_EQ(RenderWait::held(), 1);
    }
    again = RenderThreadsNow(self);
  }).join();
  ASSERT_GE(idle.size(), 2u);  // the render thread and a pool thread that took pieces
  for (const auto& [tid, s] : idle) EXPECT_EQ(s, background) << "thread " << tid;
  for (const auto& [tid, s] : waited) EXPECT_EQ(s, raised) << "thread " << tid;
  for (const auto& [tid, s] : two) EXPECT_EQ(s, raised) << "thread " << tid;
  for (const auto& [tid, s] : again) EXPECT_EQ(s, background) << "thread " << tid;
  EXPECT_EQ(RenderWait::held(), 0);
}

// Polls the render thread `tid` until it is scheduled as `want`; when that happened, or
// nullopt after a minute.
std::optional<std::chrono::steady_clock::time_point> WhenScheduled(pid_t tid, Scheduled want) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(1);
  while (std::chrono::steady_clock::now() < give_up) {
    if (SchedulingOf(tid) == want) return std::chrono::steady_clock::now();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return std::nullopt;
}

// A render nobody waits for stays in the background while it is due for less than
// kBackgroundLag; after that the render threads run at kRenderNice until it is done, so that
// another busy process cannot hold it back without bound.
TEST(CpuPool, ARenderDueTooLongIsRaised) {
  if (!RenderWait::Background()) {
    GTEST_SKIP() << "this process may not leave SCHED_IDLE (neither CAP_SYS_NICE nor an "
                    "RLIMIT_NICE of 20 - kRenderNice): renders stay at kRenderNice";
  }
  ASSERT_EQ(RenderWait::held(), 0);
  ASSERT_EQ(RenderDue::due(), 0);
  const Scheduled background{SCHED_IDLE, kRenderNice}, raised{SCHED_OTHER, kRenderNice};
  std::promise<pid_t> tid;
  std::promise<void> finished;
  std::thread render([&] {
    CpuPool::BecomeRenderThread();
    CpuPool::RenderInBackground();
    tid.set_value(gettid());
    finished.get_future().wait();
  });
  const pid_t thread = tid.get_future().get();
  EXPECT_EQ(SchedulingOf(thread), background);
  for (int round = 0; round < 2; ++round) {  // the second once the first is over
    // Read before the render comes due, so that the lag is measured from no later than the
    // time the render takes for its own.
    const auto due = std::chrono::steady_clock::now();
    std::optional<RenderDue> first(std::in_place);
    const Scheduled soon = SchedulingOf(thread);
    // Seen before the lag ran out, it is still in the background.
    if (std::chrono::steady_clock::now() - due < kBackgroundLag / 2) {
      EXPECT_EQ(soon, background);
    }
    std::optional<RenderDue> second(std::in_place);  // a later render changes nothing
    EXPECT_EQ(RenderDue::due(), 2);
    const auto up = WhenScheduled(thread, raised);
    ASSERT_TRUE(up.has_value()) << "round " << round << ": not raised in a minute";
    EXPECT_GE(*up - due, kBackgroundLag) << "round " << round;
    // Raised for lateness, which is no caller's wait (RenderLoop's rests go on).
    EXPECT_EQ(RenderWait::held(), 1);
    EXPECT_EQ(RenderWait::callers(), 0);
    first.reset();  // the second is late too: still raised
    EXPECT_EQ(SchedulingOf(thread), raised);
    second.reset();  // none due: lowered again
    EXPECT_EQ(RenderDue::due(), 0);
    ASSERT_TRUE(WhenScheduled(thread, background).has_value()) << "round " << round
                                                               << ": not lowered in a minute";
    EXPECT_EQ(RenderWait::held(), 0);
  }
  finished.set_value();
  render.join();
}

// A renderer's queue holds a scene's render due from its queueing until the render that took
// it is done, and a render taken back stays due.
TEST(CpuPool, ADirtyQueueHoldsARenderDueUntilItIsDone) {
  if (!RenderWait::Background()) GTEST_SKIP() << "renders never go to the background here";
  struct Fake {};
  auto a = std::make_shared<Fake>(), b = std::make_shared<Fake>();
  DirtyQueue<Fake> queue;
  ASSERT_EQ(RenderDue::due(), 0);
  EXPECT_TRUE(queue.Push(a));
  EXPECT_FALSE(queue.Push(a));
  EXPECT_TRUE(queue.Push(b));
  EXPECT_EQ(RenderDue::due(), 2);
  auto taken = queue.TakeFirst([](const Fake*) { return true; });
  ASSERT_EQ(taken, a);
  EXPECT_EQ(RenderDue::due(), 2);  // taken, not yet rendered
  EXPECT_TRUE(queue.Push(a));      // changed while it renders: due again
  EXPECT_EQ(RenderDue::due(), 3);
  queue.Rendered(a.get());
  EXPECT_EQ(RenderDue::due(), 2);
  taken = queue.TakeFirst([&](const Fake* s) { return s == b.get(); });
  ASSERT_EQ(taken, b);
  queue.PushFront(b);  // taken back: due still, once
  EXPECT_EQ(RenderDue::due(), 2);
  queue.Rendered(b.get());  // nothing of b's was taken now
  EXPECT_EQ(RenderDue::due(), 2);
  EXPECT_EQ(queue.TakeAll().size(), 2u);
  EXPECT_EQ(RenderDue::due(), 0);
}

}  // namespace
}  // namespace gvd
