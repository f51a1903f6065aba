#include "render/scene/slot_table.h"

#include "render/kernel/segment_tree.h"

namespace gvd {

SlotTable::SlotTable(const SiteTable& sites) {
  for (uint32_t i = 0; i < sites.size(); ++i) Set(i, std::optional<Site>(sites[i]));
}

void SlotTable::Set(uint32_t slot, std::optional<Site> site) {
  if (site) IndexSegments(*site);
  Set(slot, site ? std::make_shared<const Site>(std::move(*site)) : nullptr);
}

SlotTable::Chunk::Chunk() { points.fill(Vec2(NAN, NAN)); }

SlotTable::Block::Block() { chunks.fill(EmptyChunk()); }

const std::shared_ptr<const SlotTable::Chunk>& SlotTable::EmptyChunk() {
  static const auto* empty = new std::shared_ptr<const Chunk>(std::make_shared<const Chunk>());
  return *empty;
}

const std::shared_ptr<const SlotTable::Block>& SlotTable::EmptyBlock() {
  static const auto* empty = new std::shared_ptr<const Block>(std::make_shared<const Block>());
  return *empty;
}

namespace {

// The node `p` points to, made this table's own first when another table shares it.
template <class T>
T& Own(std::shared_ptr<const T>& p) {
  if (p.use_count() != 1) p = std::make_shared<const T>(*p);
  return const_cast<T&>(*p);
}

LeastWeights Min(LeastWeights a, LeastWeights b) {
  return {std::min(a.multiplicative, b.multiplicative), std::min(a.additive, b.additive)};
}

}  // namespace

void SlotTable::Set(uint32_t slot, std::shared_ptr<const Site> site) {
  if (!root_) root_ = std::make_shared<const Root>();
  Root& root = Own(root_);
  while (root.blocks.size() * kBlockSlots <= slot) {
    root.blocks.push_back(EmptyBlock());
    root.least.push_back({});
  }
  size_ = std::max(size_, slot + 1);
  const uint32_t b = slot / kBlockSlots, c = slot / kChunk % kBlock, i = slot % kChunk;
  Block& block = Own(root.blocks[b]);
  Chunk& chunk = Own(block.chunks[c]);
  std::shared_ptr<const Site>& entry = chunk.sites[i];
  bool recount = false;
  if (entry) {
    recount = !chunk.multiplicative.Remove(entry->multiplicative);
    recount = !chunk.additive.Remove(entry->additive) || recount;
  }
  entry = std::move(site);
  const auto* point = entry && entry->plain() ? std::get_if<PointSite>(&entry->geometry) : nullptr;
  chunk.points[i] = point ? point->p : Vec2(NAN, NAN);
  if (recount) {
    chunk.Recount();
  } else if (entry) {
    chunk.multiplicative.Add(entry->multiplicative);
    chunk.additive.Add(entry->additive);
  }
  block.least[c] = {chunk.multiplicative.value, chunk.additive.value};
  LeastWeights least;
  for (const LeastWeights& l : block.least) least = Min(least, l);
  root.least[b] = least;
}

void SlotTable::Chunk::Recount() {
  multiplicative = additive = Least{};
  for (const auto& site : sites) {
    if (site) {
      multiplicative.Add(site->multiplicative);
      additive.Add(site->additive);
    }
  }
}

LeastWeights SlotTable::least() const {
  LeastWeights least;
  if (root_) {
    for (const LeastWeights& l : root_->least) least = Min(least, l);
  }
  return least;
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
        }
      },
      site.geometry);
  if (segments >= SegmentTree::kMinSegments) bytes += sizeof(SegmentTree) + segments * kTreePerSegment;
  return bytes;
}

}  // namespace gvd
