// Voronoi sites as the render layer sees them: an id and a geometry.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "render/geometry.h"

namespace gvd {

struct PointSite {
  Vec2 p;
};

// Every site kind; new kinds are added here and in exact.cc and the mesh builders.
using Geometry = std::variant<PointSite>;

struct Site {
  std::string id;
  Geometry geometry;
};

// A densely indexed list of sites; the id buffer holds index + 1.
using SiteTable = std::vector<Site>;

// Sites by slot (the id buffer holds slot + 1), in chunks that versions share: a copy is
// O(slots / kChunk) and a change copies only its chunk. A copy is immutable to readers of the
// original; not thread-safe for concurrent writers.
class SlotTable {
 public:
  static constexpr uint32_t kChunk = 1024;

  SlotTable() = default;
  explicit SlotTable(const SiteTable& sites);  // slot i = sites[i]

  uint32_t size() const { return size_; }  // slots, free ones included
  // The site in `slot`, or null for a free slot. CONTRACT: slot < size().
  const Site* get(uint32_t slot) const {
    const auto& s = (*chunks_[slot / kChunk])[slot % kChunk];
    return s ? &*s : nullptr;
  }
  // Puts a site in (or frees, with nullopt) a slot, growing the table as needed.
  void Set(uint32_t slot, std::optional<Site> site);

 private:
  using Chunk = std::vector<std::optional<Site>>;
  std::vector<std::shared_ptr<const Chunk>> chunks_;
  uint32_t size_ = 0;
};

}  // namespace gvd
