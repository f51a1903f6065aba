// What every conversion of API messages into the core's types shares: the name of a request's
// field in messages (FieldPath), the checks of identifiers, numbers, points, windows and grid
// sizes, and the way back of points, windows and features. Every refusal is INVALID_ARGUMENT
// (RESOURCE_EXHAUSTED past a limit) naming the field, with its index, and the value; nothing
// here mutates.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/kernel/exact2.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site3.h"
#include "server/app/limits.h"

namespace gvd {

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

// INVALID_ARGUMENT with `message`.
absl::Status Invalid(std::string message);
// A text quoted for a message, cut at `max` characters.
std::string Quoted(const std::string& s, size_t max = 64);

// 1 to --max-scene-id-chars characters of [A-Za-z0-9._-].
absl::Status ValidateSceneId(const std::string& id, const ServerLimits& limits,
                             const char* field = "scene_id");

// A coordinate, checked finite.
absl::Status CheckFinite(double v, const FieldPath& field);

// A point of a scene of the output's dimension, checked finite: a 2D scene's has no z.
absl::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec2* out);
absl::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec3* out);

// A request's window of the plane, checked: finite, min < max on both axes, a width and
// height that do not overflow (`field` names it in messages).
absl::Status ToWindow(const v1::Window& w, const std::string& field, Window* out);

// width_px and height_px of a grid, checked against --max-side-px (and its square).
absl::Status ToGridSize(uint32_t width, uint32_t height, const ServerLimits& limits, Grid* grid);

// The pixels of `grid` whose centres lie in the window `w` (a request's field "window"):
// INVALID_ARGUMENT when w is not finite or holds no pixel centre.
absl::Status ToPixelRect(const v1::Window& w, const Grid& grid, PixelRect* rect);

v1::FeatureKind ToProto(FeatureKind k);
void ToProto(Vec2 p, v1::Point* out);
void ToProto(Vec3 p, v1::Point* out);
void ToProto(const Window& w, v1::Window* out);
void ToProto(const Box3& box, v1::Window* out);

}  // namespace gvd
