// Motion planning on a frame (paper sec. 7.1): the clearance field of the obstacles (the
// sites), and paths of maximal clearance along the Voronoi boundaries between them, joined
// to the start and the goal. Pure CPU work; thread-safe.
#pragma once

#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/kernel/grid2.h"

namespace gvd {

// Per pixel centre of a frame, a proven lower bound on the clearance: the distance to the
// nearest obstacle (a site's value, m d + a, in a weighted scene), from the stored distance
// and the frame's error model. Inside a solid polygon (side BOTH or OUTSIDE: the robot cannot
// be there) it is 0; where no site is a candidate, +infinity. Between pixel centres the
// clearance changes by at most `lipschitz` per unit of distance.
struct ClearanceField {
  Grid grid;
  std::vector<float> clearance;  // row-major from row 0 (min y)
  // Per pixel: the nearest site (slot + 1, 0 for none) and its nearest feature, whose
  // changes mark the Voronoi boundaries between sites and the medial axes inside them.
  std::vector<uint32_t> site, feature;
  double lipschitz = 1;

  float at(uint32_t i, uint32_t j) const { return clearance[size_t{j} * grid.width + i]; }
};

// CONTRACT: the frame is not empty and its diagram is kNearest.
ClearanceField MakeClearanceField(const Frame& frame);

enum class PathPreference {
  kMaxClearance,  // the shortest among the paths whose clearance is the best there is
  kShortest,      // the shortest whose clearance is at least the robot's radius
};

struct PlanRequest {
  Vec2 start, goal;
  double radius = 0;  // of the robot (a disc), scene units
  PathPreference prefer = PathPreference::kMaxClearance;
};

struct Plan {
  std::vector<Vec2> path;       // start, the turns, goal (simplified within a pixel)
  double min_clearance = 0;     // proven lower bound on the clearance along all of it
  double best_clearance = 0;    // the widest passage from start to goal along the roadmap
  double length = 0;
  size_t roadmap_pixels = 0;    // pixels on the boundaries the search ran on
};

// A path from start to goal along the roadmap: pixel centres on the Voronoi boundaries
// (between sites, and between features of one site: the medial axes) and on the window's
// border (where climbing can end, as nothing beyond it is known), joined to the start and
// the goal by climbing the clearance field. Each step between neighbouring pixel centres
// p, q is credited with min(c_p, c_q, (c_p + c_q - L |pq|) / 2), a proven lower bound on the
// clearance along it. The pixel path is then simplified within a pixel (Douglas-Peucker),
// keeping a shortcut only when its own proven clearance (sampled every quarter pixel) stays
// within a pixel of the path's and at least the radius; min_clearance is the least bound of
// the segments returned. NotFound when start or goal is
// closer than `radius` to an obstacle, or no path along the roadmap keeps `radius` (the
// message gives the best there is); InvalidArgument when they lie outside the window or the
// radius is negative. O(pixels log pixels) at worst.
absl::StatusOr<Plan> PlanPath(const Frame& frame, const ClearanceField& field,
                              const PlanRequest& request);

}  // namespace gvd
