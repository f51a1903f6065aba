// Bounded-error distance meshes (paper sec. 4): the triangle fans that the rasterizer draws
// so that interpolated depth approximates each site's distance function.
#pragma once

#include <cstdint>
#include <vector>

namespace gvd {

// Fan triangles needed for a point's distance cone of radius `radius` to stay within `eps`
// of the true distance (paper sec. 4.1.1): the spokes lie on the cone, the base polygon's
// edges come within eps of the base circle, alpha = 2 acos((R - eps) / R), n = ceil(2 pi / alpha).
// At least 3; eps >= radius gives 3.
// CONTRACT: radius > 0 and eps > 0, both finite.
uint32_t ConeSegments(double radius, double eps);

// The most triangles a cone may have; beyond it the error bound grows instead (it is always
// reported honestly through `overestimate`).
inline constexpr uint32_t kMaxConeSegments = 16384;

// A unit distance cone for instanced drawing: `segments` triangles around the apex (0, 0, 0)
// whose ring vertices (cos t, sin t, 1) lie on the cone z = r. Scaled by rho in all three
// axes it covers every point within rho * cos(pi / n) of the apex, and there its height h
// satisfies d <= h <= d * overestimate for the true distance d, overestimate = 1 / cos(pi / n).
struct ConeMesh {
  uint32_t segments = 0;
  double overestimate = 1;
  std::vector<float> vertices;  // x, y, z per vertex; three vertices per triangle
};

// The unit cone with `segments` triangles. CONTRACT: 3 <= segments <= kMaxConeSegments.
ConeMesh BuildUnitCone(uint32_t segments);

// The cone that meshes, within eps, every distance up to `reach`: with
// n = ConeSegments(reach + eps, eps), reach * (overestimate - 1) <= eps, so scaling the unit
// cone by reach * overestimate covers radius `reach` with error at most eps. Capped at
// kMaxConeSegments.
ConeMesh ConeForReach(double reach, double eps);

}  // namespace gvd
