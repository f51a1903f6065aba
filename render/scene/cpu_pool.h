// The process's CPU pools: one thread per core for the computation that is neither a render
// thread's nor a transport's (answers, image encoding, analyses, and the pieces of
// ParallelFor), so that the process runs as many busy threads as it has cores, whatever the
// load; and as many again for the pieces of renders, at the render threads' lower priority.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace gvd {

// The nice value of render threads and of the pool that runs their ParallelFor pieces (Linux
// sets it per thread): a call's thread woken while a render holds every core (a full render
// takes many milliseconds) runs first rather than after a time slice. Frames still come as
// soon as no call wants the CPU; the weight is relative to the process's other threads.
inline constexpr int kRenderNice = 10;

// Thread-safe. Jobs are queued on lanes; a free thread takes the oldest job of the lane of
// highest priority that has one and is under its limit of running jobs.
class CpuPool {
 public:
  // `threads` threads, named `name` (what `top -H` and debuggers show; 15 characters kept), at
  // `nice` (0: the creating thread's).
  explicit CpuPool(size_t threads, std::string name = "gvd-cpu", int nice = 0);
  ~CpuPool();  // CONTRACT: every lane is gone; joins the threads
  CpuPool(const CpuPool&) = delete;
  CpuPool& operator=(const CpuPool&) = delete;

  // The process-wide pool: hardware_concurrency() threads (at least one), made on first use
  // and never destroyed. CONTRACT: first used by a thread at nice 0 (its threads inherit it).
  static CpuPool& Process();
  // The pool of renders' ParallelFor pieces: as many threads, at kRenderNice; made on first
  // use, never destroyed.
  static CpuPool& Renders();
  // The pool ParallelFor splits work over on the calling thread: a pool thread's own, a
  // render thread's Renders(), any other thread's Process().
  static CpuPool& Current();
  // Makes the calling thread a render thread: kRenderNice, and its ParallelFor on Renders().
  static void BecomeRenderThread();

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
