// Voronoi sites as the render layer sees them: an id and a geometry.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "geometry/geometry.h"

namespace gvd {

struct PointSite {
  Vec2 p;
};

// A closed segment; a == b is allowed (it is then a point).
struct SegmentSite {
  Vec2 a, b;
};

// An open chain of segments through `points` (at least two; repeats allowed).
struct PolylineSite {
  std::vector<Vec2> points;
};

// Where a polygon's distance function is defined (paper sec. 4.3).
enum class Side : uint8_t { kBoth, kOutside, kInside };

// A closed chain: edge i runs from vertex i to vertex i + 1 (mod n); at least three
// vertices, repeats allowed. Its distance is the distance to that boundary. Inside and
// outside follow the even-odd rule, so a self-intersecting polygon is well defined; one of
// zero area has no inside. With kOutside (kInside) the polygon is a candidate only at points
// outside (inside) it, or on its boundary.
struct PolygonSite {
  std::vector<Vec2> vertices;
  Side side = Side::kBoth;
};

// A quadratic (3 control points) or cubic (4) Bezier curve, represented by `flat`: a
// polyline through points of the curve within `tolerance` of it (see Flatten in exact.h).
// Distances to the site are distances to `flat`.
struct BezierSite {
  std::vector<Vec2> control;
  double tolerance = 0;
  std::vector<Vec2> flat;
};

// Every site kind; new kinds are added here, in exact.cc and in the rasterizer's primitives.
using Geometry = std::variant<PointSite, SegmentSite, PolylineSite, PolygonSite, BezierSite>;

// What a site's part nearest to a point is (NearestSite.feature_kind in the API).
enum class FeatureKind : uint8_t { kVertex, kEdge, kCurve };

class SegmentTree;  // geometry/segment_tree.h

struct Site {
  std::string id;
  Geometry geometry;
  // The site's value at q is multiplicative * d + additive, d the Euclidean distance from q
  // to the geometry (paper sec. 4.4); beyond max_distance (in d) the site has no influence.
  // CONTRACT: additive >= 0 and multiplicative > 0, both finite; max_distance > 0.
  double additive = 0;
  double multiplicative = 1;
  double max_distance = INFINITY;
  // The geometry's segments in a tree, for sites of many segments (IndexSegments, which the
  // slot table calls as a site enters it); null otherwise. The exact functions taking a Site
  // (exact.h) use it: it changes how fast they find a value, never the value.
  std::shared_ptr<const SegmentTree> segment_tree;

  bool weighted() const { return additive != 0 || multiplicative != 1; }
  // Whether the site is a candidate everywhere at its plain distance: unweighted, unbounded
  // and not restricted to a side.
  bool plain() const;
};

// A densely indexed list of sites; the id buffer holds index + 1.
using SiteTable = std::vector<Site>;

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
class SlotTable {
 public:
  static constexpr uint32_t kChunk = 64;
  static constexpr uint32_t kBlock = 32;
  static constexpr uint32_t kBlockSlots = kChunk * kBlock;

  SlotTable() = default;
  explicit SlotTable(const SiteTable& sites);  // slot i = sites[i]

  uint32_t size() const { return size_; }  // slots, free ones included
  // The site in `slot`, or null for a free slot. CONTRACT: slot < size().
  const Site* get(uint32_t slot) const { return ptr(slot).get(); }
  const std::shared_ptr<const Site>& ptr(uint32_t slot) const {
    return chunk(slot).sites[slot % kChunk];
  }
  // Where the site in `slot` is, when it is a plain (Site::plain) point, and NaN otherwise:
  // then its value at q is Distance(q, point), found without reaching the site itself.
  // CONTRACT: slot < size().
  Vec2 point(uint32_t slot) const { return chunk(slot).points[slot % kChunk]; }
  // Puts a site in (or frees, with null) a slot, growing the table as needed.
  void Set(uint32_t slot, std::shared_ptr<const Site> site);
  // The same for a site not yet shared, which gets its segment tree (IndexSegments) first.
  void Set(uint32_t slot, std::optional<Site> site);

  // The least weights over the sites, exactly: O(slots / kBlockSlots), as each chunk and
  // block keeps its own.
  LeastWeights least() const;

  // Calls f(slot, before, after) for every slot whose site differs between the two tables
  // (by identity; either may be null). Blocks and chunks the tables share are skipped.
  template <class F>
  static void Diff(const SlotTable& before, const SlotTable& after, F&& f);

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
    std::array<Vec2, kChunk> points;  // see point()
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

template <class F>
void SlotTable::Diff(const SlotTable& before, const SlotTable& after, F&& f) {
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

}  // namespace gvd
