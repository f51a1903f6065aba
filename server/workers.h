// A fixed pool of threads for the work a call must not do on gRPC's own threads: analysis of
// frames (boundaries, neighbours, planning), which may also wait for zoom renders.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace gvd {

// Thread-safe. Jobs run in the order given; the destructor runs those queued, then joins.
class WorkerPool {
 public:
  WorkerPool(size_t threads, size_t max_queued);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // Queues the job; false (and the job dropped) when max_queued jobs already wait.
  bool Submit(std::function<void()> job);

  size_t max_queued() const { return max_queued_; }

 private:
  void Run();

  const size_t max_queued_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace gvd
