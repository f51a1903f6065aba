#include "render/kernel/site2.h"

namespace gvd {

bool Site::plain() const {
  if (weighted() || std::isfinite(max_distance)) return false;
  const auto* polygon = std::get_if<PolygonSite>(&geometry);
  return polygon == nullptr || polygon->side == Side::kBoth;
}

}  // namespace gvd
