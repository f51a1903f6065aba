// How far a frame's stored values can be from the exact diagram: what a render knows of its
// own error, and the bounds every answer read from a frame is given.
#pragma once

#include <algorithm>

#include "render/kernel/diagram.h"

namespace gvd {

// How far a frame's stored values can be from the truth. Let v_B(p) = m_B d(p, B) + a_B be
// site B's value, ignoring its max_distance and side. Wherever B's pieces are drawn over a
// pixel centre p, their height satisfies
//   v_B(p) <= h_B(p) <= min(overestimate * v_B(p), v_B(p) + max_excess)
// (a fan's spokes lie on the cone, sec. 4.1.1; a tent is exact; a >= 0), and each pixel
// centre is covered by the pieces of every site best there among those present
// (render/plan/coverage.h). The stored value D(p) is the least (kNearest) or greatest (kFarthest)
// height drawn there, up to the rasterizer's arithmetic: slack(D) = absolute_slack +
// relative_slack * D. A site that is a candidate at q is present at the pixel centres around
// q, and its value changes by at most lipschitz per unit of distance.
struct ErrorModel {
  Diagram diagram = Diagram::kNearest;
  double overestimate = 1;    // k >= 1
  double max_excess = 0;      // eps * the largest weight, scene units
  double absolute_slack = 0;  // scene units: sub-pixel vertex snapping and interpolation
  double relative_slack = 0;  // float depth and interpolation rounding, relative to D
  double lipschitz = 1;       // the largest multiplicative weight of any site
  double curve = 0;           // the largest Bezier tolerance * weight, added to every bound
  // Some site has a max_distance or a side: it is present (drawn) only within DrawMargin of
  // where it is a candidate.
  bool limited_presence = false;

  double Slack(double d) const { return absolute_slack + relative_slack * d; }
  // A lower bound on v_B(p) for every site B present at p, given the least stored value D
  // at p: the best site's height at p is at least D.
  double LowerBound(double d) const {
    return std::max(d / overestimate, d - max_excess) - Slack(d);
  }
  // An upper bound on v_B(p) for every site B present at p, given the greatest stored value
  // D at p: every height drawn is at least the value.
  double UpperBound(double d) const { return d + Slack(d); }
};

}  // namespace gvd
