#include "render/plan/error_tally.h"

#include <algorithm>
#include <cmath>

#include "render/kernel/exact2.h"
#include "render/kernel/kernel2.h"

namespace gvd {

void ErrorTally::Live(const Site& site) {
  max_weight_ = std::max(max_weight_, site.multiplicative);
  if (std::isfinite(site.max_distance) || SideOf(site.geometry) != Side::kBoth) {
    limited_presence_ = true;
  }
  curve_slack_ = std::max(curve_slack_, Kernel2::Tolerance(site));
}

void ErrorTally::Drawn(const Grid& grid, const Site& site, const SiteShape& shape) {
  overestimate_ = std::max(overestimate_, shape.overestimate);
  excess_ = std::max(excess_, shape.excess);
  // How large the float coordinates of the drawn site get, relative to the window's min
  // corner: its geometry and the reach of its pieces.
  Window b = BoundingBox(site.geometry);
  double x = std::max(std::abs(b.min_x - grid.window.min_x), std::abs(b.max_x - grid.window.min_x));
  double y = std::max(std::abs(b.min_y - grid.window.min_y), std::abs(b.max_y - grid.window.min_y));
  coordinate_scale_ = std::max(coordinate_scale_, std::max({x, y, grid.window.width(),
                                                            grid.window.height()}) +
                                                      shape.extent);
}

ErrorModel ErrorTally::Model(const Grid& grid, const DrawParams& params) const {
  // Vertices snap to 1/256 pixel (GL_SUBPIXEL_BITS = 8 on llvmpipe and NVIDIA), which moves a
  // cone's surface by at most 1/256 pixel diagonal, as its slope is at most k ~ 1: we allow
  // 1/64. Float interpolation and depth storage err by a few ulps of the depth range and of D.
  // Positions are floats relative to the window's min corner, so distances err by a few ulps
  // of the largest coordinate or reach drawn. A weight scales all of it.
  ErrorModel error;
  error.diagram = params.diagram;
  error.overestimate = overestimate_;
  error.max_excess =
      params.mode == RenderMode::kExact ? 0 : std::max(params.eps * max_weight_, excess_);
  error.absolute_slack = (grid.pixel_diagonal() / 64 + coordinate_scale_ * 0x1p-18) * max_weight_;
  error.relative_slack = 0x1p-18;
  error.lipschitz = max_weight_;
  error.curve = curve_slack_;
  error.limited_presence = limited_presence_;
  return error;
}

}  // namespace gvd
