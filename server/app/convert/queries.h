// Queries of points: FindNearestRequest's points (as NearestSite messages, or packed) and
// PickRequest's point, of a scene of either dimension.
#pragma once

#include <vector>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site3.h"
#include "server/app/limits.h"

namespace gvd {

// The query points of a FindNearestRequest or FindNearestStreamRequest, of a scene of P's
// dimension (Vec2 or Vec3): `points`, or packed `xy` (a 2D scene's) or `xyz` (a 3D scene's);
// count within the limit, finite. *outside is set when some point lies outside the scene's
// `bounds` (its window, or box).
template <class Request, class P, class Bounds>
absl::Status ToQueryPoints(const Request& request, const Bounds& bounds,
                           const ServerLimits& limits, std::vector<P>* points, bool* outside);

// PickRequest's point, of P's dimension, and max_distance (0: no limit, returned as
// +infinity).
template <class P>
absl::Status ToPick(const v1::PickRequest& request, P* point, double* max_distance);

}  // namespace gvd
