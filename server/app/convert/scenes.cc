#include "server/app/convert/scenes.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "render/plan/distance_mesh.h"
#include "server/app/convert/common.h"
#include "server/log.h"

namespace gvd {

absl::Status ToSceneSettings(const v1::CreateSceneRequest& r, const ServerLimits& limits,
                             SceneSettings* settings) {
  if (auto s = ValidateSceneId(r.scene_id(), limits); !s.ok()) return s;
  if (!r.has_window()) return Invalid("window is not set");
  Grid grid;
  if (auto s = ToWindow(r.window(), "window", &grid.window); !s.ok()) return s;
  if (auto s = ToGridSize(r.width_px(), r.height_px(), limits, &grid); !s.ok()) return s;
  double eps = r.max_error();
  if (!std::isfinite(eps) || eps < 0) {
    return Invalid(absl::StrCat("max_error is ", FormatNumber(eps),
                                "; it must be finite and not negative (0 means one pixel)"));
  }
  double pixel = grid.pixel_size();
  if (eps == 0) eps = pixel;
  if (eps < pixel / 64) {
    return Invalid(absl::StrCat("max_error ", FormatNumber(eps), " is below 1/64 pixel (",
                                FormatNumber(pixel / 64),
                                " scene units), which would need too many triangles per cone"));
  }
  if (!(eps > 0)) return Invalid("max_error underflows to 0 for this window");
  const v1::Window& w = r.window();
  if (r.depth_px() > 0) {
    // A 3D scene: a z range, slices within --max-side-px, voxels within their limit.
    if (auto s = CheckFinite(w.min_z(), FieldPath("window.min_z")); !s.ok()) return s;
    if (auto s = CheckFinite(w.max_z(), FieldPath("window.max_z")); !s.ok()) return s;
    if (!(w.min_z() < w.max_z()) || !std::isfinite(w.max_z() - w.min_z())) {
      return Invalid(absl::StrCat("window.min_z ", FormatNumber(w.min_z()),
                                  " must be less than window.max_z ", FormatNumber(w.max_z()),
                                  " (a 3D scene's box), with a finite difference"));
    }
    if (r.depth_px() > limits.max_side_px) {
      return Invalid(absl::StrCat("depth_px is ", r.depth_px(), "; it must be 1 to ",
                                  limits.max_side_px, " (--max-side-px)"));
    }
    const uint64_t voxels = uint64_t{grid.width} * grid.height * r.depth_px();
    if (voxels > limits.max_voxels_per_scene) {
      return absl::ResourceExhaustedError(
          absl::StrCat("width_px x height_px x depth_px is ", voxels, " voxels; the limit is ",
                       limits.max_voxels_per_scene, " (--max-voxels-per-scene)"));
    }
    settings->depth = r.depth_px();
    settings->min_z = w.min_z();
    settings->max_z = w.max_z();
    const double voxel_z = (w.max_z() - w.min_z()) / r.depth_px();
    if (r.max_error() == 0) eps = std::max(eps, voxel_z);
  } else if (w.min_z() != 0 || w.max_z() != 0) {
    return Invalid(absl::StrCat("window.min_z and max_z are ", FormatNumber(w.min_z()), " and ",
                                FormatNumber(w.max_z()),
                                "; a z range is for 3D scenes, which set depth_px"));
  }
  settings->id = r.scene_id();
  settings->grid = grid;
  settings->eps = eps;
  settings->cone_triangles = ConeSegments(grid.window.diagonal() + eps, eps);
  switch (r.render_mode()) {
    case v1::RENDER_MODE_UNSPECIFIED:
    case v1::RENDER_MODE_MESH:
      settings->mode = RenderMode::kMesh;
      break;
    case v1::RENDER_MODE_EXACT:
      settings->mode = RenderMode::kExact;
      break;
    default:
      return Invalid(
          absl::StrCat("render_mode is ", r.render_mode(), "; it must be RENDER_MODE_MESH or RENDER_MODE_EXACT"));
  }
  // A 3D scene is rendered exactly per voxel, whatever the mode asked.
  if (settings->three_d()) settings->mode = RenderMode::kExact;
  switch (r.diagram()) {
    case v1::DIAGRAM_UNSPECIFIED:
    case v1::DIAGRAM_NEAREST:
      settings->diagram = Diagram::kNearest;
      break;
    case v1::DIAGRAM_FARTHEST:
      settings->diagram = Diagram::kFarthest;
      break;
    default:
      return Invalid(absl::StrCat("diagram is ", r.diagram(), "; it must be DIAGRAM_NEAREST or DIAGRAM_FARTHEST"));
  }
  return absl::OkStatus();
}

void ToProto(const SceneSettings& s, v1::Scene* out) {
  out->set_scene_id(s.id);
  ToProto(s.grid.window, out->mutable_window());
  out->set_width_px(s.grid.width);
  out->set_height_px(s.grid.height);
  out->set_max_error(s.eps);
  out->set_cone_triangles(s.cone_triangles);
  out->set_render_mode(s.mode == RenderMode::kExact ? v1::RENDER_MODE_EXACT : v1::RENDER_MODE_MESH);
  out->set_diagram(s.diagram == Diagram::kFarthest ? v1::DIAGRAM_FARTHEST : v1::DIAGRAM_NEAREST);
  if (s.three_d()) {
    out->set_depth_px(s.depth);
    out->mutable_window()->set_min_z(s.min_z);
    out->mutable_window()->set_max_z(s.max_z);
  }
}

void ToProto(const SceneHandle& scene, v1::Scene* out) {
  ToProto(scene.settings(), out);
  out->set_version(scene.version());
  out->set_site_count(scene.site_count());
  out->set_rendered_version(scene.frame_version());
  out->set_memory_bytes(scene.memory_bytes());
}

void ToProto(const UnloadedScene& scene, v1::Scene* out) {
  ToProto(scene.settings, out);
  out->set_version(scene.version);
  out->set_site_count(scene.sites);
  out->set_memory_bytes(scene.bytes);
  out->set_unavailable(scene.reason);
}

void ToProto(const SceneRegistry::StoreLag& lag, v1::Scene* out) {
  if (lag.store_version == 0) return;
  out->set_store_version(lag.store_version);
  out->set_store_read_age_seconds(lag.read_age_seconds);
}

}  // namespace gvd
