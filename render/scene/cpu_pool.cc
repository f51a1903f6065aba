#include "render/scene/cpu_pool.h"

#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <limits>

namespace gvd {
namespace {

thread_local CpuPool* current_pool = nullptr;  // CpuPool::Current()'s, when set

}  // namespace

CpuPool::CpuPool(size_t threads, std::string name, int nice) {
  parallel_ = std::make_unique<Lane>(*this, std::numeric_limits<int>::max(),
                                     std::numeric_limits<size_t>::max(),
                                     std::numeric_limits<size_t>::max());
  name.resize(std::min<size_t>(name.size(), 15));  // the kernel's limit
  for (size_t t = 0; t < std::max<size_t>(threads, 1); ++t) {
    threads_.emplace_back([this, name, nice] {
      pthread_setname_np(pthread_self(), name.c_str());
      if (nice != 0) setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice);
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
      new CpuPool(std::max(1u, std::thread::hardware_concurrency()), "gvd-render-cpu", kRenderNice);
  return *pool;
}

CpuPool& CpuPool::Current() { return current_pool != nullptr ? *current_pool : Process(); }

void CpuPool::BecomeRenderThread() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kRenderNice);
  current_pool = &Renders();
}

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
