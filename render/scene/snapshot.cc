#include "render/scene/snapshot.h"

#include <algorithm>
#include <map>

#include "render/scene/cpu_pool.h"
#include "render/scene/id_order.h"
#include "render/kernel/mesh_regions.h"
#include "render/kernel/segment_tree.h"

namespace gvd {

// ---- IdMap ----

size_t IdMap::LeafAfter(std::string_view after) const {
  // The last leaf whose first id is <= after holds the ids just above it (or none do).
  auto it = std::upper_bound(leaves_.begin(), leaves_.end(), after,
                             [](std::string_view a, const std::shared_ptr<const Leaf>& leaf) {
                               return a < leaf->front().id;
                             });
  return it == leaves_.begin() ? 0 : static_cast<size_t>(it - leaves_.begin()) - 1;
}

std::optional<uint32_t> IdMap::Find(std::string_view id) const {
  if (leaves_.empty()) return std::nullopt;
  const Leaf& leaf = *leaves_[LeafAfter(id)];
  auto it = std::lower_bound(leaf.begin(), leaf.end(), id,
                             [](const Entry& e, std::string_view x) { return e.id < x; });
  if (it == leaf.end() || it->id != id) return std::nullopt;
  return it->slot;
}

IdMap IdMap::With(const std::vector<Change>& changes) const {
  IdMap out;
  out.size_ = size_;
  out.leaves_.reserve(leaves_.size() + changes.size() / kLeaf + 1);
  auto emit = [&out](Leaf&& merged) {
    // Split into leaves of kLeaf when it outgrew 2 * kLeaf; drop it when it emptied.
    for (size_t b = 0; b < merged.size();) {
      size_t e = merged.size() - b <= 2 * kLeaf ? merged.size() : b + kLeaf;
      out.leaves_.push_back(std::make_shared<const Leaf>(
          std::make_move_iterator(merged.begin() + b), std::make_move_iterator(merged.begin() + e)));
      b = e;
    }
  };
  // Each change goes to the leaf holding the greatest first id <= its id (or leaf 0), found
  // by binary search; the leaves between changed ones are shared as they are.
  size_t shared = 0;  // leaves_[0, shared) are in out
  for (size_t c = 0; c < changes.size();) {
    const size_t l = leaves_.empty() ? 0 : LeafAfter(changes[c].first);
    out.leaves_.insert(out.leaves_.end(), leaves_.begin() + shared, leaves_.begin() + l);
    const bool last = l + 1 >= leaves_.size();
    size_t end = c;
    while (end < changes.size() && (last || changes[end].first < leaves_[l + 1]->front().id)) ++end;
    static const Leaf kNone;
    const Leaf& old = leaves_.empty() ? kNone : *leaves_[l];
    Leaf merged;
    merged.reserve(old.size() + (end - c));
    size_t i = 0;
    for (; c < end; ++c) {
      const auto& [id, slot] = changes[c];
      while (i < old.size() && old[i].id < id) merged.push_back(old[i++]);
      const bool present = i < old.size() && old[i].id == id;
      if (present) ++i;
      if (slot) merged.push_back({id, *slot});
    }
    while (i < old.size()) merged.push_back(old[i++]);
    out.size_ = out.size_ - old.size() + merged.size();
    emit(std::move(merged));
    shared = std::min(l + 1, leaves_.size());
  }
  out.leaves_.insert(out.leaves_.end(), leaves_.begin() + shared, leaves_.end());
  return out;
}

void SortById(std::vector<IdMap::Change>* changes) {
  // Each change moved once into place: no string is moved per step of the sort.
  std::vector<IdMap::Change>& c = *changes;
  const std::vector<uint32_t> order =
      IdOrder(c.size(), [&](size_t k) -> std::string_view { return c[k].first; });
  std::vector<IdMap::Change> sorted;
  sorted.reserve(c.size());
  for (uint32_t k : order) sorted.push_back(std::move(c[k]));
  c = std::move(sorted);
}

// ---- SiteSnapshot ----

template <class K>
std::shared_ptr<const BasicSiteSnapshot<K>> BasicSiteSnapshot<K>::Empty(uint64_t version) {
  std::shared_ptr<BasicSiteSnapshot> s(new BasicSiteSnapshot);
  s->version_ = version;
  return s;
}

template <class K>
void BasicSiteSnapshot<K>::Improve(Point q, uint32_t* best, double* value,
                                   std::vector<uint32_t>* scratch) const {
  scratch->clear();
  index_.Within(q, (*value - least_.additive) / least_.multiplicative * (1 + 1e-12), scratch);
  for (uint32_t s : *scratch) {
    const double v = K::Value(q, *sites().get(s));
    if (v < *value || (v == *value && s < *best)) {
      *best = s;
      *value = v;
    }
  }
}

template <class K>
std::shared_ptr<const BasicSiteSnapshot<K>> BasicSiteSnapshot<K>::Of(uint64_t version,
                                                                   std::vector<Site> sites) {
  std::vector<uint32_t> free_slots;
  BasicSnapshotBuilder<K> b(Empty(0), &free_slots);
  for (Site& s : sites) b.Put(std::move(s));
  return b.Build(version);
}

// ---- SnapshotBuilder ----

template <class K>
BasicSnapshotBuilder<K>::BasicSnapshotBuilder(std::shared_ptr<const Snapshot> base,
                                              std::vector<uint32_t>* free_slots)
    : base_(std::move(base)),
      free_slots_(free_slots),
      table_(base_->sites()),
      next_slot_(base_->sites().size()),
      size_(base_->size()),
      non_plain_(base_->non_plain_),
      curves_(base_->curves_),
      curve_extent_(base_->curve_extent_),
      shape_error_(base_->shape_error_),
      ink_(base_->ink_),
      bytes_(base_->bytes_) {}

template <class K>
void BasicSnapshotBuilder<K>::Reserve(size_t puts) {
  changed_.reserve(changed_.size() + puts);
  put_.reserve(put_.size() + puts);
  id_changes_.reserve(id_changes_.size() + puts);
}

template <class K>
void BasicSnapshotBuilder<K>::Put(Site site) {
  uint32_t slot;
  if (auto found = base_->Find(site.id)) {
    slot = *found;
    non_plain_ -= !base_->sites().get(slot)->plain();
    curves_ -= K::Tolerance(*base_->sites().get(slot)) > 0;
    ink_ -= K::Ink(*base_->sites().get(slot));
    bytes_ -= SiteBytes(*base_->sites().get(slot));
  } else {
    if (!free_slots_->empty()) {
      slot = free_slots_->back();
      free_slots_->pop_back();
      taken_.push_back(slot);
    } else {
      slot = next_slot_++;
    }
    id_changes_.emplace_back(site.id, slot);
    ++size_;
  }
  non_plain_ += !site.plain();
  if (K::Tolerance(site) > 0) {
    ++curves_;
    curve_extent_ = std::max(curve_extent_, K::CurveExtent(site));
    shape_error_ = std::max(shape_error_, K::ShapeError(site));
  }
  ink_ += K::Ink(site);
  bytes_ += SiteBytes(site);
  changed_.push_back(slot);
  table_.Set(slot, std::optional<Site>(std::move(site)));
  put_.push_back(table_.ptr(slot));
}

template <class K>
bool BasicSnapshotBuilder<K>::Remove(std::string_view id) {
  auto found = base_->Find(id);
  if (!found || table_.get(*found) == nullptr) return false;
  non_plain_ -= !table_.get(*found)->plain();
  curves_ -= K::Tolerance(*table_.get(*found)) > 0;
  ink_ -= K::Ink(*table_.get(*found));
  bytes_ -= SiteBytes(*table_.get(*found));
  table_.Set(*found, std::shared_ptr<const Site>());
  changed_.push_back(*found);
  freed_.push_back(*found);
  id_changes_.emplace_back(std::string(id), std::nullopt);
  removed_.emplace_back(id);
  --size_;
  return true;
}

template <class K>
void BasicSnapshotBuilder<K>::Apply(BasicSiteChange<K> change) {
  if (change.site) {
    change.site->id = std::move(change.id);
    Put(std::move(*change.site));
  } else {
    Remove(change.id);
  }
}

template <class K>
std::shared_ptr<const BasicSiteSnapshot<K>> BasicSnapshotBuilder<K>::Build(uint64_t version) {
  std::shared_ptr<Snapshot> s(new Snapshot);
  s->version_ = version;
  s->non_plain_ = non_plain_;
  s->curves_ = curves_;
  s->curve_extent_ = curves_ == 0 ? 0 : curve_extent_;
  s->shape_error_ = curves_ == 0 ? 0 : shape_error_;
  // Rounding of the sums must not leave a little ink in an emptied scene.
  s->ink_ = size_ == 0 ? 0 : std::max(0.0, ink_);
  s->bytes_ = bytes_;
  auto index = [&] {
    s->index_ = base_->index_.Update(table_, changed_);
    s->least_ = table_.least();
  };
  auto ids = [&] {
    SortById(&id_changes_);
    s->ids_ = base_->ids_.With(id_changes_);
  };
  // Bulk changes build the index and the id map side by side; small ones on this thread.
  constexpr size_t kSideBySide = 4096;
  ParallelFor(2, changed_.size() >= kSideBySide ? 1 : 2, [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) k == 0 ? index() : ids();
  });
  return s;
}

template <class K>
void BasicSnapshotBuilder<K>::Abandon() {
  free_slots_->insert(free_slots_->end(), taken_.rbegin(), taken_.rend());
  taken_.clear();
}

template <class K>
std::shared_ptr<const BasicSiteSnapshot<K>> Advance(
    const std::shared_ptr<const BasicSiteSnapshot<K>>& base,
    std::vector<BasicSiteChange<K>> changes, std::vector<uint32_t>* free_slots) {
  std::map<std::string, std::optional<typename K::Site>> last;
  for (BasicSiteChange<K>& c : changes) last[c.id] = std::move(c.site);
  BasicSnapshotBuilder<K> builder(base, free_slots);
  for (auto& [id, site] : last) builder.Apply({id, std::move(site)});
  auto next = builder.Build(base->version() + 1);
  free_slots->insert(free_slots->end(), builder.freed().rbegin(), builder.freed().rend());
  return next;
}

size_t SiteBytes(const Site& site) {
  // Per site: the shared Site and its control block, a slot's pointer and point, a spatial
  // index entry, an id-map entry (with the id again) and the allocator's overhead on each.
  // Measured: 200,000 points added about 430 bytes each to the server's resident memory.
  // Per segment of a tree: its two ends, its pieces' indexes and its share of the nodes.
  constexpr size_t kEntries = 288;
  constexpr size_t kTreePerSegment = 112;
  size_t bytes = sizeof(Site) + kEntries + 2 * site.id.size();
  size_t segments = 0;
  std::visit(
      [&](const auto& g) {
        using G = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<G, PolylineSite>) {
          bytes += g.points.size() * sizeof(Vec2);
          segments = g.points.size() - 1;
        } else if constexpr (std::is_same_v<G, PolygonSite>) {
          bytes += g.vertices.size() * sizeof(Vec2);
          segments = g.vertices.size();
        } else if constexpr (std::is_same_v<G, BezierSite>) {
          bytes += (g.control.size() + g.flat.size()) * sizeof(Vec2);
          segments = g.flat.empty() ? 0 : g.flat.size() - 1;
        } else if constexpr (std::is_same_v<G, PathSite>) {
          for (const Subpath& s : g.subpaths) bytes += s.points.size() * sizeof(Vec2) + s.degrees.size();
          bytes += g.subpaths.size() * sizeof(Subpath) + g.pieces.size() * sizeof(PathPiece) +
                   g.flat.size() * sizeof(Vec2);
          segments = g.flat.size() - g.pieces.size();
        }
      },
      site.geometry);
  if (segments >= SegmentTree::kMinSegments) bytes += sizeof(SegmentTree) + segments * kTreePerSegment;
  return bytes;
}

size_t SiteBytes(const Site3& site) {
  // As a 2D site's entries; a mesh adds its vertices, triangles, edge tables and triangle
  // tree (TriangleTree::bytes) and its features' regions (MeshRegions::bytes).
  constexpr size_t kEntries = 320;
  size_t bytes = sizeof(Site3) + kEntries + 2 * site.id.size();
  if (const auto* mesh = std::get_if<MeshSite3>(&site.geometry)) {
    bytes += mesh->vertices.size() * sizeof(Vec3) +
             mesh->triangles.size() * (2 * sizeof(mesh->triangles[0])) +
             mesh->edges.size() * sizeof(mesh->edges[0]) +
             (mesh->tree ? mesh->tree->bytes() : 0) +
             (mesh->regions ? mesh->regions->bytes() : 0);
  }
  return bytes;
}

template class BasicSiteSnapshot<Kernel2>;
template class BasicSnapshotBuilder<Kernel2>;
template std::shared_ptr<const SiteSnapshot> Advance(const std::shared_ptr<const SiteSnapshot>&,
                                                     std::vector<SiteChange>,
                                                     std::vector<uint32_t>*);
template class BasicSiteSnapshot<Kernel3>;
template class BasicSnapshotBuilder<Kernel3>;
template std::shared_ptr<const SiteSnapshot3> Advance(const std::shared_ptr<const SiteSnapshot3>&,
                                                      std::vector<SiteChange3>,
                                                      std::vector<uint32_t>*);

}  // namespace gvd
