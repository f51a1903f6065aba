#include "render/scene/site_index.h"

#include <algorithm>
#include <utility>

#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/iterator/function_output_iterator.hpp>

namespace gvd {
namespace {

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

// Boost.Geometry's view of kernel K: its points and boxes.
template <class K>
struct Boost {
  using Point = bg::model::point<double, K::kDimension, bg::cs::cartesian>;
  using Box = bg::model::box<Point>;
  static Point Of(typename K::Point p) {
    Point out;
    Set(out, [&](int axis) { return K::At(p, axis); });
    return out;
  }
  static Box Of(const typename K::Box& b) {
    Box out;
    Set(out.min_corner(), [&](int axis) { return K::Min(b, axis); });
    Set(out.max_corner(), [&](int axis) { return K::Max(b, axis); });
    return out;
  }
  // The box of the points within r of p, on every axis.
  static Box Around(typename K::Point p, double r) {
    Box out;
    Set(out.min_corner(), [&](int axis) { return K::At(p, axis) - r; });
    Set(out.max_corner(), [&](int axis) { return K::At(p, axis) + r; });
    return out;
  }
  // The corner of a box as a kernel point.
  static typename K::Point Corner(const Box& b) {
    typename K::Point out;
    Get(b.min_corner(), out, std::make_index_sequence<K::kDimension>());
    return out;
  }

 private:
  template <class F, size_t... I>
  static void SetAll(Point& p, F&& f, std::index_sequence<I...>) {
    (bg::set<I>(p, f(static_cast<int>(I))), ...);
  }
  template <class F>
  static void Set(Point& p, F&& f) {
    SetAll(p, f, std::make_index_sequence<K::kDimension>());
  }
  template <size_t... I>
  static void Get(const Point& p, typename K::Point& out, std::index_sequence<I...>) {
    ((out[I] = bg::get<I>(p)), ...);
  }
};

}  // namespace

template <class K>
struct BasicSiteIndex<K>::Entry {
  typename Boost<K>::Box box;
  uint32_t slot;
  bool point;  // the site is a point: its distance is that to the box's corner
  std::shared_ptr<const typename K::Site> site;
  bool operator==(const Entry& o) const { return slot == o.slot && site == o.site; }
};

namespace {

template <class K>
typename BasicSiteIndex<K>::Entry EntryOf(uint32_t slot,
                                          const std::shared_ptr<const typename K::Site>& site) {
  return {Boost<K>::Of(K::BoxOf(*site)), slot, K::PointOf(*site).has_value(), site};
}

// The distance from q to the entry's site, without reaching a point site.
template <class K>
double EntryDistance(typename K::Point q, const typename BasicSiteIndex<K>::Entry& e) {
  if (e.point) return Distance(q, Boost<K>::Corner(e.box));
  return K::Distance(q, *e.site);
}

template <class K>
struct EntryBox {
  using result_type = typename Boost<K>::Box;
  const result_type& operator()(const typename BasicSiteIndex<K>::Entry& e) const { return e.box; }
};

}  // namespace

template <class K>
struct BasicSiteIndex<K>::Level {
  bgi::rtree<Entry, bgi::rstar<16>, EntryBox<K>> tree;
};

template <class K>
BasicSiteIndex<K>::BasicSiteIndex() : tail_(std::make_shared<const std::vector<Entry>>()) {}
template <class K>
BasicSiteIndex<K>::~BasicSiteIndex() = default;
template <class K>
BasicSiteIndex<K>::BasicSiteIndex(const BasicSiteIndex&) = default;
template <class K>
BasicSiteIndex<K>& BasicSiteIndex<K>::operator=(const BasicSiteIndex&) = default;
template <class K>
BasicSiteIndex<K>::BasicSiteIndex(BasicSiteIndex&&) noexcept = default;
template <class K>
BasicSiteIndex<K>& BasicSiteIndex<K>::operator=(BasicSiteIndex&&) noexcept = default;

// Each live site has a live entry (Update adds one for every slot placed anew), so when
// there are no more entries than live sites, no entry is dead.
template <class K>
bool BasicSiteIndex<K>::AllLive() const { return entries_ == live_; }

template <class K>
bool BasicSiteIndex<K>::Live(const Entry& e) const {
  return e.slot < sites_.size() && sites_.ptr(e.slot) == e.site;
}

template <class K>
BasicSiteIndex<K> BasicSiteIndex<K>::Build(const Table& sites) {
  BasicSiteIndex index;
  index.sites_ = sites;
  index.Rebuild();
  return index;
}

template <class K>
void BasicSiteIndex<K>::Rebuild() {
  std::vector<Entry> entries;
  entries.reserve(sites_.size());
  for (uint32_t i = 0; i < sites_.size(); ++i) {
    if (const auto& s = sites_.ptr(i)) entries.push_back(EntryOf<K>(i, s));
  }
  live_ = entries_ = entries.size();
  levels_.clear();
  tail_ = std::make_shared<const std::vector<Entry>>();
  if (entries.size() <= kTail) {
    tail_ = std::make_shared<const std::vector<Entry>>(std::move(entries));
    return;
  }
  auto level = std::make_shared<Level>();
  level->tree = decltype(level->tree)(entries);  // packing bulk load
  // Placed at the first level with room, so that the levels below fill before it is redone.
  size_t i = 0;
  for (size_t cap = kTail * 4; cap < entries.size(); cap *= 4) ++i;
  levels_.resize(i + 1);
  levels_[i] = std::move(level);
}

template <class K>
BasicSiteIndex<K> BasicSiteIndex<K>::Update(const Table& sites,
                                            std::span<const uint32_t> changed) const {
  BasicSiteIndex next = *this;
  next.sites_ = sites;
  std::vector<uint32_t> slots(changed.begin(), changed.end());
  std::sort(slots.begin(), slots.end());
  slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
  std::vector<Entry> added;
  added.reserve(slots.size());
  for (uint32_t s : slots) {
    const std::shared_ptr<const typename K::Site> none;
    const auto& before = s < sites_.size() ? sites_.ptr(s) : none;
    const auto& after = s < sites.size() ? sites.ptr(s) : none;
    if (before == after) continue;
    if (before) --next.live_;
    if (after) {
      ++next.live_;
      added.push_back(EntryOf<K>(s, after));
    }
  }
  next.entries_ += added.size();
  // Dead entries cost every query a visit: past one per live site, start over.
  if (next.entries_ > 2 * next.live_ + kTail) {
    next.Rebuild();
    return next;
  }
  if (added.empty()) return next;
  if (tail_->size() + added.size() <= kTail) {
    auto tail = std::make_shared<std::vector<Entry>>(*tail_);
    tail->insert(tail->end(), added.begin(), added.end());
    next.tail_ = std::move(tail);
    return next;
  }
  // Carry the tail (and the new entries) down into the first level with room, taking along
  // the live entries of the full levels passed on the way.
  std::vector<Entry> carry = std::move(added);
  for (const Entry& e : *tail_) {
    if (next.Live(e)) carry.push_back(e);
  }
  next.tail_ = std::make_shared<const std::vector<Entry>>();
  size_t i = 0;
  for (size_t cap = kTail * 4;; ++i, cap *= 4) {
    if (i == next.levels_.size()) next.levels_.emplace_back();
    if (next.levels_[i]) {
      for (const Entry& e : next.levels_[i]->tree) {
        if (next.Live(e)) carry.push_back(e);
      }
      next.levels_[i] = nullptr;
    }
    if (carry.size() <= cap) break;
  }
  auto level = std::make_shared<Level>();
  level->tree = decltype(level->tree)(carry);
  next.levels_[i] = std::move(level);
  // Entries dropped as dead on the way are gone.
  size_t entries = 0;
  for (const auto& l : next.levels_) entries += l ? l->tree.size() : 0;
  next.entries_ = entries;
  return next;
}

template <class K>
ExactNearest BasicSiteIndex<K>::Nearest(Point q) const {
  const auto p = Boost<K>::Of(q);
  ExactNearest best{ExactNearest::kNone, INFINITY};
  double box_distance = INFINITY;  // the least over every live entry
  auto consider = [&](const Entry& e) {
    double b = bg::distance(e.box, p);
    box_distance = std::min(box_distance, b);
    double d = EntryDistance<K>(q, e);
    if (d < best.distance || best.index == ExactNearest::kNone) best = {e.slot, d};
  };
  const bool all_live = AllLive();
  for (const Entry& e : *tail_) {
    if (all_live || Live(e)) consider(e);
  }
  for (const auto& level : levels_) {
    if (!level) continue;
    auto out = boost::make_function_output_iterator(consider);
    if (all_live) {
      level->tree.query(bgi::nearest(p, 1), out);
    } else {
      level->tree.query(bgi::nearest(p, 1) && bgi::satisfies([&](const Entry& e) { return Live(e); }),
                        out);
    }
  }
  // Boxes bound distances from below, and each tree gave its nearest box: when the best site
  // is as near as the nearest box of all (a point always is), no other site can be nearer.
  // Otherwise every site nearer than `best` has its box within best.distance of q.
  if (best.distance <= box_distance) return best;
  std::vector<uint32_t> nearer;
  Within(q, best.distance, &nearer);
  for (uint32_t s : nearer) {
    double d = K::Distance(q, *sites_.get(s));
    if (d < best.distance) best = {s, d};
  }
  return best;
}

template <class K>
void BasicSiteIndex<K>::Within(Point q, double r, std::vector<uint32_t>* out) const {
  const auto p = Boost<K>::Of(q);
  const auto query = Boost<K>::Around(q, r);
  const double r2 = r * r;
  auto near = [&](const Entry& e) { return bg::comparable_distance(e.box, p) <= r2; };
  const bool all_live = AllLive();
  for (const Entry& e : *tail_) {
    if ((all_live || Live(e)) && near(e)) out->push_back(e.slot);
  }
  for (const auto& level : levels_) {
    if (!level) continue;
    level->tree.query(bgi::intersects(query) && bgi::satisfies([&](const Entry& e) {
                        return (all_live || Live(e)) && near(e);
                      }),
                      boost::make_function_output_iterator(
                          [&](const Entry& e) { out->push_back(e.slot); }));
  }
}

template class BasicSiteIndex<Kernel2>;
template class BasicSiteIndex<Kernel3>;

}  // namespace gvd
