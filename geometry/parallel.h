// Splits [0, n) across the machine's cores for work that is worth a thread each.
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace gvd {

// Calls fn(begin, end) on disjoint ranges covering [0, n): on this thread alone when n is
// below 2 * min_per_thread, else on up to hardware_concurrency() threads (this one included).
// fn must be safe to run concurrently on disjoint ranges.
template <class Fn>
void ParallelFor(size_t n, size_t min_per_thread, Fn fn) {
  size_t threads = std::min<size_t>(std::max(1u, std::thread::hardware_concurrency()),
                                    n / std::max<size_t>(min_per_thread, 1));
  if (threads <= 1) {
    fn(size_t{0}, n);
    return;
  }
  std::vector<std::thread> pool;
  size_t step = (n + threads - 1) / threads;
  for (size_t t = 1; t < threads; ++t) {
    size_t b = t * step, e = std::min(n, b + step);
    if (b < e) pool.emplace_back([=] { fn(b, e); });
  }
  fn(size_t{0}, std::min(n, step));
  for (auto& th : pool) th.join();
}

}  // namespace gvd
