#include "server/app/convert/common.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "server/log.h"

namespace gvd {

absl::Status Invalid(std::string message) { return absl::InvalidArgumentError(message); }

std::string Quoted(const std::string& s, size_t max) {
  return absl::StrCat("\"", s.size() > max ? s.substr(0, max) + "..." : s, "\"");
}

std::string FieldPath::str() const {
  std::string s = parent_ == nullptr ? "" : parent_->str();
  if (!name_.empty()) {
    if (!s.empty()) s += '.';
    s.append(name_);
  }
  if (index_ >= 0) absl::StrAppend(&s, "[", index_, "]");
  return s;
}

absl::Status ValidateSceneId(const std::string& id, const ServerLimits& limits, const char* field) {
  if (id.empty()) return Invalid(absl::StrCat(field, " is empty"));
  if (id.size() > limits.max_scene_id_chars) {
    return Invalid(absl::StrCat(field, " ", Quoted(id), " is ", id.size(),
                                " characters; the limit is ", limits.max_scene_id_chars));
  }
  for (char c : id) {
    bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '.' || c == '_' || c == '-';
    if (!ok) {
      return Invalid(
          absl::StrCat(field, " ", Quoted(id), " may hold only letters, digits, '.', '_' and '-'"));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckFinite(double v, const FieldPath& field) {
  if (std::isfinite(v)) return absl::OkStatus();
  return Invalid(
      absl::StrCat(field.str(), " is ", FormatNumber(v), "; coordinates must be finite"));
}

absl::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec2* out) {
  if (auto s = CheckFinite(p.x(), field.Member("x")); !s.ok()) return s;
  if (auto s = CheckFinite(p.y(), field.Member("y")); !s.ok()) return s;
  if (p.z() != 0) {
    return Invalid(absl::StrCat(field.Member("z").str(), " is ", FormatNumber(p.z()),
                                "; points of a 2D scene have no z"));
  }
  *out = {p.x(), p.y()};
  return absl::OkStatus();
}

absl::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec3* out) {
  if (auto s = CheckFinite(p.x(), field.Member("x")); !s.ok()) return s;
  if (auto s = CheckFinite(p.y(), field.Member("y")); !s.ok()) return s;
  if (auto s = CheckFinite(p.z(), field.Member("z")); !s.ok()) return s;
  *out = {p.x(), p.y(), p.z()};
  return absl::OkStatus();
}

absl::Status ToWindow(const v1::Window& w, const std::string& field, Window* out) {
  const FieldPath window(field.c_str());
  for (auto [v, name] : {std::pair{w.min_x(), "min_x"},
                         {w.min_y(), "min_y"},
                         {w.max_x(), "max_x"},
                         {w.max_y(), "max_y"}}) {
    if (auto s = CheckFinite(v, window.Member(name)); !s.ok()) return s;
  }
  if (!(w.min_x() < w.max_x())) {
    return Invalid(absl::StrCat(field, ".min_x ", FormatNumber(w.min_x()), " must be less than ",
                                field, ".max_x ", FormatNumber(w.max_x())));
  }
  if (!(w.min_y() < w.max_y())) {
    return Invalid(absl::StrCat(field, ".min_y ", FormatNumber(w.min_y()), " must be less than ",
                                field, ".max_y ", FormatNumber(w.max_y())));
  }
  if (!std::isfinite(w.max_x() - w.min_x()) || !std::isfinite(w.max_y() - w.min_y())) {
    return Invalid(absl::StrCat(field, " is too large: its width or height overflows a double"));
  }
  *out = {w.min_x(), w.min_y(), w.max_x(), w.max_y()};
  return absl::OkStatus();
}

absl::Status ToGridSize(uint32_t width, uint32_t height, const ServerLimits& limits, Grid* grid) {
  for (auto [v, name] : {std::pair{width, "width_px"}, {height, "height_px"}}) {
    if (v == 0 || v > limits.max_side_px) {
      return Invalid(absl::StrCat(name, " is ", v, "; it must be 1 to ", limits.max_side_px,
                                  " (--max-side-px)"));
    }
  }
  uint64_t pixels = uint64_t{width} * height;
  if (pixels > limits.max_scene_pixels) {
    return absl::ResourceExhaustedError(
        absl::StrCat("width_px x height_px is ", pixels, " pixels; the limit is ",
                     limits.max_scene_pixels, " (--max-side-px squared)"));
  }
  grid->width = width;
  grid->height = height;
  return absl::OkStatus();
}

absl::Status ToPixelRect(const v1::Window& w, const Grid& grid, PixelRect* rect) {
  for (double v : {w.min_x(), w.min_y(), w.max_x(), w.max_y()}) {
    if (!std::isfinite(v)) {
      return Invalid(
          absl::StrCat("window holds ", FormatNumber(v), "; coordinates must be finite"));
    }
  }
  *rect = grid.CentresIn({w.min_x(), w.min_y()}, {w.max_x(), w.max_y()});
  if (rect->empty()) {
    return Invalid(absl::StrCat("window [", FormatNumber(w.min_x()), ", ", FormatNumber(w.max_x()),
                                "] x [", FormatNumber(w.min_y()), ", ", FormatNumber(w.max_y()),
                                "] holds no pixel centre of the scene"));
  }
  return absl::OkStatus();
}

v1::FeatureKind ToProto(FeatureKind k) {
  switch (k) {
    case FeatureKind::kVertex:
      return v1::FEATURE_KIND_VERTEX;
    case FeatureKind::kEdge:
      return v1::FEATURE_KIND_EDGE;
    case FeatureKind::kCurve:
      return v1::FEATURE_KIND_CURVE;
    case FeatureKind::kFace:
      return v1::FEATURE_KIND_FACE;
  }
  return v1::FEATURE_KIND_UNSPECIFIED;
}

void ToProto(Vec2 p, v1::Point* out) {
  out->set_x(p.x);
  out->set_y(p.y);
}

void ToProto(Vec3 p, v1::Point* out) {
  out->set_x(p.x);
  out->set_y(p.y);
  out->set_z(p.z);
}

void ToProto(const Window& w, v1::Window* out) {
  out->set_min_x(w.min_x);
  out->set_min_y(w.min_y);
  out->set_max_x(w.max_x);
  out->set_max_y(w.max_y);
}

void ToProto(const Box3& b, v1::Window* out) {
  out->set_min_x(b.min_x);
  out->set_min_y(b.min_y);
  out->set_min_z(b.min_z);
  out->set_max_x(b.max_x);
  out->set_max_y(b.max_y);
  out->set_max_z(b.max_z);
}

}  // namespace gvd
