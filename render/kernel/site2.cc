#include "render/kernel/site2.h"

namespace gvd {

bool Site::plain() const {
  if (weighted() || std::isfinite(max_distance)) return false;
  if (const auto* polygon = std::get_if<PolygonSite>(&geometry)) return polygon->side == Side::kBoth;
  if (const auto* path = std::get_if<PathSite>(&geometry)) return path->side == Side::kBoth;
  return true;
}

}  // namespace gvd
