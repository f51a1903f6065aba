// The one place where API messages and enums become the core's types and back, with
// validation. Every refusal is a gRPC status whose message names the field (with its index)
// and the offending value; nothing here mutates.
#pragma once

#include <string>
#include <vector>

#include <grpcpp/support/status.h>

#include "gvd/v1/voronoi.pb.h"
#include "render/kernel/grid2.h"
#include "render/analysis/analysis.h"
#include "render/analysis/planning.h"
#include "render/kernel/site2.h"
#include "render/image/image.h"
#include "server/app/limits.h"
#include "server/app/registry.h"
#include "server/log.h"
#include "render/scene/scene.h"

namespace gvd {

grpc::Status ValidateSceneId(const std::string& id, const ServerLimits& limits,
                             const char* field = "scene_id");

// Checks a CreateSceneRequest and derives the scene's settings (eps = one pixel for 0).
grpc::Status ToSceneSettings(const v1::CreateSceneRequest& request, const ServerLimits& limits,
                             SceneSettings* settings);

// A request field's name in error messages, such as sites[3].polygon.vertices[7].x, spelled
// out only when an error names it: a large request is checked without building a name per
// value. A path refers to its parent, which must outlive it (pass them down the stack).
class FieldPath {
 public:
  FieldPath(const char* name) : name_(name) {}  // NOLINT: a top-level field
  FieldPath(const FieldPath& parent, std::string_view member, int64_t index = -1)
      : parent_(&parent), name_(member), index_(index) {}
  // parent.member, and parent[i].
  FieldPath Member(std::string_view member) const { return {*this, member}; }
  FieldPath operator[](size_t i) const { return {*this, "", static_cast<int64_t>(i)}; }
  std::string str() const;

 private:
  const FieldPath* parent_ = nullptr;
  std::string_view name_;  // after the parent's name and a dot, or the whole name
  int64_t index_ = -1;     // appended as [index] when not negative
};

// Checks one site (`field` names it in messages, e.g. "sites[3]") and converts it: geometry
// set with enough points, coordinates finite, weights and max_distance in range. Bezier
// curves are flattened here.
grpc::Status ToSite(const v1::Site& site, const FieldPath& field, const ServerLimits& limits,
                    Site* out);

// Checks every site (ids non-empty, short, distinct; each as ToSite).
grpc::Status ToSites(const v1::UpsertSitesRequest& request, const ServerLimits& limits,
                     std::vector<Site>* sites);
// The same for a 3D scene's sites: points and segments with z, triangles and meshes (checked
// by MakeMesh against --max-triangles-per-mesh), weights as in 2D.
grpc::Status ToSite3(const v1::Site& site, const FieldPath& field, const ServerLimits& limits,
                     Site3* out);
grpc::Status ToSites3(const v1::UpsertSitesRequest& request, const ServerLimits& limits,
                      std::vector<Site3>* sites);

// A write's `durability` field: SYNC when unspecified.
grpc::Status ToDurability(v1::Durability durability, Durability* out);

// Checks ids non-empty and distinct.
grpc::Status ToSiteIds(const v1::DeleteSitesRequest& request, const ServerLimits& limits,
                       std::vector<std::string>* ids);

// Checks the query points (`points` or packed `xy`): count within the limit, finite. Sets
// *outside when some point lies outside the window.
grpc::Status ToQueryPoints(const v1::FindNearestRequest& request, const Window& window,
                           const ServerLimits& limits, std::vector<Vec2>* points, bool* outside);

// The same for a 3D scene (`points` with z, or packed `xyz`); *outside when some point lies
// outside the box.
grpc::Status ToQueryPoints3(const v1::FindNearestRequest& request, const Box3& box,
                            const ServerLimits& limits, std::vector<Vec3>* points, bool* outside);

// The samples of a 3D scene's clearance field that a request asks for (see
// GetClearanceFieldRequest): the box they are the cell centres of, their counts along x, y,
// z, and where they are. Sample (i, j, k) is the centre of voxel (first + (i, j, k)) of
// `cells`: the scene's own grid (own) or the box's. INVALID_ARGUMENT naming the field;
// RESOURCE_EXHAUSTED when the samples exceed --max-voxels-per-scene, --max-points-per-query
// (samples of a box of the caller's) or, with what each answers, --max-message-bytes.
struct ClearanceSamples3 {
  Box3 box;
  uint32_t width = 0, height = 0, depth = 0;
  bool own = false;  // the scene's voxels, read as they are
  Grid3 cells;
  uint32_t first[3] = {0, 0, 0};
  uint64_t count() const { return uint64_t{width} * height * depth; }
  Vec3 At(uint32_t i, uint32_t j, uint32_t k) const {
    return cells.Center(first[0] + i, first[1] + j, first[2] + k);
  }
};
grpc::Status ToClearanceSamples3(const v1::GetClearanceFieldRequest& request, const Grid3& grid,
                                 size_t sites, const ServerLimits& limits, ClearanceSamples3* out);

// The pixels of `grid` whose centres lie in the window `w` (a request's field "window"):
// INVALID_ARGUMENT when w is not finite or holds no pixel centre.
grpc::Status ToPixelRect(const v1::Window& w, const Grid& grid, PixelRect* rect);

// A request's window of the plane, checked: finite, min < max on both axes, a width and
// height that do not overflow (`field` names it in messages).
grpc::Status ToWindow(const v1::Window& w, const std::string& field, Window* out);

// width_px and height_px of a grid, checked against --max-side-px (and its square).
grpc::Status ToGridSize(uint32_t width, uint32_t height, const ServerLimits& limits, Grid* grid);

// A point given in field `field`, checked finite.
grpc::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec2* out);

// RenderImageRequest's layer, format, drawing options, window and polyline, checked together.
grpc::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid& grid,
                            ImageOptions* options);

// The same of a 3D scene: the options of one slice (z or slice), its rect of the slice's
// voxels.
grpc::Status ToImageOptions3(const v1::RenderImageRequest& request, const Grid3& grid,
                             ImageOptions* options);

// PickRequest's point and max_distance (0: no limit, returned as +infinity).
grpc::Status ToPick(const v1::PickRequest& request, Vec2* point, double* max_distance);
// The same for a 3D scene (point with z).
grpc::Status ToPick3(const v1::PickRequest& request, Vec3* point, double* max_distance);

grpc::Status ToBoundaryMethod(const v1::GetBoundariesRequest& request, BoundaryMethod* method);
grpc::Status ToPathPreference(const v1::PlanPathRequest& request, PathPreference* prefer);

v1::FeatureKind ToProto(FeatureKind k);
void ToProto(Vec2 p, v1::Point* out);
void ToProto(Vec3 p, v1::Point* out);
void ToProto(const Site& site, v1::Site* out);
void ToProto(const Site3& site, v1::Site* out);
void ToProto(const Window& w, v1::Window* out);
void ToProto(const SceneSettings& settings, v1::Scene* out);  // the settings' fields only
void ToProto(const Scene& scene, v1::Scene* out);
void ToProto(const Scene3& scene, v1::Scene* out);
// A replica's lag behind its shared store (nothing on a server with a store of its own).
void ToProto(const SceneRegistry::StoreLag& lag, v1::Scene* out);

// absl::Status from the render and scene layers to a gRPC status with the same code.
grpc::Status ToGrpc(const absl::Status& status);

}  // namespace gvd
