// A scene's sites by slot: the persistent table that snapshots of nearby versions share. A
// template on the kernel (render/kernel/kernel2.h) whose sites it holds; SlotTable is the 2D
// kernel's.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "render/kernel/kernel2.h"
#include "render/kernel/kernel3.h"

namespace gvd {

// The least multiplicative and additive weights over some sites (infinite when there are
// none): no site's value at a point at distance d from it is below
// multiplicative * d + additive.
struct LeastWeights {
  double multiplicative = INFINITY;
  double additive = INFINITY;
};

// Sites by slot (the id buffer holds slot + 1), in a persistent two-level table that versions
// share: blocks of kBlock chunks of kChunk slots, under a root. A copy is O(1); a change
// copies the root's block pointers, one block and one chunk (O(slots / kBlockSlots + kBlock
// + kChunk)), and leaves every other table as it was. Each site is immutable and shared: two
// tables hold the same site in a slot exactly when they hold the same pointer, which is how a
// renderer finds what changed between two versions (Diff). A copy is immutable to readers of
// the original; not thread-safe for concurrent writers.
template <class K>
class BasicSlotTable {
 public:
  using Site = typename K::Site;
  using Point = typename K::Point;
  static constexpr uint32_t kChunk = 64;
  static constexpr uint32_t kBlock = 32;
  static constexpr uint32_t kBlockSlots = kChunk * kBlock;

  BasicSlotTable() = default;
  explicit BasicSlotTable(const std::vector<Site>& sites);  // slot i = sites[i]

  uint32_t size() const { return size_; }  // slots, free ones included
  // The site in `slot`, or null for a free slot. CONTRACT: slot < size().
  const Site* get(uint32_t slot) const { return ptr(slot).get(); }
  const std::shared_ptr<const Site>& ptr(uint32_t slot) const {
    return chunk(slot).sites[slot % kChunk];
  }
  // Where the site in `slot` is, when it is a plain (Site::plain) point, and NaN otherwise:
  // then its value at q is its distance from q, found without reaching the site itself.
  // CONTRACT: slot < size().
  Point point(uint32_t slot) const { return chunk(slot).points[slot % kChunk]; }
  // Puts a site in (or frees, with null) a slot, growing the table as needed.
  void Set(uint32_t slot, std::shared_ptr<const Site> site);
  // The same for a site not yet shared, which the kernel readies first (K::Prepare).
  void Set(uint32_t slot, std::optional<Site> site);

  // The least weights over the sites, exactly: O(slots / kBlockSlots), as each chunk and
  // block keeps its own.
  LeastWeights least() const;

  // Calls f(slot, before, after) for every slot whose site differs between the two tables
  // (by identity; either may be null). Blocks and chunks the tables share are skipped.
  template <class F>
  static void Diff(const BasicSlotTable& before, const BasicSlotTable& after, F&& f);

 private:
  // The least of some values and how many of them equal it, kept as values come and go; a
  // removal that leaves none at the least asks for a recount.
  struct Least {
    double value = INFINITY;
    uint32_t count = 0;
    void Add(double v) {
      if (v < value) {
        value = v;
        count = 1;
      } else if (v == value) {
        ++count;
      }
    }
    // False when the least must be recounted.
    bool Remove(double v) { return v != value || --count > 0; }
  };
  struct Chunk {
    Chunk();  // all slots free
    std::array<std::shared_ptr<const Site>, kChunk> sites;
    std::array<Point, kChunk> points;  // see point()
    Least multiplicative, additive;
    void Recount();
  };
  struct Block {
    Block();  // every chunk the shared empty one
    std::array<std::shared_ptr<const Chunk>, kBlock> chunks;
    std::array<LeastWeights, kBlock> least;  // each chunk's
  };
  struct Root {
    std::vector<std::shared_ptr<const Block>> blocks;
    std::vector<LeastWeights> least;  // each block's
  };
  static const std::shared_ptr<const Chunk>& EmptyChunk();
  static const std::shared_ptr<const Block>& EmptyBlock();
  // Block b, or the empty block past the table's end.
  const Block& block(uint32_t b) const {
    return root_ && b < root_->blocks.size() ? *root_->blocks[b] : *EmptyBlock();
  }
  const Chunk& chunk(uint32_t slot) const {
    return *root_->blocks[slot / kBlockSlots]->chunks[slot / kChunk % kBlock];
  }

  std::shared_ptr<const Root> root_;  // null while no slot was ever set
  uint32_t size_ = 0;
};

template <class K>
template <class F>
void BasicSlotTable<K>::Diff(const BasicSlotTable& before, const BasicSlotTable& after, F&& f) {
  if (before.root_ == after.root_) return;
  const uint32_t n = std::max(before.size_, after.size_);
  for (uint32_t b = 0; b * kBlockSlots < n; ++b) {
    const Block& x = before.block(b);
    const Block& y = after.block(b);
    if (&x == &y) continue;
    for (uint32_t c = 0; c < kBlock; ++c) {
      const Chunk& cx = *x.chunks[c];
      const Chunk& cy = *y.chunks[c];
      if (&cx == &cy) continue;
      const uint32_t first = (b * kBlock + c) * kChunk;
      for (uint32_t i = 0; i < kChunk && first + i < n; ++i) {
        const Site* s = cx.sites[i].get();
        const Site* t = cy.sites[i].get();
        if (s != t) f(first + i, s, t);
      }
    }
  }
}

// The 2D kernel's table, instantiated in slot_table.cc.
extern template class BasicSlotTable<Kernel2>;
using SlotTable = BasicSlotTable<Kernel2>;
// The 3D kernel's, instantiated beside it.
extern template class BasicSlotTable<Kernel3>;
using SlotTable3 = BasicSlotTable<Kernel3>;

}  // namespace gvd
