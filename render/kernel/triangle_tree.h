// A bounding-volume hierarchy over a mesh's triangles, for nearest points in O(log n) rather
// than a scan of every triangle: what makes a mesh of 10,000 triangles as cheap to query as a
// handful of sites. Built once with the mesh (MakeMesh, exact3.h) and shared by every copy
// of it.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "render/kernel/vec.h"

namespace gvd {

// A triangle made ready for nearest-point queries: its first corner, its edges from it and
// their dot products, so that the regions of its corners, edges and face (Ericson's) cost two
// dot products a query rather than six and a cross product. `plain`: not degenerate (as
// exact3.cc's TriangleFoot judges it) and of coordinates far from overflow and underflow;
// other triangles are scored the general way.
struct PreparedTriangle {
  Vec3 a, ab, ac;
  double abab = 0, abac = 0, acac = 0;
  bool plain = false;
};

// Immutable once built; concurrent queries are safe.
class TriangleTree {
 public:
  // At most this many triangles a leaf (a leaf tests each triangle's own box before scoring it,
  // so a wide leaf costs little).
  static constexpr uint32_t kLeaf = 16;

  // The tree of triangles[i] (three indices into `vertices`, all valid). O(n log n).
  TriangleTree(const std::vector<Vec3>& vertices,
               const std::vector<std::array<uint32_t, 3>>& triangles);

  // Calls `score(i)` for triangle i, which returns its distance from q, for every triangle
  // whose box lies within `*best` of q, nearest boxes first, lowering *best as it goes; the
  // boxes farther than *best are skipped. So with *best = +inf it finds the nearest triangle,
  // and with a finite start only those nearer than it (or as near: a box exactly at *best is
  // visited, so that ties are seen).
  template <class Score>
  void Nearest(Vec3 q, double* best, Score&& score) const;

  // Calls `visit(i)` for every triangle i whose own box lies within `reach` of the box
  // [lo, hi] (so every triangle within `reach` of a point of the box, and some more).
  template <class Visit>
  void WithinBox(Vec3 lo, Vec3 hi, double reach, Visit&& visit) const;

  // Triangle i, made ready for queries.
  const PreparedTriangle& prepared(uint32_t i) const { return prepared_[i]; }

  // The box of all the triangles (of the mesh's used vertices); empty: +inf to -inf.
  Vec3 lo() const { return nodes_.empty() ? Vec3(INFINITY) : nodes_[0].lo; }
  Vec3 hi() const { return nodes_.empty() ? Vec3(-INFINITY) : nodes_[0].hi; }

  size_t bytes() const {
    return sizeof(*this) + nodes_.size() * sizeof(Node) + order_.size() * sizeof(uint32_t) +
           boxes_.size() * sizeof(boxes_[0]) + prepared_.size() * sizeof(PreparedTriangle);
  }

 private:
  struct Node {
    Vec3 lo, hi;          // the box of the node's triangles
    uint32_t first = 0;   // leaf: order_[first, first + count); inner: left child (right = first + 1)
    uint32_t count = 0;   // 0: an inner node
  };
  // The squared distance from q to the box (0 inside), rounded as a triangle's distance is
  // not: a box is skipped only when it lies farther than *best by more than `slack` (a few
  // units in the last place of the coordinates involved), so rounding never drops a triangle
  // as near as the best.
  static double BoxDistance2(const Node& n, Vec3 q) {
    const Vec3 d = glm::max(glm::max(n.lo - q, q - n.hi), Vec3(0));
    return glm::dot(d, d);
  }
  std::vector<Node> nodes_;      // nodes_[0] is the root
  std::vector<uint32_t> order_;  // triangle indices, leaf by leaf
  // The box of triangle order_[k]: a triangle whose own box lies beyond *best is not scored.
  std::vector<std::array<Vec3, 2>> boxes_;
  std::vector<PreparedTriangle> prepared_;  // by triangle index
};

template <class Score>
void TriangleTree::Nearest(Vec3 q, double* best, Score&& score) const {
  if (nodes_.empty()) return;
  const Vec3 m = glm::max(glm::abs(q), glm::max(glm::abs(nodes_[0].lo), glm::abs(nodes_[0].hi)));
  const double slack = 0x1p-45 * std::max({m.x, m.y, m.z});
  // Each node waits on the stack with its box's squared distance, computed once.
  struct Entry {
    uint32_t node;
    double distance2;
  };
  Entry stack[64];
  uint32_t top = 0;
  stack[top++] = {0, BoxDistance2(nodes_[0], q)};
  while (top > 0) {
    const Entry e = stack[--top];
    // Box distances are squared without scaling: past 1e150 they are infinite, which only
    // visits more (an infinite *best prunes nothing).
    const double b = *best + slack;
    if (e.distance2 > b * b) continue;
    const Node& n = nodes_[e.node];
    if (n.count > 0) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) {
        const Vec3 o = glm::max(glm::max(boxes_[k][0] - q, q - boxes_[k][1]), Vec3(0));
        const double c = *best + slack;
        if (glm::dot(o, o) > c * c) continue;
        const double d = score(order_[k]);
        if (d < *best) *best = d;
      }
      continue;
    }
    // The nearer child is visited first: pushed last.
    const uint32_t l = n.first, r = n.first + 1;
    const double dl = BoxDistance2(nodes_[l], q), dr = BoxDistance2(nodes_[r], q);
    if (dl <= dr) {
      stack[top++] = {r, dr};
      stack[top++] = {l, dl};
    } else {
      stack[top++] = {l, dl};
      stack[top++] = {r, dr};
    }
  }
}

template <class Visit>
void TriangleTree::WithinBox(Vec3 lo, Vec3 hi, double reach, Visit&& visit) const {
  if (nodes_.empty()) return;
  const Vec3 m = glm::max(glm::max(glm::abs(lo), glm::abs(hi)),
                          glm::max(glm::abs(nodes_[0].lo), glm::abs(nodes_[0].hi)));
  const double r = reach + 0x1p-45 * std::max({m.x, m.y, m.z});
  uint32_t stack[64];
  uint32_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    const Vec3 d = glm::max(glm::max(n.lo - hi, lo - n.hi), Vec3(0));
    if (glm::dot(d, d) > r * r) continue;
    if (n.count > 0) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) {
        const Vec3 o = glm::max(glm::max(boxes_[k][0] - hi, lo - boxes_[k][1]), Vec3(0));
        if (glm::dot(o, o) <= r * r) visit(order_[k]);
      }
      continue;
    }
    stack[top++] = n.first;
    stack[top++] = n.first + 1;
  }
}

}  // namespace gvd
