#include "server/app/convert/analysis.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "server/app/convert/common.h"
#include "server/log.h"

namespace gvd {

absl::Status ToBoundaryMethod(const v1::GetBoundariesRequest& request, BoundaryMethod* method) {
  switch (request.method()) {
    case v1::GetBoundariesRequest::METHOD_UNSPECIFIED:
    case v1::GetBoundariesRequest::METHOD_FULL_SCAN:
      *method = BoundaryMethod::kFullScan;
      break;
    case v1::GetBoundariesRequest::METHOD_CONTINUATION:
      *method = BoundaryMethod::kContinuation;
      break;
    default:
      return Invalid(
          absl::StrCat("method is ", request.method(), "; it must be METHOD_FULL_SCAN or METHOD_CONTINUATION"));
  }
  return absl::OkStatus();
}

absl::Status ToPathPreference(const v1::PlanPathRequest& request, PathPreference* prefer) {
  switch (request.prefer()) {
    case v1::PlanPathRequest::PREFER_UNSPECIFIED:
    case v1::PlanPathRequest::PREFER_MAX_CLEARANCE:
      *prefer = PathPreference::kMaxClearance;
      break;
    case v1::PlanPathRequest::PREFER_SHORTEST:
      *prefer = PathPreference::kShortest;
      break;
    default:
      return Invalid(
          absl::StrCat("prefer is ", request.prefer(), "; it must be PREFER_MAX_CLEARANCE or PREFER_SHORTEST"));
  }
  return absl::OkStatus();
}

absl::Status ToClearanceSamples3(const v1::GetClearanceFieldRequest& r, const Grid3& grid,
                                 size_t sites, const ServerLimits& limits, ClearanceSamples3* out) {
  Box3 box = grid.box;
  if (r.has_window()) {
    Window plane;
    if (auto s = ToWindow(r.window(), "window", &plane); !s.ok()) return s;
    const v1::Window& w = r.window();
    for (auto [v, name] : {std::pair{w.min_z(), "window.min_z"}, {w.max_z(), "window.max_z"}}) {
      if (auto s = CheckFinite(v, FieldPath(name)); !s.ok()) return s;
    }
    if (!(w.min_z() < w.max_z()) || !std::isfinite(w.max_z() - w.min_z())) {
      return Invalid(absl::StrCat("window.min_z ", FormatNumber(w.min_z()),
                                  " must be less than window.max_z ", FormatNumber(w.max_z()),
                                  ", with a finite difference"));
    }
    box = {plane.min_x, plane.min_y, w.min_z(), plane.max_x, plane.max_y, w.max_z()};
  }
  const uint32_t sizes[3] = {r.width_px(), r.height_px(), r.depth_px()};
  const bool own = sizes[0] == 0 && sizes[1] == 0 && sizes[2] == 0;
  uint32_t first[3] = {0, 0, 0}, count[3] = {grid.width, grid.height, grid.depth};
  if (own) {
    // The scene's voxels whose centres lie in the box: centre i + 0.5 in [lo, hi].
    const Vec3 lo = grid.ToVoxel({box.min_x, box.min_y, box.min_z});
    const Vec3 hi = grid.ToVoxel({box.max_x, box.max_y, box.max_z});
    for (int a = 0; a < 3; ++a) {
      const double n = a == 0 ? grid.width : a == 1 ? grid.height : grid.depth;
      const double f = std::max(0.0, std::ceil(lo[a] - 0.5));
      const double l = std::min(n - 1, std::floor(hi[a] - 0.5));
      if (!(f <= l)) return Invalid("window holds no voxel centre of the scene");
      first[a] = static_cast<uint32_t>(f);
      count[a] = static_cast<uint32_t>(l - f + 1);
    }
    const Vec3 a = grid.Center(first[0], first[1], first[2]);
    const Vec3 b =
        grid.Center(first[0] + count[0] - 1, first[1] + count[1] - 1, first[2] + count[2] - 1);
    const Vec3 half = grid.voxel_size() * 0.5;
    box = {a.x - half.x, a.y - half.y, a.z - half.z, b.x + half.x, b.y + half.y, b.z + half.z};
  } else {
    for (auto [v, name] :
         {std::pair{sizes[0], "width_px"}, {sizes[1], "height_px"}, {sizes[2], "depth_px"}}) {
      if (v == 0 || v > limits.max_side_px) {
        return Invalid(absl::StrCat(name, " is ", v, "; it must be 1 to ", limits.max_side_px,
                                    " (--max-side-px), or all three 0"));
      }
    }
    for (int a = 0; a < 3; ++a) count[a] = sizes[a];
  }
  const uint64_t n = uint64_t{count[0]} * count[1] * count[2];
  if (n > limits.max_voxels_per_scene) {
    return absl::ResourceExhaustedError(absl::StrCat("the field has ", n, " samples; the limit is ",
                                                     limits.max_voxels_per_scene,
                                                     " (--max-voxels-per-scene)"));
  }
  if (!own && n > limits.max_points_per_query) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the field has ", n, " samples; the limit is ", limits.max_points_per_query,
                     " (--max-points-per-query); the scene's own voxels are not limited so"));
  }
  // A float each, three with a gradient, an index and, at most once a site, its id.
  uint64_t bytes = n * (5 + (r.gradients() ? 15 : 0) + (r.site_indices() ? 5 : 0));
  if (r.site_indices()) bytes += std::min<uint64_t>(n, sites) * (limits.max_site_id_bytes + 3);
  if (bytes > uint64_t(limits.max_message_bytes)) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the field's ", n, " samples take up to ", bytes, " bytes, over a message's ",
                     limits.max_message_bytes, " (--max-message-bytes)"));
  }
  out->box = box;
  out->width = count[0];
  out->height = count[1];
  out->depth = count[2];
  out->own = own;
  out->cells = own ? grid : Grid3{box, count[0], count[1], count[2]};
  for (int a = 0; a < 3; ++a) out->first[a] = own ? first[a] : 0;
  return absl::OkStatus();
}

}  // namespace gvd
