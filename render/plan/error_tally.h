// What a frame's error model is made from: the sites live in it and the shapes they were
// drawn with (render/scene/error_model.h says what the bounds mean).
#pragma once

#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"
#include "render/plan/site_shape.h"
#include "render/scene/error_model.h"

namespace gvd {

// What a frame's ErrorModel needs to know of the sites drawn into it: the largest weight,
// fan overestimate and excess, Bezier tolerance, coordinate magnitude, and whether presence
// is limited. Reset before a render from scratch; later draws only widen it.
class ErrorTally {
 public:
  void Reset() { *this = ErrorTally(); }
  // A site that is live in the frame (drawn or not).
  void Live(const Site& site);
  // A site drawn with `shape` on `grid`.
  void Drawn(const Grid& grid, const Site& site, const SiteShape& shape);
  ErrorModel Model(const Grid& grid, const DrawParams& params) const;

 private:
  double overestimate_ = 1;
  double max_weight_ = 1;
  double curve_slack_ = 0;
  double coordinate_scale_ = 0;  // relative to the window's min corner
  double excess_ = 0;            // beyond eps * weight, from fans with capped triangle counts
  bool limited_presence_ = false;
};

}  // namespace gvd
