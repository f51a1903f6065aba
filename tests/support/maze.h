// Random mazes of segment walls for the planning tests (render and server).
#pragma once

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "render/kernel/site2.h"

namespace gvd::testing {

// A perfect maze of k x k cells from a random depth-first search, walls as segments: every
// corridor is one cell wide, so the bottleneck clearance is half a cell.
inline SiteTable Maze(int k, uint64_t seed) {
  std::mt19937_64 rng(seed);
  const double c = 1.0 / k;
  // wall[h][y][x]: the wall below cell (x, y) (h = 1) or left of it (h = 0).
  std::vector<uint8_t> below((k + 1) * k, 1), left(k * (k + 1), 1), seen(k * k, 0);
  std::vector<std::pair<int, int>> stack = {{0, 0}};
  seen[0] = 1;
  while (!stack.empty()) {
    auto [x, y] = stack.back();
    std::vector<std::pair<int, int>> next;
    for (auto [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
      int nx = x + dx, ny = y + dy;
      if (nx >= 0 && ny >= 0 && nx < k && ny < k && !seen[ny * k + nx]) next.push_back({nx, ny});
    }
    if (next.empty()) {
      stack.pop_back();
      continue;
    }
    auto [nx, ny] = next[rng() % next.size()];
    if (nx != x) left[y * (k + 1) + std::max(x, nx)] = 0;
    else below[std::max(y, ny) * k + x] = 0;
    seen[ny * k + nx] = 1;
    stack.push_back({nx, ny});
  }
  SiteTable sites;
  for (int y = 0; y <= k; ++y) {
    for (int x = 0; x < k; ++x) {
      if (below[y * k + x]) {
        sites.push_back({"h" + std::to_string(y) + "_" + std::to_string(x),
                         SegmentSite{{x * c, y * c}, {(x + 1) * c, y * c}}});
      }
    }
  }
  for (int y = 0; y < k; ++y) {
    for (int x = 0; x <= k; ++x) {
      if (left[y * (k + 1) + x]) {
        sites.push_back({"v" + std::to_string(y) + "_" + std::to_string(x),
                         SegmentSite{{x * c, y * c}, {x * c, (y + 1) * c}}});
      }
    }
  }
  return sites;
}

}  // namespace gvd::testing
