// A scene's sites at one version: an immutable snapshot shared by the writers that make the
// next one, the renderer that draws it, the frames rendered from it and the queries that read
// them. Slot numbers mean the same thing in every structure built from one snapshot (its
// table, its index, the id buffers of its frames), and snapshots of nearby versions share
// almost all of their storage.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "render/kernel/kernel2.h"
#include "render/kernel/kernel3.h"
#include "render/kernel/site2.h"
#include "render/scene/site_index.h"
#include "render/scene/slot_table.h"

namespace gvd {

// Site ids to slots, in id order: a persistent (copy-on-write) sorted map in leaves of up to
// 2 * kLeaf entries that versions share. Immutable once made.
class IdMap {
 public:
  static constexpr size_t kLeaf = 256;
  struct Entry {
    std::string id;
    uint32_t slot;
  };
  // (id, slot): insert or reassign; (id, nullopt): erase (an unknown id is ignored).
  using Change = std::pair<std::string, std::optional<uint32_t>>;

  size_t size() const { return size_; }
  std::optional<uint32_t> Find(std::string_view id) const;
  // The map with the changes applied. CONTRACT: changes sorted by id, ids distinct. Copies
  // only the leaves the changes fall in: O(changes + touched leaves * kLeaf + leaves).
  IdMap With(const std::vector<Change>& changes) const;
  // Calls f(entry) in id order for the ids greater than `after` (all, when empty) until f
  // returns false.
  template <class F>
  void ForEachAfter(std::string_view after, F&& f) const;

 private:
  using Leaf = std::vector<Entry>;  // sorted, never empty
  // The first leaf that can hold ids greater than `after`.
  size_t LeafAfter(std::string_view after) const;
  std::vector<std::shared_ptr<const Leaf>> leaves_;
  size_t size_ = 0;
};

// Sorts changes by id, as IdMap::With takes them.
void SortById(std::vector<IdMap::Change>* changes);

// About how many bytes a site holds in a scene: the site, its id and geometry, the segment
// tree it has or will have (IndexSegments) or a mesh's triangle tree, and its entries in the
// slot table, spatial index and id map. What the memory budget (--max-memory) charges for a
// site, the same before and after the site enters a table.
size_t SiteBytes(const Site& site);
size_t SiteBytes(const Site3& site);

// Immutable; shared between threads by shared_ptr<const SiteSnapshot>. Made by
// SnapshotBuilder. A template on the kernel (render/kernel/kernel2.h) whose sites it holds:
// SiteSnapshot is the plane's, SiteSnapshot3 space's.
template <class K>
class BasicSiteSnapshot {
 public:
  using Site = typename K::Site;
  using Point = typename K::Point;
  using Table = BasicSlotTable<K>;
  using Index = BasicSiteIndex<K>;

  // No sites.
  static std::shared_ptr<const BasicSiteSnapshot> Empty(uint64_t version);
  // The sites in slots 0..n-1, in order. CONTRACT: ids distinct.
  static std::shared_ptr<const BasicSiteSnapshot> Of(uint64_t version, std::vector<Site> sites);

  uint64_t version() const { return version_; }
  size_t size() const { return index_.size(); }  // live sites
  bool empty() const { return size() == 0; }
  const Table& sites() const { return index_.sites(); }
  const Index& index() const { return index_; }
  const IdMap& ids() const { return ids_; }
  // The slot of a site id, if it is a site of this version.
  std::optional<uint32_t> Find(std::string_view id) const { return ids_.Find(id); }
  // Whether every site is plain (Site::plain): then the nearest site is the nearest by
  // Euclidean distance alone.
  bool plain() const { return non_plain_ == 0; }
  // The least weights over the sites (SlotTable::least), found once when the version is
  // built, for the queries that bound their search with them.
  const LeastWeights& least() const { return least_; }
  // How far a site's exact value `value` at a point may be from the truth: 0 unless the
  // version holds curves, which are measured within BezierDistanceError of the truth (twice
  // that here, for the value and the values it was compared with), or paths that stand for
  // a shape within their approximation (K::ShapeError). Their extent and shape error are the
  // largest since the scene last held no curve (a removal does not lower them).
  double CurveError(double value) const {
    return curves_ == 0 ? 0 : 2 * BezierDistanceError(std::abs(value), curve_extent_) + shape_error_;
  }
  // The summed length of the sites' segments (TotalLength): how much line the coverage's
  // tiles must resolve (DefaultTilePx).
  double ink() const { return ink_; }
  // The bytes its sites hold (SiteBytes summed), for the memory budget.
  size_t bytes() const { return bytes_; }
  // In a NEAREST diagram: given a site `best` whose value at q is `value` (finite), makes
  // them the best site at q and its value, exactly (least slot on ties). Only a site within
  // (value - least additive) / least multiplicative of q can beat the value (m d + a < V
  // needs d < (V - a) / m), and the index finds those. `scratch` is reused between calls.
  void Improve(Point q, uint32_t* best, double* value, std::vector<uint32_t>* scratch) const;

 private:
  template <class>
  friend class BasicSnapshotBuilder;
  BasicSiteSnapshot() = default;

  uint64_t version_ = 0;
  Index index_;
  IdMap ids_;
  size_t non_plain_ = 0;
  size_t curves_ = 0;  // sites with a tolerance
  double curve_extent_ = 0;
  double shape_error_ = 0;
  double ink_ = 0;
  size_t bytes_ = 0;
  LeastWeights least_;
};

// An upsert (site set) or a deletion (site empty) of the site `id`.
template <class K>
struct BasicSiteChange {
  using Site = typename K::Site;
  BasicSiteChange(std::string id, std::optional<Site> site)
      : id(std::move(id)), site(std::move(site)) {}
  // An upsert of a plain site.
  BasicSiteChange(std::string id, typename K::Geometry geometry)
      : id(std::move(id)), site(Site{this->id, std::move(geometry)}) {}
  std::string id;
  std::optional<Site> site;
};

// Makes the next snapshot from a base: the one way sites change. Not thread-safe; the base
// is not modified.
//
// Slots. A new id takes a slot from `free_slots` (the scene's list of slots free in the base,
// kept by its single writer) or the next slot past the base's table. Slots freed by Remove are
// listed by freed() and are the caller's to return to its list once the snapshot is
// published; Abandon() returns the slots taken, for a change that is not published.
template <class K>
class BasicSnapshotBuilder {
 public:
  using Site = typename K::Site;
  using Snapshot = BasicSiteSnapshot<K>;
  BasicSnapshotBuilder(std::shared_ptr<const Snapshot> base, std::vector<uint32_t>* free_slots);

  // Makes room for `puts` more Puts, for a caller that knows how many come.
  void Reserve(size_t puts);
  // Inserts or replaces the site with this id. CONTRACT: each id at most once per builder.
  void Put(Site site);
  // Removes the site; false (and nothing changes) when the id is not a site of the base.
  bool Remove(std::string_view id);
  void Apply(BasicSiteChange<K> change);

  // Live sites once the changes are made.
  size_t size() const { return size_; }
  const std::vector<uint32_t>& freed() const { return freed_; }
  // The sites put and the ids removed so far, in call order: what a store commits.
  const std::vector<std::shared_ptr<const Site>>& put() const { return put_; }
  const std::vector<std::string>& removed() const { return removed_; }

  // The snapshot at `version`. Call once. It leaves put() and removed() as they are: another
  // thread may read them meanwhile.
  std::shared_ptr<const Snapshot> Build(uint64_t version);
  // Gives the slots taken from `free_slots` back, when the change is not published (after
  // Build too, if its snapshot is dropped).
  void Abandon();

 private:
  std::shared_ptr<const Snapshot> base_;
  std::vector<uint32_t>* free_slots_;
  BasicSlotTable<K> table_;
  uint32_t next_slot_;
  size_t size_;
  size_t non_plain_;
  size_t curves_;
  double curve_extent_;
  double shape_error_;
  double ink_;
  size_t bytes_;
  std::vector<uint32_t> changed_, taken_, freed_;
  std::vector<IdMap::Change> id_changes_;
  std::vector<std::shared_ptr<const Site>> put_;
  std::vector<std::string> removed_;
};

// `base` with the changes applied in order (a later change of an id overrides an earlier
// one; deleting an unknown id does nothing), at base's version + 1: for callers with no
// writer of their own (tests, benchmarks, one-off renders). `free_slots` is the list of
// slots free in base, updated for the result.
template <class K>
std::shared_ptr<const BasicSiteSnapshot<K>> Advance(
    const std::shared_ptr<const BasicSiteSnapshot<K>>& base,
    std::vector<BasicSiteChange<K>> changes, std::vector<uint32_t>* free_slots);

// The plane's, instantiated in snapshot.cc.
extern template class BasicSiteSnapshot<Kernel2>;
extern template class BasicSnapshotBuilder<Kernel2>;
using SiteSnapshot = BasicSiteSnapshot<Kernel2>;
using SnapshotBuilder = BasicSnapshotBuilder<Kernel2>;
using SiteChange = BasicSiteChange<Kernel2>;
// Space's, beside them.
extern template class BasicSiteSnapshot<Kernel3>;
extern template class BasicSnapshotBuilder<Kernel3>;
using SiteSnapshot3 = BasicSiteSnapshot<Kernel3>;
using SnapshotBuilder3 = BasicSnapshotBuilder<Kernel3>;
using SiteChange3 = BasicSiteChange<Kernel3>;

// ---- implementation ----

template <class F>
void IdMap::ForEachAfter(std::string_view after, F&& f) const {
  for (size_t l = LeafAfter(after); l < leaves_.size(); ++l) {
    for (const Entry& e : *leaves_[l]) {
      if (!after.empty() && e.id.compare(after) <= 0) continue;
      if (!f(e)) return;
    }
  }
}

}  // namespace gvd
