// The structure and applications calls' own fields: GetBoundariesRequest's method,
// PlanPathRequest's preference, and the samples of a 3D scene's clearance field.
#pragma once

#include <cstddef>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/analysis/analysis.h"
#include "render/analysis/clearance3.h"
#include "render/analysis/planning.h"
#include "server/app/limits.h"

namespace gvd {

absl::Status ToBoundaryMethod(const v1::GetBoundariesRequest& request, BoundaryMethod* method);
absl::Status ToPathPreference(const v1::PlanPathRequest& request, PathPreference* prefer);

// The samples of a 3D scene's clearance field that a request asks for (see
// GetClearanceFieldRequest): the scene's own voxels in its window, or width_px x height_px x
// depth_px cells of a box of the caller's. INVALID_ARGUMENT naming the field;
// RESOURCE_EXHAUSTED when the samples exceed --max-voxels-per-scene, --max-points-per-query
// (samples of a box of the caller's) or, with what each answers, --max-message-bytes.
absl::Status ToClearanceSamples3(const v1::GetClearanceFieldRequest& request, const Grid3& grid,
                                 size_t sites, const ServerLimits& limits, ClearanceSamples3* out);

}  // namespace gvd
