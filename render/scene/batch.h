// How a batch of query points is answered, whatever answers each point (a frame's raster
// answer, an exact search of a snapshot): split across the CPU pool and taken tile by tile of
// the grid, with cancellation polled as it goes.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "render/scene/cpu_pool.h"

namespace gvd {

// Calls answer(i, scratch) for the index i of every one of n points, on this thread and the
// process's CPU pool (ParallelFor), in `order` (when not empty: the order of the frame tiles
// the points fall in, OrderByTile, so that each tile's pixels and sites stay in cache; or
// their own order). `scratch` is a vector
// each piece of the batch reuses. `cancelled`, when given, is polled every `check_every`
// points; `answer` returns false to stop the batch. Returns false when the batch stopped
// (cancelled, or an answer said stop): some answers are then missing.
// CONTRACT: answer is safe to call concurrently for distinct indices.
template <class Answer>
bool AnswerBatch(size_t n, const std::vector<uint32_t>& order, size_t check_every,
                 const std::function<bool()>& cancelled, Answer&& answer) {
  std::atomic<bool> stop{false};
  ParallelFor(n, 8192, [&](size_t begin, size_t end) {
    std::vector<uint32_t> scratch;
    for (size_t k = begin; k < end; ++k) {
      if (k % check_every == 0 && (stop || (cancelled && cancelled()))) {
        stop = true;
        return;
      }
      if (!answer(order.empty() ? k : order[k], scratch)) {
        stop = true;
        return;
      }
    }
  });
  return !stop;
}

}  // namespace gvd
