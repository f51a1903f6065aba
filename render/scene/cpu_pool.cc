#include "render/scene/cpu_pool.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <set>

namespace gvd {
namespace {

thread_local CpuPool* current_pool = nullptr;  // CpuPool::Current()'s, when set

// The render threads, and how they run now.
struct RenderThreads {
  std::mutex mu;
  std::vector<pid_t> tids;
  int waits = 0;
  int callers = 0;  // of waits, those of callers (not RenderDue's raise)
  bool background = false;
};

// WakeOnCaller's callbacks. Called under call_mu (never under RenderThreads::mu), which
// StopWaking takes too, so that none runs once it returns.
struct CallerWakers {
  std::mutex call_mu;
  std::mutex mu;  // guards the two below
  std::map<uint64_t, std::function<void()>> wakers;
  uint64_t next = 1;
};

CallerWakers& Wakers() {
  static auto* wakers = new CallerWakers;
  return *wakers;
}

RenderThreads& Renderers() {
  static auto* threads = new RenderThreads;
  return *threads;
}

// Schedules thread `tid`, a render thread of this process, in the background (SCHED_IDLE)
// or at kRenderNice.
void Schedule(pid_t tid, bool background) {
  // The nice value first: SCHED_IDLE keeps it, and leaving SCHED_IDLE is allowed up to the
  // priority it names.
  setpriority(PRIO_PROCESS, static_cast<id_t>(tid), kRenderNice);
  sched_param none{};
  sched_setscheduler(tid, background ? SCHED_IDLE : SCHED_OTHER, &none);
}

// The renders due (RenderDue), and the thread that raises the render threads while one of
// them is late.
// The watcher is told only what it could not see for itself by looking again at the time it
// set (every kBackgroundLag at most): a render due while it sleeps with none due, and the
// oldest render done while it holds the threads raised. A move's render comes due and is
// done without waking it.
struct DueRenders {
  std::mutex mu;
  std::condition_variable changed;
  std::multiset<std::chrono::steady_clock::time_point> since;
  bool asleep = false;  // the watcher waits with no time set
  bool raised = false;  // it holds a RenderWait
};

// Looks this many times, kBackgroundLag apart, after the last render due was done, before
// sleeping until the next comes due: a burst of moves wakes it no more than this.
constexpr int kIdleLooks = 50;

void WatchLateRenders(DueRenders& due) {
  pthread_setname_np(pthread_self(), "gvd-render-late");
  // Whoever made this thread, it runs as calls do: a render thread's priority would let the
  // background starve it.
  sched_param none{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &none);
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 0);
  std::unique_lock<std::mutex> lock(due.mu);
  std::optional<RenderWait> raised;
  int idle = 0;
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    const bool late = !due.since.empty() && now >= *due.since.begin() + kBackgroundLag;
    if (late != raised.has_value()) {
      if (late) {
        raised.emplace(RenderWait::Late{});
      } else {
        raised.reset();
      }
      due.raised = late;
    }
    if (late) {
      due.changed.wait(lock);
    } else if (!due.since.empty()) {
      idle = 0;
      due.changed.wait_until(lock, *due.since.begin() + kBackgroundLag);
    } else if (idle < kIdleLooks) {
      ++idle;
      due.changed.wait_until(lock, now + kBackgroundLag);
    } else {
      due.asleep = true;
      due.changed.wait(lock);
      due.asleep = false;
    }
  }
}

DueRenders& Due() {
  static DueRenders* due = [] {
    auto* d = new DueRenders;
    std::thread([d] { WatchLateRenders(*d); }).detach();  // lives as long as the process
    return d;
  }();
  return *due;
}

// Registers the calling thread as a render thread until it ends (its id is then no longer
// scheduled: the system may give it to another thread).
void JoinRenderers() {
  RenderWait::Background();  // decided before the first render thread is scheduled
  struct Member {
    pid_t tid = gettid();
    Member() {
      RenderThreads& r = Renderers();
      std::lock_guard<std::mutex> lock(r.mu);
      r.tids.push_back(tid);
      Schedule(tid, r.background);
    }
    ~Member() {
      RenderThreads& r = Renderers();
      std::lock_guard<std::mutex> lock(r.mu);
      r.tids.erase(std::find(r.tids.begin(), r.tids.end(), tid));
    }
  };
  thread_local Member member;
}

}  // namespace

bool RenderWait::Background() {
  static const bool background = [] {
    // Renders go to the background only if the process can bring them back.
    bool back = false;
    std::thread([&back] {
      sched_param none{};
      if (setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kRenderNice) != 0 ||
          pthread_setschedparam(pthread_self(), SCHED_IDLE, &none) != 0) {
        return;
      }
      back = pthread_setschedparam(pthread_self(), SCHED_OTHER, &none) == 0;
    }).join();
    RenderThreads& r = Renderers();
    std::lock_guard<std::mutex> lock(r.mu);
    r.background = back && r.waits == 0;
    for (pid_t tid : r.tids) Schedule(tid, r.background);
    return back;
  }();
  return background;
}

RenderWait::RenderWait() : RenderWait(Late{}) {
  caller_ = true;
  bool first;
  {
    RenderThreads& r = Renderers();
    std::lock_guard<std::mutex> lock(r.mu);
    first = ++r.callers == 1;
  }
  if (first) {
    CallerWakers& w = Wakers();
    std::lock_guard<std::mutex> calling(w.call_mu);
    std::vector<std::function<void()>> wakers;
    {
      std::lock_guard<std::mutex> lock(w.mu);
      for (const auto& [token, wake] : w.wakers) wakers.push_back(wake);
    }
    for (const auto& wake : wakers) wake();
  }
}

RenderWait::RenderWait(Late) : caller_(false) {
  Background();  // decided before the first count
  RenderThreads& r = Renderers();
  std::lock_guard<std::mutex> lock(r.mu);
  if (++r.waits == 1 && r.background) {
    r.background = false;
    for (pid_t tid : r.tids) Schedule(tid, false);
  }
}

RenderWait::~RenderWait() {
  if (!held_) return;
  RenderThreads& r = Renderers();
  std::lock_guard<std::mutex> lock(r.mu);
  if (caller_) --r.callers;
  if (--r.waits == 0 && Background()) {
    r.background = true;
    for (pid_t tid : r.tids) Schedule(tid, true);
  }
}

RenderWait::RenderWait(RenderWait&& other) noexcept
    : held_(other.held_), caller_(other.caller_) {
  other.held_ = false;
}

RenderWait& RenderWait::operator=(RenderWait&& other) noexcept {
  if (this != &other) {
    RenderWait gone(std::move(*this));
    held_ = other.held_;
    caller_ = other.caller_;
    other.held_ = false;
  }
  return *this;
}

uint64_t RenderWait::WakeOnCaller(std::function<void()> wake) {
  CallerWakers& w = Wakers();
  std::lock_guard<std::mutex> lock(w.mu);
  const uint64_t token = w.next++;
  w.wakers.emplace(token, std::move(wake));
  return token;
}

void RenderWait::StopWaking(uint64_t token) {
  CallerWakers& w = Wakers();
  std::lock_guard<std::mutex> calling(w.call_mu);
  std::lock_guard<std::mutex> lock(w.mu);
  w.wakers.erase(token);
}

RenderDue::RenderDue() {
  if (!RenderWait::Background()) return;
  DueRenders& due = Due();
  held_ = true;
  since_ = std::chrono::steady_clock::now();
  std::lock_guard<std::mutex> lock(due.mu);
  if (due.asleep) due.changed.notify_one();
  due.since.insert(since_);
}

RenderDue::~RenderDue() {
  if (!held_) return;
  DueRenders& due = Due();
  std::lock_guard<std::mutex> lock(due.mu);
  auto it = due.since.find(since_);
  if (due.raised && it == due.since.begin()) due.changed.notify_one();
  due.since.erase(it);
}

int RenderDue::due() {
  if (!RenderWait::Background()) return 0;
  DueRenders& due = Due();
  std::lock_guard<std::mutex> lock(due.mu);
  return static_cast<int>(due.since.size());
}

int RenderWait::held() {
  RenderThreads& r = Renderers();
  std::lock_guard<std::mutex> lock(r.mu);
  return r.waits;
}

int RenderWait::callers() {
  RenderThreads& r = Renderers();
  std::lock_guard<std::mutex> lock(r.mu);
  return r.callers;
}

CpuPool::CpuPool(size_t threads, std::string name, bool render) {
  parallel_ = std::make_unique<Lane>(*this, std::numeric_limits<int>::max(),
                                     std::numeric_limits<size_t>::max(),
                                     std::numeric_limits<size_t>::max());
  name.resize(std::min<size_t>(name.size(), 15));  // the kernel's limit
  for (size_t t = 0; t < std::max<size_t>(threads, 1); ++t) {
    threads_.emplace_back([this, name, render] {
      pthread_setname_np(pthread_self(), name.c_str());
      if (render) JoinRenderers();
      current_pool = this;
      Run();
    });
  }
}

CpuPool::~CpuPool() {
  parallel_.reset();
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
  }
  work_.notify_all();
  for (auto& t : threads_) t.join();
}

CpuPool& CpuPool::Process() {
  static CpuPool* pool = new CpuPool(std::max(1u, std::thread::hardware_concurrency()));
  return *pool;
}

CpuPool& CpuPool::Renders() {
  static CpuPool* pool =
      new CpuPool(std::max(1u, std::thread::hardware_concurrency()), "gvd-render-cpu", true);
  return *pool;
}

CpuPool& CpuPool::Current() { return current_pool != nullptr ? *current_pool : Process(); }

void CpuPool::BecomeRenderThread() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kRenderNice);
  current_pool = &Renders();
}

void CpuPool::RenderInBackground() { JoinRenderers(); }

CpuPool::Lane::Lane(CpuPool& pool, int priority, size_t max_running, size_t max_queued)
    : pool_(pool),
      priority_(priority),
      max_running_(std::max<size_t>(max_running, 1)),
      max_queued_(max_queued) {
  std::lock_guard<std::mutex> lock(pool_.mu_);
  auto at = std::find_if(pool_.lanes_.begin(), pool_.lanes_.end(),
                         [&](const Lane* l) { return l->priority_ < priority_; });
  pool_.lanes_.insert(at, this);
}

CpuPool::Lane::~Lane() {
  std::unique_lock<std::mutex> lock(pool_.mu_);
  pool_.idle_.wait(lock, [this] { return queue_.empty() && running_ == 0; });
  pool_.lanes_.erase(std::find(pool_.lanes_.begin(), pool_.lanes_.end(), this));
}

bool CpuPool::Lane::Submit(std::function<void()> job) {
  {
    std::lock_guard<std::mutex> lock(pool_.mu_);
    if (queue_.size() >= max_queued_) return false;
    queue_.push_back(std::move(job));
  }
  pool_.work_.notify_one();
  return true;
}

bool CpuPool::Lane::RunHereIfIdle(const std::function<void()>& job) {
  {
    std::lock_guard<std::mutex> lock(pool_.mu_);
    if (running_ > 0 || !queue_.empty()) return false;
    ++running_;
  }
  job();
  std::lock_guard<std::mutex> lock(pool_.mu_);
  --running_;
  pool_.idle_.notify_all();
  // Jobs queued meanwhile waited for this one only if the lane is at its limit.
  if (!queue_.empty()) pool_.work_.notify_one();
  return true;
}

CpuPool::Lane* CpuPool::Next() {
  for (Lane* lane : lanes_) {
    if (!lane->queue_.empty() && lane->running_ < lane->max_running_) return lane;
  }
  return nullptr;
}

void CpuPool::Run() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    Lane* lane;
    work_.wait(lock, [&] { return (lane = Next()) != nullptr || stopping_; });
    if (lane == nullptr) return;  // stopping, and every lane is gone
    std::function<void()> job = std::move(lane->queue_.front());
    lane->queue_.pop_front();
    ++lane->running_;
    lock.unlock();
    job();
    job = nullptr;  // what the job holds is released outside the lock
    lock.lock();
    --lane->running_;
    idle_.notify_all();
    // A lane at its limit may now run its next job, which a waiting thread was not told of.
    if (!lane->queue_.empty()) work_.notify_one();
  }
}

}  // namespace gvd
