// A 2D scene's site in a slot as the hot paths (raster lookups, the coverage proof) read it.
#pragma once

#include <cmath>
#include <cstdint>

#include "render/kernel/exact2.h"
#include "render/scene/slot_table.h"

namespace gvd {

// The site in a slot as the hot paths (raster lookups, the coverage proof) read it: a plain
// point (Site::plain: weights 1 and 0, no max_distance, no side) from the slot table's own
// record of it, without reaching the site object; any other site from the site.
struct SiteView {
  const Site* site;  // null for a plain point
  Vec2 point;        // the plain point

  // CONTRACT: the slot holds a site.
  static SiteView Of(const SlotTable& sites, uint32_t slot) {
    Vec2 p = sites.point(slot);
    return std::isnan(p.x) ? SiteView{sites.get(slot), p} : SiteView{nullptr, p};
  }
  bool plain_point() const { return site == nullptr; }
  double multiplicative() const { return site ? site->multiplicative : 1; }
  double additive() const { return site ? site->additive : 0; }
  double max_distance() const { return site ? site->max_distance : INFINITY; }
  // DrawnDistance (what the raster's planning measures), FarthestDistance and SiteValue of
  // the site (a plain point's value is its distance).
  double DrawnDistanceFrom(Vec2 q) const {
    return site ? DrawnDistance(q, *site) : Distance(q, point);
  }
  double FarthestFrom(const Window& box) const {
    return site ? FarthestDistance(box, *site) : box.FarthestDistance(point);
  }
  double ValueAt(Vec2 q) const { return site ? SiteValue(q, *site) : Distance(q, point); }
};

}  // namespace gvd
