#include "render/kernel/segment_tree.h"

#include <algorithm>
#include <memory>
#include <type_traits>
#include <variant>

#include "render/kernel/exact2.h"

namespace gvd {

SegmentTree::SegmentTree(const Geometry& g) {
  ForEachSegment(g, [&](Vec2 p, Vec2 q) {
    a_.push_back(p);
    b_.push_back(q);
  });
  if (a_.empty()) return;
  // Long segments are indexed in pieces of about the spacing segments would have if they
  // were spread evenly over the site's box (at most 16 pieces a segment on average), so
  // that boxes stay small where long segments cross one another; distances are always
  // measured to the whole segment.
  Window box{INFINITY, INFINITY, -INFINITY, -INFINITY};
  double total = 0;
  for (size_t k = 0; k < a_.size(); ++k) {
    for (Vec2 p : {a_[k], b_[k]}) {
      box.min_x = std::min(box.min_x, p.x);
      box.min_y = std::min(box.min_y, p.y);
      box.max_x = std::max(box.max_x, p.x);
      box.max_y = std::max(box.max_y, p.y);
    }
    total += Distance(a_[k], b_[k]);
  }
  const double n = static_cast<double>(a_.size());
  double piece = 2 * std::max(box.max_x - box.min_x, box.max_y - box.min_y) / std::sqrt(n);
  piece = std::max(piece, total / (16 * n));
  std::vector<Vec2> pa, pb;
  std::vector<uint32_t> owner;
  for (uint32_t k = 0; k < a_.size(); ++k) {
    const double length = Distance(a_[k], b_[k]);
    const uint32_t pieces =
        std::isfinite(length) && piece > 0 && length > piece
            ? static_cast<uint32_t>(std::min(std::ceil(length / piece), 1e6))
            : 1;
    for (uint32_t i = 0; i < pieces; ++i) {
      pa.push_back(i == 0 ? a_[k] : a_[k] + (b_[k] - a_[k]) * (double(i) / pieces));
      pb.push_back(i + 1 == pieces ? b_[k] : a_[k] + (b_[k] - a_[k]) * (double(i + 1) / pieces));
      owner.push_back(k);
    }
  }
  // Built over a permutation of the pieces, which index_ then takes.
  std::vector<uint32_t> order(pa.size());
  for (uint32_t k = 0; k < order.size(); ++k) order[k] = k;
  nodes_.reserve(2 * (pa.size() / kLeaf + 1));
  Build(pa, pb, owner, order, 0, static_cast<uint32_t>(pa.size()));
  index_.resize(order.size());
  for (size_t k = 0; k < order.size(); ++k) index_[k] = owner[order[k]];
}

uint32_t SegmentTree::Build(const std::vector<Vec2>& a, const std::vector<Vec2>& b,
                            const std::vector<uint32_t>& owner, std::vector<uint32_t>& order,
                            uint32_t begin, uint32_t end) {
  const uint32_t at = static_cast<uint32_t>(nodes_.size());
  nodes_.emplace_back();
  Window box{INFINITY, INFINITY, -INFINITY, -INFINITY}, mids = box, whole = box;
  auto mid = [&](uint32_t k) { return (a[k] + b[k]) * 0.5; };
  auto add = [](Window& w, Vec2 p) {
    w.min_x = std::min(w.min_x, p.x);
    w.min_y = std::min(w.min_y, p.y);
    w.max_x = std::max(w.max_x, p.x);
    w.max_y = std::max(w.max_y, p.y);
  };
  for (uint32_t i = begin; i < end; ++i) {
    const uint32_t k = order[i];
    add(box, a[k]);
    add(box, b[k]);
    add(mids, mid(k));
    add(whole, a_[owner[k]]);
    add(whole, b_[owner[k]]);
  }
  // A computed point of a segment, and a piece's computed ends, can stray a few ulps of
  // their coordinates from the segment: grow the box by far more than that.
  auto grown = [](const Window& w) {
    const double grow = 0x1p-40 * std::max({std::abs(w.min_x), std::abs(w.max_x),
                                            std::abs(w.min_y), std::abs(w.max_y)}) +
                        0x1p-1000;
    return Window{w.min_x - grow, w.min_y - grow, w.max_x + grow, w.max_y + grow};
  };
  nodes_[at].box = grown(box);
  nodes_[at].whole = grown(whole);
  nodes_[at].begin = begin;
  nodes_[at].end = end;
  if (end - begin <= kLeaf) return at;
  // Halves by the middles' median along the wider side of their box.
  const int axis = mids.max_x - mids.min_x >= mids.max_y - mids.min_y ? 0 : 1;
  const uint32_t half = begin + (end - begin) / 2;
  std::nth_element(order.begin() + begin, order.begin() + half, order.begin() + end,
                   [&](uint32_t x, uint32_t y) {
                     const double mx = mid(x)[axis], my = mid(y)[axis];
                     return mx < my || (mx == my && x < y);
                   });
  Build(a, b, owner, order, begin, half);
  const uint32_t right = Build(a, b, owner, order, half, end);
  nodes_[at].right = right;
  return at;
}

SegmentTree::Hit SegmentTree::Nearest(Vec2 q) const {
  Hit best;
  if (nodes_.empty()) return best;
  // Nodes are pruned only when their box is farther than the best distance by more than
  // rounding, so every segment that ties with the best is measured, and the first wins.
  auto prune = [&](double lower) { return lower > best.distance * (1 + 0x1p-40); };
  uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (prune(BoxDistance(n.box, q))) continue;
    if (n.right == 0) {
      for (uint32_t k = n.begin; k < n.end; ++k) {
        const uint32_t j = index_[k];
        double t = 0;
        const double d = SegmentDistance(q, a_[j], b_[j], &t);
        if (d < best.distance || (d == best.distance && j < best.index)) best = {d, j, t};
      }
      continue;
    }
    // The nearer child last, so that it is searched first.
    const uint32_t left = static_cast<uint32_t>(&n - nodes_.data()) + 1;
    const bool left_first = BoxDistance(nodes_[left].box, q) <= BoxDistance(nodes_[n.right].box, q);
    stack[top++] = left_first ? n.right : left;
    stack[top++] = left_first ? left : n.right;
  }
  return best;
}

double SegmentTree::Farthest(const Window& box) const {
  double best = INFINITY;
  if (nodes_.empty()) return best;
  const Vec2 corners[4] = {{box.min_x, box.min_y}, {box.max_x, box.min_y},
                           {box.min_x, box.max_y}, {box.max_x, box.max_y}};
  uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    // A piece's box bounds the distance to its piece, not to its segment: the whole
    // segments' boxes do.
    double lower = 0;
    for (Vec2 c : corners) lower = std::max(lower, BoxDistance(n.whole, c));
    if (lower > best * (1 + 0x1p-40)) continue;
    if (n.right == 0) {
      for (uint32_t k = n.begin; k < n.end; ++k) {
        const uint32_t j = index_[k];
        double m = 0;
        for (Vec2 c : corners) m = std::max(m, SegmentDistance(c, a_[j], b_[j]));
        best = std::min(best, m);
      }
      continue;
    }
    stack[top++] = n.right;
    stack[top++] = static_cast<uint32_t>(&n - nodes_.data()) + 1;
  }
  return best;
}

void IndexSegments(Site& site) {
  if (std::holds_alternative<PointSite>(site.geometry) ||
      std::holds_alternative<SegmentSite>(site.geometry)) {
    site.segment_tree = nullptr;
    return;
  }
  size_t n = 0;
  ForEachSegment(site.geometry, [&](Vec2, Vec2) { ++n; });
  site.segment_tree = n >= SegmentTree::kMinSegments
                      ? std::make_shared<const SegmentTree>(site.geometry)
                      : nullptr;
}

}  // namespace gvd
