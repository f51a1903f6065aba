#include "render/kernel/triangle_tree.h"

#include <algorithm>
#include <numeric>

namespace gvd {

TriangleTree::TriangleTree(const std::vector<Vec3>& vertices,
                           const std::vector<std::array<uint32_t, 3>>& triangles) {
  const uint32_t n = static_cast<uint32_t>(triangles.size());
  if (n == 0) return;
  prepared_.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    PreparedTriangle& p = prepared_[i];
    p.a = vertices[triangles[i][0]];
    p.ab = vertices[triangles[i][1]] - p.a;
    p.ac = vertices[triangles[i][2]] - p.a;
    p.abab = glm::dot(p.ab, p.ab);
    p.abac = glm::dot(p.ab, p.ac);
    p.acac = glm::dot(p.ac, p.ac);
    const Vec3 m = glm::max(glm::abs(p.ab), glm::abs(p.ac));
    const double largest = std::max({m.x, m.y, m.z});
    const Vec3 normal = glm::cross(p.ab, p.ac);
    // As TriangleFoot: unscaled (its scale is 1 for these magnitudes), and not degenerate.
    p.plain = largest < 0x1p100 && largest > 0x1p-100 &&
              glm::dot(normal, normal) > 0x1p-80 * p.abab * p.acac;
  }
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0u);
  std::vector<Vec3> lo(n), hi(n), centre(n);
  for (uint32_t i = 0; i < n; ++i) {
    const Vec3 a = vertices[triangles[i][0]], b = vertices[triangles[i][1]],
               c = vertices[triangles[i][2]];
    lo[i] = glm::min(a, glm::min(b, c));
    hi[i] = glm::max(a, glm::max(b, c));
    centre[i] = lo[i] * 0.5 + hi[i] * 0.5;
  }
  // Splits at the median of the triangles' centres along the longest axis of their spread;
  // a tree of n leaves' worth has depth about log2(n / kLeaf) + 1, well within the query's
  // stack of 64 (a median split halves every level).
  struct Task {
    uint32_t node, first, count;
  };
  nodes_.reserve(2 * (n / kLeaf + 1));
  nodes_.emplace_back();
  std::vector<Task> tasks{{0, 0, n}};
  while (!tasks.empty()) {
    const Task t = tasks.back();
    tasks.pop_back();
    Vec3 blo(INFINITY), bhi(-INFINITY), clo(INFINITY), chi(-INFINITY);
    for (uint32_t k = t.first; k < t.first + t.count; ++k) {
      const uint32_t i = order_[k];
      blo = glm::min(blo, lo[i]);
      bhi = glm::max(bhi, hi[i]);
      clo = glm::min(clo, centre[i]);
      chi = glm::max(chi, centre[i]);
    }
    nodes_[t.node].lo = blo;
    nodes_[t.node].hi = bhi;
    if (t.count <= kLeaf) {
      nodes_[t.node].first = t.first;
      nodes_[t.node].count = t.count;
      continue;
    }
    const Vec3 spread = chi - clo;
    const int axis = spread.x >= spread.y && spread.x >= spread.z ? 0 : spread.y >= spread.z ? 1 : 2;
    const uint32_t half = t.count / 2;
    auto begin = order_.begin() + t.first;
    std::nth_element(begin, begin + half, begin + t.count, [&](uint32_t a, uint32_t b) {
      return centre[a][axis] < centre[b][axis] || (centre[a][axis] == centre[b][axis] && a < b);
    });
    const uint32_t left = static_cast<uint32_t>(nodes_.size());
    nodes_.emplace_back();
    nodes_.emplace_back();
    nodes_[t.node].first = left;
    nodes_[t.node].count = 0;
    tasks.push_back({left, t.first, half});
    tasks.push_back({left + 1, t.first + half, t.count - half});
  }
  boxes_.resize(n);
  for (uint32_t k = 0; k < n; ++k) boxes_[k] = {lo[order_[k]], hi[order_[k]]};
}

}  // namespace gvd
