// A spatial index of sites by bounding box, for finding the sites that can be nearest within
// a region, and exact nearest sites. Persistent: an index is an immutable value, and the
// index of the next version of a slot table is made from this one in time that follows the
// change, not the table (Update), while both stay valid and share most of their storage. A
// template on the kernel whose sites it indexes (render/kernel/kernel2.h); SiteIndex is the 2D
// kernel's.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "render/kernel/kernel2.h"
#include "render/kernel/kernel3.h"
#include "render/scene/slot_table.h"

namespace gvd {

// The exact nearest site to a point, as the index finds it.
struct ExactNearest {
  static constexpr size_t kNone = std::numeric_limits<size_t>::max();
  size_t index = kNone;  // the site (SiteIndex::Nearest: its slot); kNone when none is a candidate
  double distance = 0;   // its value at q
  bool found() const { return index != kNone; }
};

// Immutable; concurrent calls are safe, and copies are cheap (they share their trees).
//
// How. Entries (a box, a slot and the site it held) live in a short unsorted tail and in
// levels of Boost.Geometry R*-trees built in bulk, level i holding at most kTail * 4^(i+1)
// entries, as in the logarithmic method (Bentley and Saxe). A change adds entries for the
// slots placed anew; an entry is live while the index's table still holds its site in its
// slot (by identity: the entry keeps the site alive, so its address cannot be reused), and
// dead entries are skipped by every query and dropped when their level is rebuilt. When the
// tail overflows it is merged into the first level with room, rebuilding the levels below
// it; when dead entries outnumber live ones, everything is rebuilt. Each entry is rebuilt
// O(log n) times between full rebuilds, so an update costs amortized O(log^2 n) per changed
// slot, and a query visits O(log n) trees.
template <class K>
class BasicSiteIndex {
 public:
  using Point = typename K::Point;
  using Table = BasicSlotTable<K>;
  static constexpr size_t kTail = 64;

  BasicSiteIndex();  // empty
  ~BasicSiteIndex();
  BasicSiteIndex(const BasicSiteIndex&);
  BasicSiteIndex& operator=(const BasicSiteIndex&);
  BasicSiteIndex(BasicSiteIndex&&) noexcept;
  BasicSiteIndex& operator=(BasicSiteIndex&&) noexcept;

  // An index of every live slot of the table. O(n log n), bulk loaded.
  static BasicSiteIndex Build(const Table& sites);
  // The index of `sites`, a table that differs from this index's table only in the slots
  // `changed` (placed, replaced or freed; repeats allowed). This index is left as it was.
  BasicSiteIndex Update(const Table& sites, std::span<const uint32_t> changed) const;

  size_t size() const { return live_; }  // live sites
  const Table& sites() const { return sites_; }

  // The exact nearest site to q (ties: either); `index` is its slot. CONTRACT: size() > 0.
  ExactNearest Nearest(Point q) const;

  // Appends the slots of the sites whose bounding boxes come within r of q: a superset of
  // the sites within r of q.
  void Within(Point q, double r, std::vector<uint32_t>* out) const;

  struct Entry;  // defined in the .cc

 private:
  struct Level;

  bool Live(const Entry& e) const;
  bool AllLive() const;
  void Rebuild();

  Table sites_;
  std::shared_ptr<const std::vector<Entry>> tail_;
  std::vector<std::shared_ptr<const Level>> levels_;  // null: empty level
  size_t live_ = 0;
  size_t entries_ = 0;  // in the tail and the levels, dead ones included
};

// The 2D kernel's index, instantiated in site_index.cc.
extern template class BasicSiteIndex<Kernel2>;
using SiteIndex = BasicSiteIndex<Kernel2>;
// The 3D kernel's, instantiated beside it.
extern template class BasicSiteIndex<Kernel3>;
using SiteIndex3 = BasicSiteIndex<Kernel3>;

}  // namespace gvd
