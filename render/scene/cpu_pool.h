// The process's CPU pools: one thread per core for the computation that is neither a render
// thread's nor a transport's (answers, image encoding, analyses, and the pieces of
// ParallelFor), so that the process runs as many busy threads as it has cores, whatever the
// load; and as many again for the pieces of renders, at the render threads' lower priority.
// And that priority: renders run in the background unless a caller waits for one, or one has
// waited there too long.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace gvd {

// The nice value of render threads and of the pool that runs their ParallelFor pieces (Linux
// sets it per thread) while they run in the foreground (RenderWait): below calls, and still
// with a share of the cores when calls keep them busy.
inline constexpr int kRenderNice = 10;

// How render threads (BecomeRenderThread's) and the render pool's threads are scheduled.
// While no caller waits for a render, they run in the background (SCHED_IDLE): a call's
// thread takes a core from them at once, where at kRenderNice it could wait for a render's
// time slice to end, and reads of versions not yet drawn need no render (the index answers
// them). While a caller waits (a RenderWait is held: a frame's waiter, a zoom), every one of
// them runs at kRenderNice, so that the render it waits for keeps its share of the cores
// under load. A render nobody waits for is raised too once it has been due for
// kBackgroundLag (RenderDue): the background yields to every other task of the process's
// scheduling group (its session's, or its cgroup's: the scheduler shares the cores between
// groups first, as equals whatever their threads' policies), and another busy process must
// not hold a frame back without bound. A process that may not leave SCHED_IDLE again (it has
// neither CAP_SYS_NICE nor an RLIMIT_NICE of at least 20 - kRenderNice) keeps them at
// kRenderNice throughout.
class RenderWait {
 public:
  RenderWait();   // one more caller waits: the first raises the render threads
  ~RenderWait();  // the last one gone lowers them again
  RenderWait(RenderWait&& other) noexcept;
  RenderWait& operator=(RenderWait&& other) noexcept;
  RenderWait(const RenderWait&) = delete;
  RenderWait& operator=(const RenderWait&) = delete;

  // Whether renders go to the background when nobody waits (the process may leave
  // SCHED_IDLE again); tried once, on a thread of its own.
  static bool Background();
  // The RenderWaits held now.
  static int held();
  // Those of callers: held() but RenderDue's raise of a late render.
  static int callers();
  // Calls `wake` whenever a caller begins to wait while none did (callers() 0 to 1), on
  // that caller's thread, under no lock of this class's: a renderer that holds back
  // renders nobody waits for (RenderLoop) hears that one is now awaited. Until the token
  // returned is passed to StopWaking, which returns once no call of `wake` is under way.
  static uint64_t WakeOnCaller(std::function<void()> wake);
  static void StopWaking(uint64_t token);

  // RenderDue's raise of a late render, which is no caller's: it raises the render threads
  // but is not counted in callers().
  struct Late {};
  explicit RenderWait(Late);

 private:
  bool held_ = true;
  bool caller_ = true;
};

// How long a render may be due in the background before the render threads run at
// kRenderNice for it, as if a caller waited: what a frame nobody waits for may lag behind its
// sites, beyond its render's own time, while other processes keep every core busy. Renders
// that keep up with updates never reach it.
inline constexpr std::chrono::milliseconds kBackgroundLag{20};

// A render due: a renderer holds one from the moment a scene is queued for a render until
// that render is done (DirtyQueue does). While one has been held for kBackgroundLag, a thread
// of its own (not a render thread, so the background never starves it) holds a RenderWait,
// until none has. Thread-safe; nothing at all where renders never go to the background.
class RenderDue {
 public:
  RenderDue();
  ~RenderDue();
  RenderDue(const RenderDue&) = delete;
  RenderDue& operator=(const RenderDue&) = delete;

  // The renders due now.
  static int due();

 private:
  bool held_ = false;
  std::chrono::steady_clock::time_point since_;
};

// Thread-safe. Jobs are queued on lanes; a free thread takes the oldest job of the lane of
// highest priority that has one and is under its limit of running jobs.
class CpuPool {
 public:
  // `threads` threads, named `name` (what `top -H` and debuggers show; 15 characters kept), at
  // the creating thread's priority, or scheduled as render threads (`render`).
  explicit CpuPool(size_t threads, std::string name = "gvd-cpu", bool render = false);
  ~CpuPool();  // CONTRACT: every lane is gone; joins the threads
  CpuPool(const CpuPool&) = delete;
  CpuPool& operator=(const CpuPool&) = delete;

  // The process-wide pool: hardware_concurrency() threads (at least one), made on first use
  // and never destroyed. CONTRACT: first used by a thread at nice 0 (its threads inherit it).
  static CpuPool& Process();
  // The pool of renders' ParallelFor pieces: as many threads, scheduled as render threads;
  // made on first use, never destroyed.
  static CpuPool& Renders();
  // The pool ParallelFor splits work over on the calling thread: a pool thread's own, a
  // render thread's Renders(), any other thread's Process().
  static CpuPool& Current();
  // Makes the calling thread a render thread: kRenderNice, and its ParallelFor on Renders().
  static void BecomeRenderThread();
  // And, from now on, scheduled as RenderWait says (the background while no caller waits).
  // Threads it made before keep kRenderNice: a GL driver's own, made with its context, which
  // no caller could raise.
  static void RenderInBackground();

  size_t threads() const { return threads_.size(); }

  // A queue of jobs with a priority and limits. Threading rules: Submit from any thread; the
  // destructor (on a thread that is not one of its jobs) waits for the lane's queued and
  // running jobs to finish, and those may still submit to it meanwhile.
  class Lane {
   public:
    // Higher `priority` is served first. At most max_running of its jobs run at once, and
    // at most max_queued wait.
    Lane(CpuPool& pool, int priority, size_t max_running, size_t max_queued);
    ~Lane();
    Lane(const Lane&) = delete;
    Lane& operator=(const Lane&) = delete;

    // Queues the job; false (and the job dropped) when max_queued jobs already wait.
    bool Submit(std::function<void()> job);
    // Runs the job on the calling thread, as one of the lane's running jobs, when the lane
    // has none running or waiting; false (the job not run) otherwise.
    bool RunHereIfIdle(const std::function<void()>& job);
    size_t max_queued() const { return max_queued_; }

   private:
    friend class CpuPool;
    CpuPool& pool_;
    const int priority_;
    const size_t max_running_;
    const size_t max_queued_;
    // Guarded by the pool's mutex.
    std::deque<std::function<void()>> queue_;
    size_t running_ = 0;
  };

  // The lane ParallelFor's pieces run on: above every other, unlimited.
  Lane& parallel() { return *parallel_; }

 private:
  void Run();
  // The lane whose job runs next, or null. Under mu_.
  Lane* Next();

  std::mutex mu_;
  std::condition_variable work_;  // a job was queued, a limit freed, or stopping
  std::condition_variable idle_;  // a job finished
  std::vector<Lane*> lanes_;      // by priority, highest first
  bool stopping_ = false;
  std::vector<std::thread> threads_;
  std::unique_ptr<Lane> parallel_;
};

// Calls fn(begin, end) on disjoint ranges covering [0, n): on this thread alone when n is
// below 2 * min_per_thread, else split into pieces of at least min_per_thread that this
// thread and its pool (CpuPool::Current()) take in turn; returns when every piece is done. Never waits
// for a pool thread to be free (this thread takes whatever pieces are left), so it may be
// called from a pool job. fn must be safe to run concurrently on disjoint ranges.
template <class Fn>
void ParallelFor(size_t n, size_t min_per_thread, Fn fn);

// ---- implementation ----

namespace parallel_detail {
struct State {
  size_t n = 0, pieces = 0;
  std::atomic<size_t> next{0}, done{0};
  void (*call)(void*, size_t, size_t) = nullptr;
  void* fn = nullptr;
  std::mutex mu;
  std::condition_variable finished;
  // Takes pieces until none is left; true when it finished the last one.
  void Work() {
    size_t p;
    while ((p = next.fetch_add(1)) < pieces) {
      call(fn, p * n / pieces, (p + 1) * n / pieces);
      if (done.fetch_add(1) + 1 == pieces) {
        std::lock_guard<std::mutex> lock(mu);
        finished.notify_all();
      }
    }
  }
};
}  // namespace parallel_detail

template <class Fn>
void ParallelFor(size_t n, size_t min_per_thread, Fn fn) {
  CpuPool& pool = CpuPool::Current();
  const size_t workers = pool.threads();
  const size_t pieces =
      std::min<size_t>(4 * std::max<size_t>(workers, 1), n / std::max<size_t>(min_per_thread, 1));
  if (pieces <= 1 || workers <= 1) {
    fn(size_t{0}, n);
    return;
  }
  auto state = std::make_shared<parallel_detail::State>();
  state->n = n;
  state->pieces = pieces;
  state->fn = &fn;
  state->call = [](void* f, size_t b, size_t e) { (*static_cast<Fn*>(f))(b, e); };
  // Helpers that start after every piece is taken return at once, touching only `state`.
  for (size_t h = 0; h + 1 < std::min(workers, pieces); ++h) {
    pool.parallel().Submit([state] { state->Work(); });
  }
  state->Work();
  std::unique_lock<std::mutex> lock(state->mu);
  state->finished.wait(lock, [&] { return state->done.load() == pieces; });
}

}  // namespace gvd
