#include "geometry/site.h"

namespace gvd {

bool Site::plain() const {
  if (weighted() || std::isfinite(max_distance)) return false;
  const auto* polygon = std::get_if<PolygonSite>(&geometry);
  return polygon == nullptr || polygon->side == Side::kBoth;
}

SlotTable::SlotTable(const SiteTable& sites) {
  for (uint32_t i = 0; i < sites.size(); ++i) Set(i, std::make_shared<const Site>(sites[i]));
}

void SlotTable::Set(uint32_t slot, std::shared_ptr<const Site> site) {
  while (chunks_.size() * kChunk <= slot) chunks_.push_back(std::make_shared<Chunk>());
  size_ = std::max(size_, slot + 1);
  auto& shared = chunks_[slot / kChunk];
  if (shared.use_count() > 1) shared = std::make_shared<Chunk>(*shared);  // copy on write
  Chunk& chunk = const_cast<Chunk&>(*shared);
  std::shared_ptr<const Site>& entry = chunk.sites[slot % kChunk];
  bool recount = false;
  if (entry) {
    recount = !chunk.multiplicative.Remove(entry->multiplicative);
    recount = !chunk.additive.Remove(entry->additive) || recount;
  }
  entry = std::move(site);
  if (recount) {
    chunk.Recount();
  } else if (entry) {
    chunk.multiplicative.Add(entry->multiplicative);
    chunk.additive.Add(entry->additive);
  }
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
  for (const auto& chunk : chunks_) {
    least.multiplicative = std::min(least.multiplicative, chunk->multiplicative.value);
    least.additive = std::min(least.additive, chunk->additive.value);
  }
  return least;
}

}  // namespace gvd
