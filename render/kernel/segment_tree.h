// A bounding-volume hierarchy over the segments of one site with many of them (a long
// polyline, a polygon of many vertices, a finely flattened curve), so that the exact
// functions of exact2.h cost about O(log n) for it instead of O(n). It changes none of their
// values, only how fast they are found: ties still go to the first segment in ForEachSegment
// order.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"

namespace gvd {

class SegmentTree {
 public:
  // Sites with fewer segments are scanned in a loop, which is as fast.
  static constexpr size_t kMinSegments = 32;

  // The tree of the geometry's segments (ForEachSegment, exact2.h).
  explicit SegmentTree(const Geometry& g);

  size_t size() const { return a_.size(); }

  // The least SegmentDistance(q, a, b, &t) over the segments, the first segment in order that
  // has it, and its t: what a loop over ForEachSegment keeping the first least finds.
  struct Hit {
    double distance = INFINITY;
    uint32_t index = 0;
    double t = 0;
  };
  Hit Nearest(Vec2 q) const;

  // The least over the segments of the greatest SegmentDistance from a corner of the box:
  // FarthestDistance(box, geometry).
  double Farthest(const Window& box) const;

  // Calls f(index, a, b) for every segment within r of q, and perhaps a few a little farther
  // (the test is on boxes); in no particular order, and a long segment perhaps more than once.
  template <class F>
  void Within(Vec2 q, double r, F&& f) const;

 private:
  // Node boxes are grown by a few ulps of their coordinates, so that a box's distance from a
  // point never exceeds a computed distance to a segment inside it.
  struct Node {
    Window box;    // of its pieces
    Window whole;  // of the whole segments its pieces belong to (for Farthest)
    uint32_t begin = 0, end = 0;  // its pieces, in index_
    uint32_t right = 0;           // the second child (the first follows the node); 0: a leaf
  };
  static constexpr uint32_t kLeaf = 4;
  // Distance from q to the box (0 inside), within an ulp or two.
  static double BoxDistance(const Window& b, Vec2 q) {
    const double dx = std::max({0.0, b.min_x - q.x, q.x - b.max_x});
    const double dy = std::max({0.0, b.min_y - q.y, q.y - b.max_y});
    const double d2 = dx * dx + dy * dy;
    return d2 < 1e300 ? std::sqrt(d2) : std::hypot(dx, dy);
  }
  // The node over the pieces order[begin, end) of a, b (piece k of segment owner[k]; their
  // order within the range permuted), with its subtree after it.
  uint32_t Build(const std::vector<Vec2>& a, const std::vector<Vec2>& b,
                 const std::vector<uint32_t>& owner, std::vector<uint32_t>& order,
                 uint32_t begin, uint32_t end);

  std::vector<Node> nodes_;
  std::vector<Vec2> a_, b_;      // the segments, in ForEachSegment order
  std::vector<uint32_t> index_;  // the segment of each piece, in the nodes' order
};

// Gives the site a SegmentTree when it has at least SegmentTree::kMinSegments segments (and
// drops any it had otherwise). The slot table and the snapshot builder call it as a site
// enters them. CONTRACT: the site's geometry does not change afterwards.
void IndexSegments(Site& site);

// ---- implementation ----

template <class F>
void SegmentTree::Within(Vec2 q, double r, F&& f) const {
  if (nodes_.empty()) return;
  const double reach = r * (1 + 0x1p-40);
  uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (BoxDistance(n.box, q) > reach) continue;
    if (n.right == 0) {
      for (uint32_t k = n.begin; k < n.end; ++k) f(index_[k], a_[index_[k]], b_[index_[k]]);
      continue;
    }
    stack[top++] = n.right;
    stack[top++] = static_cast<uint32_t>(&n - nodes_.data()) + 1;
  }
}

}  // namespace gvd
