#include "render/site_index.h"

#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/iterator/function_output_iterator.hpp>

namespace gvd {
namespace {

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using BPoint = bg::model::point<double, 2, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using Entry = std::pair<BBox, uint32_t>;

BBox BoxOf(const Geometry& g) {
  Window b = BoundingBox(g);
  return BBox(BPoint(b.min_x, b.min_y), BPoint(b.max_x, b.max_y));
}

}  // namespace

struct SiteIndex::Tree {
  bgi::rtree<Entry, bgi::rstar<16>> rtree;
};

SiteIndex::SiteIndex() : tree_(std::make_unique<Tree>()) {}
SiteIndex::~SiteIndex() = default;
SiteIndex::SiteIndex(SiteIndex&&) noexcept = default;
SiteIndex& SiteIndex::operator=(SiteIndex&&) noexcept = default;

SiteIndex SiteIndex::Build(const SlotTable& sites) {
  std::vector<Entry> entries;
  entries.reserve(sites.size());
  for (uint32_t i = 0; i < sites.size(); ++i) {
    if (const Site* s = sites.get(i)) entries.emplace_back(BoxOf(s->geometry), i);
  }
  SiteIndex index;
  index.tree_->rtree = bgi::rtree<Entry, bgi::rstar<16>>(entries);  // packing bulk load
  return index;
}

void SiteIndex::Insert(uint32_t slot, const Geometry& g) { tree_->rtree.insert({BoxOf(g), slot}); }

void SiteIndex::Remove(uint32_t slot, const Geometry& g) { tree_->rtree.remove({BoxOf(g), slot}); }

size_t SiteIndex::size() const { return tree_->rtree.size(); }

ExactNearest SiteIndex::Nearest(Vec2 q, const SlotTable& sites) const {
  const BPoint p(q.x, q.y);
  ExactNearest best{0, INFINITY};
  double box_distance = 0;
  tree_->rtree.query(bgi::nearest(p, 1), boost::make_function_output_iterator([&](const Entry& e) {
                       best = {e.second, ExactDistance(q, sites.get(e.second)->geometry)};
                       box_distance = bg::distance(e.first, p);
                     }));
  // Boxes bound distances from below: when the nearest box's site is as near as its box (a
  // point always is), no other site can be nearer. Otherwise every site nearer than `best`
  // has its box within best.distance of q.
  if (best.distance <= box_distance) return best;
  std::vector<uint32_t> nearer;
  Within(q, best.distance, &nearer);
  for (uint32_t s : nearer) {
    double d = ExactDistance(q, sites.get(s)->geometry);
    if (d < best.distance) best = {s, d};
  }
  return best;
}

void SiteIndex::Within(Vec2 q, double r, std::vector<uint32_t>* out) const {
  const BPoint p(q.x, q.y);
  BBox query(BPoint(q.x - r, q.y - r), BPoint(q.x + r, q.y + r));
  const double r2 = r * r;
  tree_->rtree.query(bgi::intersects(query) && bgi::satisfies([&](const Entry& e) {
                       return bg::comparable_distance(e.first, p) <= r2;
                     }),
                     boost::make_function_output_iterator([&](const Entry& e) {
                       out->push_back(e.second);
                     }));
}

}  // namespace gvd
