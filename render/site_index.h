// A spatial index of sites by bounding box (a Boost.Geometry R*-tree), for finding the
// sites that can be nearest within a region, and exact nearest sites.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "render/exact.h"
#include "render/geometry.h"
#include "render/site.h"

namespace gvd {

// Not thread-safe for writers; concurrent const calls are safe.
class SiteIndex {
 public:
  SiteIndex();
  ~SiteIndex();
  SiteIndex(SiteIndex&&) noexcept;
  SiteIndex& operator=(SiteIndex&&) noexcept;

  // An index of every live slot of the table. O(n log n), bulk loaded.
  static SiteIndex Build(const SlotTable& sites);

  void Insert(uint32_t slot, const Geometry& geometry);
  // CONTRACT: (slot, geometry) was inserted and not removed since.
  void Remove(uint32_t slot, const Geometry& geometry);
  size_t size() const;

  // The exact nearest site to q (ties: the one met first); `index` is its slot. `sites` is
  // the table the slots index. CONTRACT: the index is not empty.
  ExactNearest Nearest(Vec2 q, const SlotTable& sites) const;

  // Appends the slots of the sites whose bounding boxes come within r of q: a superset of
  // the sites within r of q.
  void Within(Vec2 q, double r, std::vector<uint32_t>* out) const;

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

}  // namespace gvd
