#include "geometry/site.h"

namespace gvd {

bool Site::plain() const {
  if (weighted() || std::isfinite(max_distance)) return false;
  const auto* polygon = std::get_if<PolygonSite>(&geometry);
  return polygon == nullptr || polygon->side == Side::kBoth;
}

SlotTable::SlotTable(const SiteTable& sites) {
  for (uint32_t i = 0; i < sites.size(); i += kChunk) {
    auto chunk = std::make_shared<Chunk>(kChunk);
    for (uint32_t j = i; j < std::min<size_t>(sites.size(), i + kChunk); ++j) {
      (*chunk)[j - i] = std::make_shared<const Site>(sites[j]);
    }
    chunks_.push_back(std::move(chunk));
  }
  size_ = static_cast<uint32_t>(sites.size());
}

void SlotTable::Set(uint32_t slot, std::shared_ptr<const Site> site) {
  while (chunks_.size() * kChunk <= slot) chunks_.push_back(std::make_shared<Chunk>(kChunk));
  size_ = std::max(size_, slot + 1);
  auto& chunk = chunks_[slot / kChunk];
  if (chunk.use_count() > 1) chunk = std::make_shared<Chunk>(*chunk);  // copy on write
  const_cast<Chunk&>(*chunk)[slot % kChunk] = std::move(site);
}

}  // namespace gvd
