#include "server/convert.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <unordered_set>

#include "absl/strings/str_cat.h"
#include "render/mesh.h"

namespace gvd {
namespace {

using grpc::Status;
using grpc::StatusCode;

Status Invalid(std::string message) { return Status(StatusCode::INVALID_ARGUMENT, message); }

// "sites[3].point" and the like.
std::string Indexed(const std::string& field, size_t i) { return absl::StrCat(field, "[", i, "]"); }

Status CheckFinite(double v, const std::string& field) {
  if (std::isfinite(v)) return Status::OK;
  return Invalid(absl::StrCat(field, " is ", FormatNumber(v), "; coordinates must be finite"));
}

Status CheckPoint(const v1::Point& p, const std::string& field) {
  if (auto s = CheckFinite(p.x(), absl::StrCat(field, ".x")); !s.ok()) return s;
  return CheckFinite(p.y(), absl::StrCat(field, ".y"));
}

std::string Quoted(const std::string& s, size_t max = 64) {
  return absl::StrCat("\"", s.size() > max ? s.substr(0, max) + "..." : s, "\"");
}

}  // namespace

std::string FormatNumber(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];  // the shortest form that reads back as v
  auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  return std::string(buf, end);
}

Status ValidateSceneId(const std::string& id, const ServerLimits& limits, const char* field) {
  if (id.empty()) return Invalid(absl::StrCat(field, " is empty"));
  if (id.size() > limits.max_scene_id_chars) {
    return Invalid(absl::StrCat(field, " ", Quoted(id), " is ", id.size(),
                                " characters; the limit is ", limits.max_scene_id_chars));
  }
  for (char c : id) {
    bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '.' || c == '_' || c == '-';
    if (!ok) {
      return Invalid(absl::StrCat(field, " ", Quoted(id),
                                  " may hold only letters, digits, '.', '_' and '-'"));
    }
  }
  return Status::OK;
}

Status ToSceneSettings(const v1::CreateSceneRequest& r, const ServerLimits& limits,
                       SceneSettings* settings) {
  if (auto s = ValidateSceneId(r.scene_id(), limits); !s.ok()) return s;
  if (!r.has_window()) return Invalid("window is not set");
  const v1::Window& w = r.window();
  for (auto [v, name] : {std::pair{w.min_x(), "window.min_x"}, {w.min_y(), "window.min_y"},
                         {w.max_x(), "window.max_x"}, {w.max_y(), "window.max_y"}}) {
    if (auto s = CheckFinite(v, name); !s.ok()) return s;
  }
  if (!(w.min_x() < w.max_x())) {
    return Invalid(absl::StrCat("window.min_x ", FormatNumber(w.min_x()),
                                " must be less than window.max_x ", FormatNumber(w.max_x())));
  }
  if (!(w.min_y() < w.max_y())) {
    return Invalid(absl::StrCat("window.min_y ", FormatNumber(w.min_y()),
                                " must be less than window.max_y ", FormatNumber(w.max_y())));
  }
  if (!std::isfinite(w.max_x() - w.min_x()) || !std::isfinite(w.max_y() - w.min_y())) {
    return Invalid("window is too large: its width or height overflows a double");
  }
  for (auto [v, name] : {std::pair{r.width_px(), "width_px"}, {r.height_px(), "height_px"}}) {
    if (v == 0 || v > limits.max_side_px) {
      return Invalid(absl::StrCat(name, " is ", v, "; it must be 1 to ", limits.max_side_px,
                                  " (--max-side-px)"));
    }
  }
  uint64_t pixels = uint64_t{r.width_px()} * r.height_px();
  if (pixels > limits.max_scene_pixels) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("width_px x height_px is ", pixels, " pixels; the limit is ",
                               limits.max_scene_pixels, " (--max-side-px squared)"));
  }
  Grid grid{{w.min_x(), w.min_y(), w.max_x(), w.max_y()}, r.width_px(), r.height_px()};
  double eps = r.max_error();
  if (!std::isfinite(eps) || eps < 0) {
    return Invalid(absl::StrCat("max_error is ", FormatNumber(eps),
                                "; it must be finite and not negative (0 means one pixel)"));
  }
  double pixel = grid.pixel_size();
  if (eps == 0) eps = pixel;
  if (eps < pixel / 64) {
    return Invalid(absl::StrCat("max_error ", FormatNumber(eps),
                                " is below 1/64 pixel (", FormatNumber(pixel / 64),
                                " scene units), which would need too many triangles per cone"));
  }
  if (!(eps > 0)) return Invalid("max_error underflows to 0 for this window");
  settings->id = r.scene_id();
  settings->grid = grid;
  settings->eps = eps;
  settings->cone_triangles = ConeSegments(grid.window.diagonal() + eps, eps);
  switch (r.render_mode()) {
    case v1::RENDER_MODE_UNSPECIFIED:
    case v1::MESH:
      settings->mode = RenderMode::kMesh;
      break;
    case v1::EXACT:
      settings->mode = RenderMode::kExact;
      break;
    default:
      return Invalid(absl::StrCat("render_mode is ", r.render_mode(), "; it must be MESH or EXACT"));
  }
  return Status::OK;
}

Status ToSites(const v1::UpsertSitesRequest& r, const ServerLimits& limits,
               std::vector<Site>* sites) {
  if (r.sites_size() == 0) return Invalid("sites is empty");
  if (size_t(r.sites_size()) > limits.max_sites_per_request) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("sites has ", r.sites_size(), " entries; the limit per request is ",
                               limits.max_sites_per_request, " (--max-sites-per-request)"));
  }
  std::unordered_map<std::string_view, size_t> seen;
  sites->clear();
  sites->reserve(r.sites_size());
  for (int i = 0; i < r.sites_size(); ++i) {
    const v1::Site& s = r.sites(i);
    std::string field = Indexed("sites", i);
    if (s.id().empty()) return Invalid(absl::StrCat(field, ".id is empty"));
    if (s.id().size() > limits.max_site_id_bytes) {
      return Invalid(absl::StrCat(field, ".id ", Quoted(s.id()), " is ", s.id().size(),
                                  " bytes; the limit is ", limits.max_site_id_bytes));
    }
    auto [it, fresh] = seen.emplace(s.id(), i);
    if (!fresh) {
      return Invalid(absl::StrCat(field, ".id ", Quoted(s.id()), " repeats sites[", it->second,
                                  "].id; ids in one request must be distinct"));
    }
    switch (s.geometry_case()) {
      case v1::Site::kPoint: {
        if (auto st = CheckPoint(s.point(), field + ".point"); !st.ok()) return st;
        sites->push_back({s.id(), PointSite{{s.point().x(), s.point().y()}}});
        break;
      }
      case v1::Site::GEOMETRY_NOT_SET:
        return Invalid(absl::StrCat(field, ".geometry is not set (site ", Quoted(s.id()), ")"));
    }
  }
  return Status::OK;
}

Status ToSiteIds(const v1::DeleteSitesRequest& r, const ServerLimits& limits,
                 std::vector<std::string>* ids) {
  if (r.ids_size() == 0) return Invalid("ids is empty");
  if (size_t(r.ids_size()) > limits.max_sites_per_request) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("ids has ", r.ids_size(), " entries; the limit per request is ",
                               limits.max_sites_per_request, " (--max-sites-per-request)"));
  }
  std::unordered_map<std::string_view, size_t> seen;
  for (int i = 0; i < r.ids_size(); ++i) {
    const std::string& id = r.ids(i);
    if (id.empty()) return Invalid(absl::StrCat(Indexed("ids", i), " is empty"));
    auto [it, fresh] = seen.emplace(id, i);
    if (!fresh) {
      return Invalid(absl::StrCat(Indexed("ids", i), " ", Quoted(id), " repeats ids[",
                                  it->second, "]"));
    }
  }
  ids->assign(r.ids().begin(), r.ids().end());
  return Status::OK;
}

Status ToQueryPoints(const v1::FindNearestRequest& r, const Window& w, const ServerLimits& limits,
                     std::vector<Vec2>* points, bool* outside) {
  if (r.points_size() > 0 && r.xy_size() > 0) {
    return Invalid("points and xy are both set; use one form");
  }
  if (r.xy_size() % 2 != 0) {
    return Invalid(absl::StrCat("xy has ", r.xy_size(), " values; it needs x, y pairs"));
  }
  const size_t n = r.xy_size() > 0 ? r.xy_size() / 2 : r.points_size();
  if (n == 0) return Invalid("points is empty");
  if (n > limits.max_points_per_query) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat(r.xy_size() > 0 ? "xy" : "points", " has ", n,
                               " points; the limit per query is ", limits.max_points_per_query,
                               " (--max-points-per-query)"));
  }
  points->resize(n);
  *outside = false;
  if (r.xy_size() > 0) {
    for (int i = 0; i < r.xy_size(); ++i) {
      if (auto s = CheckFinite(r.xy(i), Indexed("xy", i)); !s.ok()) return s;
    }
    for (size_t i = 0; i < n; ++i) (*points)[i] = {r.xy(2 * i), r.xy(2 * i + 1)};
  } else {
    for (int i = 0; i < r.points_size(); ++i) {
      if (auto s = CheckPoint(r.points(i), Indexed("points", i)); !s.ok()) return s;
      (*points)[i] = {r.points(i).x(), r.points(i).y()};
    }
  }
  for (const Vec2& p : *points) *outside = *outside || !w.Contains(p);
  return Status::OK;
}

void ToProto(const Site& site, v1::Site* out) {
  out->set_id(site.id);
  const auto& p = std::get<PointSite>(site.geometry).p;
  out->mutable_point()->set_x(p.x);
  out->mutable_point()->set_y(p.y);
}

void ToProto(const Scene& scene, v1::Scene* out) {
  const SceneSettings& s = scene.settings();
  out->set_scene_id(s.id);
  v1::Window* w = out->mutable_window();
  w->set_min_x(s.grid.window.min_x);
  w->set_min_y(s.grid.window.min_y);
  w->set_max_x(s.grid.window.max_x);
  w->set_max_y(s.grid.window.max_y);
  out->set_width_px(s.grid.width);
  out->set_height_px(s.grid.height);
  out->set_max_error(s.eps);
  out->set_version(scene.version());
  out->set_site_count(scene.site_count());
  out->set_rendered_version(scene.frame()->version());
  out->set_cone_triangles(s.cone_triangles);
  out->set_render_mode(s.mode == RenderMode::kExact ? v1::EXACT : v1::MESH);
}

grpc::Status ToGrpc(const absl::Status& status) {
  if (status.ok()) return Status::OK;
  return Status(static_cast<StatusCode>(status.code()), std::string(status.message()));
}

}  // namespace gvd
