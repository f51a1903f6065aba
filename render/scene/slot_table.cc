#include "render/scene/slot_table.h"

namespace gvd {

template <class K>
BasicSlotTable<K>::BasicSlotTable(const std::vector<Site>& sites) {
  for (uint32_t i = 0; i < sites.size(); ++i) Set(i, std::optional<Site>(sites[i]));
}

template <class K>
void BasicSlotTable<K>::Set(uint32_t slot, std::optional<Site> site) {
  if (site) K::Prepare(*site);
  Set(slot, site ? std::make_shared<const Site>(std::move(*site)) : nullptr);
}

template <class K>
BasicSlotTable<K>::Chunk::Chunk() { points.fill(K::None()); }

template <class K>
BasicSlotTable<K>::Block::Block() { chunks.fill(EmptyChunk()); }

template <class K>
const std::shared_ptr<const typename BasicSlotTable<K>::Chunk>& BasicSlotTable<K>::EmptyChunk() {
  static const auto* empty = new std::shared_ptr<const Chunk>(std::make_shared<const Chunk>());
  return *empty;
}

template <class K>
const std::shared_ptr<const typename BasicSlotTable<K>::Block>& BasicSlotTable<K>::EmptyBlock() {
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

template <class K>
void BasicSlotTable<K>::Set(uint32_t slot, std::shared_ptr<const Site> site) {
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
  const auto point = entry && entry->plain() ? K::PointOf(*entry) : std::nullopt;
  chunk.points[i] = point ? *point : K::None();
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

template <class K>
void BasicSlotTable<K>::Chunk::Recount() {
  multiplicative = additive = Least{};
  for (const auto& site : sites) {
    if (site) {
      multiplicative.Add(site->multiplicative);
      additive.Add(site->additive);
    }
  }
}

template <class K>
LeastWeights BasicSlotTable<K>::least() const {
  LeastWeights least;
  if (root_) {
    for (const LeastWeights& l : root_->least) least = Min(least, l);
  }
  return least;
}

template class BasicSlotTable<Kernel2>;
template class BasicSlotTable<Kernel3>;

}  // namespace gvd
