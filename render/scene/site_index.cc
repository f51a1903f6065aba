#include "render/scene/site_index.h"

#include <algorithm>

#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/iterator/function_output_iterator.hpp>

namespace gvd {
namespace {

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using BPoint = bg::model::point<double, 2, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;

BBox BoxOf(const Geometry& g) {
  Window b = BoundingBox(g);
  return BBox(BPoint(b.min_x, b.min_y), BPoint(b.max_x, b.max_y));
}

}  // namespace

struct SiteIndex::Entry {
  BBox box;
  uint32_t slot;
  bool point;  // the site is a point: its distance is that to the box's corner
  std::shared_ptr<const Site> site;
  bool operator==(const Entry& o) const { return slot == o.slot && site == o.site; }
};

namespace {
SiteIndex::Entry EntryOf(uint32_t slot, const std::shared_ptr<const Site>& site) {
  return {BoxOf(site->geometry), slot, std::holds_alternative<PointSite>(site->geometry), site};
}

// The distance from q to the entry's site (ExactDistance), without reaching a point site.
double EntryDistance(Vec2 q, const SiteIndex::Entry& e) {
  if (e.point) return Distance(q, Vec2(e.box.min_corner().get<0>(), e.box.min_corner().get<1>()));
  return ExactDistance(q, *e.site);
}

struct EntryBox {
  using result_type = BBox;
  const BBox& operator()(const SiteIndex::Entry& e) const { return e.box; }
};
}  // namespace

struct SiteIndex::Level {
  bgi::rtree<Entry, bgi::rstar<16>, EntryBox> tree;
};

SiteIndex::SiteIndex() : tail_(std::make_shared<const std::vector<Entry>>()) {}
SiteIndex::~SiteIndex() = default;
SiteIndex::SiteIndex(const SiteIndex&) = default;
SiteIndex& SiteIndex::operator=(const SiteIndex&) = default;
SiteIndex::SiteIndex(SiteIndex&&) noexcept = default;
SiteIndex& SiteIndex::operator=(SiteIndex&&) noexcept = default;

// Each live site has a live entry (Update adds one for every slot placed anew), so when
// there are no more entries than live sites, no entry is dead.
bool SiteIndex::AllLive() const { return entries_ == live_; }

bool SiteIndex::Live(const Entry& e) const {
  return e.slot < sites_.size() && sites_.ptr(e.slot) == e.site;
}

SiteIndex SiteIndex::Build(const SlotTable& sites) {
  SiteIndex index;
  index.sites_ = sites;
  index.Rebuild();
  return index;
}

void SiteIndex::Rebuild() {
  std::vector<Entry> entries;
  entries.reserve(sites_.size());
  for (uint32_t i = 0; i < sites_.size(); ++i) {
    if (const auto& s = sites_.ptr(i)) entries.push_back(EntryOf(i, s));
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

SiteIndex SiteIndex::Update(const SlotTable& sites, std::span<const uint32_t> changed) const {
  SiteIndex next = *this;
  next.sites_ = sites;
  std::vector<uint32_t> slots(changed.begin(), changed.end());
  std::sort(slots.begin(), slots.end());
  slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
  std::vector<Entry> added;
  for (uint32_t s : slots) {
    const std::shared_ptr<const Site> none;
    const auto& before = s < sites_.size() ? sites_.ptr(s) : none;
    const auto& after = s < sites.size() ? sites.ptr(s) : none;
    if (before == after) continue;
    if (before) --next.live_;
    if (after) {
      ++next.live_;
      added.push_back(EntryOf(s, after));
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

ExactNearest SiteIndex::Nearest(Vec2 q) const {
  const BPoint p(q.x, q.y);
  ExactNearest best{ExactNearest::kNone, INFINITY};
  double box_distance = INFINITY;  // the least over every live entry
  auto consider = [&](const Entry& e) {
    double b = bg::distance(e.box, p);
    box_distance = std::min(box_distance, b);
    double d = EntryDistance(q, e);
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
    double d = ExactDistance(q, *sites_.get(s));
    if (d < best.distance) best = {s, d};
  }
  return best;
}

void SiteIndex::Within(Vec2 q, double r, std::vector<uint32_t>* out) const {
  const BPoint p(q.x, q.y);
  BBox query(BPoint(q.x - r, q.y - r), BPoint(q.x + r, q.y + r));
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

}  // namespace gvd
