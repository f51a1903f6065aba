#include "server/grpc/convert.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <unordered_set>

#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/kernel/exact3.h"
#include "render/plan/distance_mesh.h"

namespace gvd {
namespace {

using grpc::Status;
using grpc::StatusCode;

Status Invalid(std::string message) { return Status(StatusCode::INVALID_ARGUMENT, message); }

std::string Quoted(const std::string& s, size_t max = 64) {
  return absl::StrCat("\"", s.size() > max ? s.substr(0, max) + "..." : s, "\"");
}

Status CheckFinite(double v, const FieldPath& field) {
  if (std::isfinite(v)) return Status::OK;
  return Invalid(
      absl::StrCat(field.str(), " is ", FormatNumber(v), "; coordinates must be finite"));
}

// A point of a 2D scene: finite, and no z.
Status CheckPoint(const v1::Point& p, const FieldPath& field) {
  if (auto s = CheckFinite(p.x(), field.Member("x")); !s.ok()) return s;
  if (auto s = CheckFinite(p.y(), field.Member("y")); !s.ok()) return s;
  if (p.z() != 0) {
    return Invalid(absl::StrCat(field.Member("z").str(), " is ", FormatNumber(p.z()),
                                "; points of a 2D scene have no z"));
  }
  return Status::OK;
}

// A point of a 3D scene, checked finite.
Status ToPoint3(const v1::Point& p, const FieldPath& field, Vec3* out) {
  if (auto s = CheckFinite(p.x(), field.Member("x")); !s.ok()) return s;
  if (auto s = CheckFinite(p.y(), field.Member("y")); !s.ok()) return s;
  if (auto s = CheckFinite(p.z(), field.Member("z")); !s.ok()) return s;
  *out = {p.x(), p.y(), p.z()};
  return Status::OK;
}

// The weights and reach of a site of either dimension, checked, into `site`.
template <class S>
Status ToWeights(const v1::Site& s, const FieldPath& field, S* site) {
  double a = s.additive_weight(), m = s.multiplicative_weight(), r = s.max_distance();
  if (!std::isfinite(a) || a < 0 || a > 1e15) {
    return Invalid(absl::StrCat(field.str(), ".additive_weight is ", FormatNumber(a),
                                "; it must be 0 to 1e15"));
  }
  if (!std::isfinite(m) || m < 0 || m > 1e6 || (m != 0 && m < 1e-6)) {
    return Invalid(absl::StrCat(field.str(), ".multiplicative_weight is ", FormatNumber(m),
                                "; it must be 0 (meaning 1) or 1e-6 to 1e6"));
  }
  if (!std::isfinite(r) || r < 0) {
    return Invalid(absl::StrCat(field.str(), ".max_distance is ", FormatNumber(r),
                                "; it must be finite and positive, or 0 for none"));
  }
  site->additive = a;
  site->multiplicative = m == 0 ? 1 : m;
  site->max_distance = r == 0 ? INFINITY : r;
  return Status::OK;
}

// The sites of an UpsertSitesRequest, ids checked (non-empty, short, distinct), each
// converted by `convert` (ToSite or ToSite3).
template <class S, class Convert>
Status ToSitesWith(const v1::UpsertSitesRequest& r, const ServerLimits& limits,
                   std::vector<S>* sites, Convert&& convert) {
  if (r.sites_size() == 0) return Invalid("sites is empty");
  if (size_t(r.sites_size()) > limits.max_sites_per_request) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("sites has ", r.sites_size(), " entries; the limit per request is ",
                               limits.max_sites_per_request, " (--max-sites-per-request)"));
  }
  std::unordered_map<std::string_view, size_t> seen;
  seen.reserve(r.sites_size());
  sites->clear();
  sites->reserve(r.sites_size());
  const FieldPath all("sites");
  for (int i = 0; i < r.sites_size(); ++i) {
    const v1::Site& s = r.sites(i);
    const FieldPath field = all[i];
    if (s.id().empty()) return Invalid(absl::StrCat(field.str(), ".id is empty"));
    if (s.id().size() > limits.max_site_id_bytes) {
      return Invalid(absl::StrCat(field.str(), ".id ", Quoted(s.id()), " is ", s.id().size(),
                                  " bytes; the limit is ", limits.max_site_id_bytes));
    }
    auto [it, fresh] = seen.emplace(s.id(), i);
    if (!fresh) {
      return Invalid(absl::StrCat(field.str(), ".id ", Quoted(s.id()), " repeats sites[",
                                  it->second, "].id; ids in one request must be distinct"));
    }
    S site;
    if (auto st = convert(s, field, limits, &site); !st.ok()) return st;
    sites->push_back(std::move(site));
  }
  return Status::OK;
}


}  // namespace

std::string FieldPath::str() const {
  std::string s = parent_ == nullptr ? "" : parent_->str();
  if (!name_.empty()) {
    if (!s.empty()) s += '.';
    s.append(name_);
  }
  if (index_ >= 0) absl::StrAppend(&s, "[", index_, "]");
  return s;
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
    return Invalid(absl::StrCat("max_error ", FormatNumber(eps),
                                " is below 1/64 pixel (", FormatNumber(pixel / 64),
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
      return Status(StatusCode::RESOURCE_EXHAUSTED,
                    absl::StrCat("width_px x height_px x depth_px is ", voxels,
                                 " voxels; the limit is ", limits.max_voxels_per_scene,
                                 " (--max-voxels-per-scene)"));
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
    case v1::MESH:
      settings->mode = RenderMode::kMesh;
      break;
    case v1::EXACT:
      settings->mode = RenderMode::kExact;
      break;
    default:
      return Invalid(absl::StrCat("render_mode is ", r.render_mode(), "; it must be MESH or EXACT"));
  }
  // A 3D scene is rendered exactly per voxel, whatever the mode asked.
  if (settings->three_d()) settings->mode = RenderMode::kExact;
  switch (r.diagram()) {
    case v1::DIAGRAM_UNSPECIFIED:
    case v1::NEAREST:
      settings->diagram = Diagram::kNearest;
      break;
    case v1::FARTHEST:
      settings->diagram = Diagram::kFarthest;
      break;
    default:
      return Invalid(absl::StrCat("diagram is ", r.diagram(), "; it must be NEAREST or FARTHEST"));
  }
  return Status::OK;
}

Status ToSite(const v1::Site& s, const FieldPath& field, const ServerLimits& limits,
              Site* site) {
  site->id = s.id();
  auto points = [&](const auto& list, const FieldPath& name, size_t min,
                    std::vector<Vec2>* out) -> Status {
    if (size_t(list.size()) < min) {
      return Invalid(absl::StrCat(name.str(), " has ", list.size(), " points; it needs at least ",
                                  min, " (site ", Quoted(s.id()), ")"));
    }
    if (size_t(list.size()) > limits.max_vertices_per_site) {
      return Status(StatusCode::RESOURCE_EXHAUSTED,
                    absl::StrCat(name.str(), " has ", list.size(), " points; the limit is ",
                                 limits.max_vertices_per_site, " (--max-vertices-per-site)"));
    }
    out->clear();
    out->reserve(list.size());
    for (int k = 0; k < list.size(); ++k) {
      if (auto st = CheckPoint(list[k], name[k]); !st.ok()) return st;
      out->push_back({list[k].x(), list[k].y()});
    }
    return Status::OK;
  };
  switch (s.geometry_case()) {
    case v1::Site::kPoint: {
      if (auto st = CheckPoint(s.point(), field.Member("point")); !st.ok()) return st;
      site->geometry = PointSite{{s.point().x(), s.point().y()}};
      break;
    }
    case v1::Site::kSegment: {
      const FieldPath segment = field.Member("segment");
      if (auto st = CheckPoint(s.segment().a(), segment.Member("a")); !st.ok()) return st;
      if (auto st = CheckPoint(s.segment().b(), segment.Member("b")); !st.ok()) return st;
      site->geometry = SegmentSite{{s.segment().a().x(), s.segment().a().y()},
                                   {s.segment().b().x(), s.segment().b().y()}};
      break;
    }
    case v1::Site::kPolyline: {
      PolylineSite l;
      const FieldPath polyline = field.Member("polyline");
      if (auto st = points(s.polyline().points(), polyline.Member("points"), 2, &l.points);
          !st.ok()) {
        return st;
      }
      site->geometry = std::move(l);
      break;
    }
    case v1::Site::kPolygon: {
      PolygonSite poly;
      const FieldPath polygon = field.Member("polygon");
      if (auto st = points(s.polygon().vertices(), polygon.Member("vertices"), 3, &poly.vertices);
          !st.ok()) {
        return st;
      }
      switch (s.polygon().side()) {
        case v1::Polygon::SIDE_UNSPECIFIED: poly.side = Side::kBoth; break;
        case v1::Polygon::OUTSIDE: poly.side = Side::kOutside; break;
        case v1::Polygon::INSIDE: poly.side = Side::kInside; break;
        default:
          return Invalid(absl::StrCat(field.str(), ".polygon.side is ", s.polygon().side(),
                                      "; it must be SIDE_UNSPECIFIED, OUTSIDE or INSIDE"));
      }
      site->geometry = std::move(poly);
      break;
    }
    case v1::Site::kBezier: {
      std::vector<Vec2> control;
      const FieldPath bezier = field.Member("bezier");
      const FieldPath name = bezier.Member("control_points");
      if (auto st = points(s.bezier().control_points(), name, 3, &control); !st.ok()) return st;
      if (control.size() > 4) {
        return Invalid(absl::StrCat(name.str(), " has ", control.size(),
                                    " points; a Bezier takes 3 (quadratic) or 4 (cubic)"));
      }
      double tol = s.bezier().tolerance();
      if (!std::isfinite(tol) || tol < 0) {
        return Invalid(absl::StrCat(field.str(), ".bezier.tolerance is ", FormatNumber(tol),
                                    "; it must be finite and not negative (0 means a "
                                    "thousandth of the control polygon)"));
      }
      site->geometry = MakeBezier(std::move(control), tol);
      break;
    }
    case v1::Site::kTriangle:
    case v1::Site::kMesh:
      return Invalid(absl::StrCat(field.str(), ".", s.has_triangle() ? "triangle" : "mesh",
                                  " is a site of 3D scenes; this scene is 2D (site ",
                                  Quoted(s.id()), ")"));
    case v1::Site::GEOMETRY_NOT_SET:
      return Invalid(absl::StrCat(field.str(), ".geometry is not set (site ", Quoted(s.id()), ")"));
  }
  // Extents must stay finite for distances to be.
  Window box = BoundingBox(site->geometry);
  if (!std::isfinite(box.width()) || !std::isfinite(box.height())) {
    return Invalid(absl::StrCat(field.str(), " spans ", FormatNumber(box.width()), " x ",
                                FormatNumber(box.height()),
                                ", which overflows a double (site ", Quoted(s.id()), ")"));
  }
  return ToWeights(s, field, site);
}

Status ToSites(const v1::UpsertSitesRequest& r, const ServerLimits& limits,
               std::vector<Site>* sites) {
  return ToSitesWith(r, limits, sites,
                     [](const v1::Site& s, const FieldPath& field, const ServerLimits& limits,
                        Site* out) { return ToSite(s, field, limits, out); });
}

Status ToSite3(const v1::Site& s, const FieldPath& field, const ServerLimits& limits,
               Site3* site) {
  site->id = s.id();
  switch (s.geometry_case()) {
    case v1::Site::kPoint: {
      Vec3 p;
      if (auto st = ToPoint3(s.point(), field.Member("point"), &p); !st.ok()) return st;
      site->geometry = PointSite3{p};
      break;
    }
    case v1::Site::kSegment: {
      const FieldPath segment = field.Member("segment");
      SegmentSite3 g;
      if (auto st = ToPoint3(s.segment().a(), segment.Member("a"), &g.a); !st.ok()) return st;
      if (auto st = ToPoint3(s.segment().b(), segment.Member("b"), &g.b); !st.ok()) return st;
      site->geometry = g;
      break;
    }
    case v1::Site::kTriangle: {
      const FieldPath triangle = field.Member("triangle");
      TriangleSite3 g;
      if (auto st = ToPoint3(s.triangle().a(), triangle.Member("a"), &g.a); !st.ok()) return st;
      if (auto st = ToPoint3(s.triangle().b(), triangle.Member("b"), &g.b); !st.ok()) return st;
      if (auto st = ToPoint3(s.triangle().c(), triangle.Member("c"), &g.c); !st.ok()) return st;
      site->geometry = g;
      break;
    }
    case v1::Site::kMesh: {
      const v1::Mesh& m = s.mesh();
      if (size_t(m.triangles_size()) / 3 > limits.max_triangles_per_mesh) {
        return Status(StatusCode::RESOURCE_EXHAUSTED,
                      absl::StrCat(field.str(), ".mesh.triangles holds ", m.triangles_size() / 3,
                                   " triangles; the limit is ", limits.max_triangles_per_mesh,
                                   " (--max-triangles-per-mesh)"));
      }
      auto mesh = MakeMesh(std::vector<double>(m.xyz().begin(), m.xyz().end()),
                           std::vector<uint32_t>(m.triangles().begin(), m.triangles().end()),
                           limits.max_triangles_per_mesh);
      if (!mesh.ok()) {
        return Invalid(absl::StrCat(field.str(), ".mesh.", mesh.status().message(), " (site ",
                                    Quoted(s.id()), ")"));
      }
      site->geometry = *std::move(mesh);
      break;
    }
    case v1::Site::kPolyline:
    case v1::Site::kPolygon:
    case v1::Site::kBezier:
      return Invalid(absl::StrCat(field.str(), " is a ",
                                  s.has_polyline() ? "polyline" : s.has_polygon() ? "polygon" : "bezier",
                                  "; a 3D scene takes point, segment, triangle and mesh sites (site ",
                                  Quoted(s.id()), ")"));
    case v1::Site::GEOMETRY_NOT_SET:
      return Invalid(absl::StrCat(field.str(), ".geometry is not set (site ", Quoted(s.id()), ")"));
  }
  const Box3 box = BoundingBox(site->geometry);
  if (!std::isfinite(box.max_x - box.min_x) || !std::isfinite(box.max_y - box.min_y) ||
      !std::isfinite(box.max_z - box.min_z)) {
    return Invalid(absl::StrCat(field.str(), " spans more than a double holds (site ",
                                Quoted(s.id()), ")"));
  }
  return ToWeights(s, field, site);
}

Status ToSites3(const v1::UpsertSitesRequest& r, const ServerLimits& limits,
                std::vector<Site3>* sites) {
  return ToSitesWith(r, limits, sites, ToSite3);
}

Status ToDurability(v1::Durability durability, Durability* out) {
  switch (durability) {
    case v1::DURABILITY_UNSPECIFIED:
    case v1::SYNC:
      *out = Durability::kSync;
      return Status::OK;
    case v1::RELAXED:
      *out = Durability::kRelaxed;
      return Status::OK;
    default:
      return Invalid(absl::StrCat("durability is ", durability, "; it must be SYNC or RELAXED"));
  }
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
    if (id.empty()) return Invalid(absl::StrCat(FieldPath("ids")[i].str(), " is empty"));
    auto [it, fresh] = seen.emplace(id, i);
    if (!fresh) {
      return Invalid(absl::StrCat(FieldPath("ids")[i].str(), " ", Quoted(id), " repeats ids[",
                                  it->second, "]"));
    }
  }
  ids->assign(r.ids().begin(), r.ids().end());
  return Status::OK;
}

Status ToQueryPoints(const v1::FindNearestRequest& r, const Window& w, const ServerLimits& limits,
                     std::vector<Vec2>* points, bool* outside) {
  if (r.xyz_size() > 0) return Invalid("xyz is for 3D scenes; a 2D scene's packed points are xy");
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
      if (auto s = CheckFinite(r.xy(i), FieldPath("xy")[i]); !s.ok()) return s;
    }
    for (size_t i = 0; i < n; ++i) (*points)[i] = {r.xy(2 * i), r.xy(2 * i + 1)};
  } else {
    for (int i = 0; i < r.points_size(); ++i) {
      if (auto s = CheckPoint(r.points(i), FieldPath("points")[i]); !s.ok()) return s;
      (*points)[i] = {r.points(i).x(), r.points(i).y()};
    }
  }
  for (const Vec2& p : *points) *outside = *outside || !w.Contains(p);
  return Status::OK;
}

Status ToQueryPoints3(const v1::FindNearestRequest& r, const Box3& box,
                      const ServerLimits& limits, std::vector<Vec3>* points, bool* outside) {
  if (r.xy_size() > 0) return Invalid("xy is for 2D scenes; a 3D scene's packed points are xyz");
  if (r.points_size() > 0 && r.xyz_size() > 0) {
    return Invalid("points and xyz are both set; use one form");
  }
  if (r.xyz_size() % 3 != 0) {
    return Invalid(absl::StrCat("xyz has ", r.xyz_size(), " values; it needs x, y, z triples"));
  }
  const size_t n = r.xyz_size() > 0 ? r.xyz_size() / 3 : r.points_size();
  if (n == 0) return Invalid("points is empty");
  if (n > limits.max_points_per_query) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat(r.xyz_size() > 0 ? "xyz" : "points", " has ", n,
                               " points; the limit per query is ", limits.max_points_per_query,
                               " (--max-points-per-query)"));
  }
  points->resize(n);
  if (r.xyz_size() > 0) {
    for (int i = 0; i < r.xyz_size(); ++i) {
      if (auto s = CheckFinite(r.xyz(i), FieldPath("xyz")[i]); !s.ok()) return s;
    }
    for (size_t i = 0; i < n; ++i) (*points)[i] = {r.xyz(3 * i), r.xyz(3 * i + 1), r.xyz(3 * i + 2)};
  } else {
    for (int i = 0; i < r.points_size(); ++i) {
      if (auto s = ToPoint3(r.points(i), FieldPath("points")[i], &(*points)[i]); !s.ok()) return s;
    }
  }
  *outside = false;
  for (const Vec3& p : *points) *outside = *outside || !box.Contains(p);
  return Status::OK;
}

void ToProto(Vec3 p, v1::Point* out) {
  out->set_x(p.x);
  out->set_y(p.y);
  out->set_z(p.z);
}

void ToProto(const Site3& site, v1::Site* out) {
  out->set_id(site.id);
  if (const auto* p = std::get_if<PointSite3>(&site.geometry)) {
    ToProto(p->p, out->mutable_point());
  } else if (const auto* seg = std::get_if<SegmentSite3>(&site.geometry)) {
    ToProto(seg->a, out->mutable_segment()->mutable_a());
    ToProto(seg->b, out->mutable_segment()->mutable_b());
  } else if (const auto* t = std::get_if<TriangleSite3>(&site.geometry)) {
    ToProto(t->a, out->mutable_triangle()->mutable_a());
    ToProto(t->b, out->mutable_triangle()->mutable_b());
    ToProto(t->c, out->mutable_triangle()->mutable_c());
  } else {
    const auto& m = std::get<MeshSite3>(site.geometry);
    auto* mesh = out->mutable_mesh();
    mesh->mutable_xyz()->Reserve(static_cast<int>(3 * m.vertices.size()));
    for (Vec3 v : m.vertices) {
      mesh->add_xyz(v.x);
      mesh->add_xyz(v.y);
      mesh->add_xyz(v.z);
    }
    for (const auto& tri : m.triangles) {
      for (uint32_t k : tri) mesh->add_triangles(k);
    }
  }
  if (site.additive != 0) out->set_additive_weight(site.additive);
  if (site.multiplicative != 1) out->set_multiplicative_weight(site.multiplicative);
  if (std::isfinite(site.max_distance)) out->set_max_distance(site.max_distance);
}

void ToProto(Vec2 p, v1::Point* out) {
  out->set_x(p.x);
  out->set_y(p.y);
}

void ToProto(const Site& site, v1::Site* out) {
  out->set_id(site.id);
  if (const auto* p = std::get_if<PointSite>(&site.geometry)) {
    ToProto(p->p, out->mutable_point());
  } else if (const auto* seg = std::get_if<SegmentSite>(&site.geometry)) {
    ToProto(seg->a, out->mutable_segment()->mutable_a());
    ToProto(seg->b, out->mutable_segment()->mutable_b());
  } else if (const auto* l = std::get_if<PolylineSite>(&site.geometry)) {
    for (Vec2 q : l->points) ToProto(q, out->mutable_polyline()->add_points());
  } else if (const auto* poly = std::get_if<PolygonSite>(&site.geometry)) {
    for (Vec2 q : poly->vertices) ToProto(q, out->mutable_polygon()->add_vertices());
    out->mutable_polygon()->set_side(poly->side == Side::kOutside  ? v1::Polygon::OUTSIDE
                                     : poly->side == Side::kInside ? v1::Polygon::INSIDE
                                                                   : v1::Polygon::SIDE_UNSPECIFIED);
  } else if (const auto* b = std::get_if<BezierSite>(&site.geometry)) {
    for (Vec2 q : b->control) ToProto(q, out->mutable_bezier()->add_control_points());
    out->mutable_bezier()->set_tolerance(b->tolerance);
  }
  if (site.additive != 0) out->set_additive_weight(site.additive);
  if (site.multiplicative != 1) out->set_multiplicative_weight(site.multiplicative);
  if (std::isfinite(site.max_distance)) out->set_max_distance(site.max_distance);
}

void ToProto(const SceneSettings& s, v1::Scene* out) {
  out->set_scene_id(s.id);
  ToProto(s.grid.window, out->mutable_window());
  out->set_width_px(s.grid.width);
  out->set_height_px(s.grid.height);
  out->set_max_error(s.eps);
  out->set_cone_triangles(s.cone_triangles);
  out->set_render_mode(s.mode == RenderMode::kExact ? v1::EXACT : v1::MESH);
  out->set_diagram(s.diagram == Diagram::kFarthest ? v1::FARTHEST : v1::NEAREST);
  if (s.three_d()) {
    out->set_depth_px(s.depth);
    out->mutable_window()->set_min_z(s.min_z);
    out->mutable_window()->set_max_z(s.max_z);
  }
}

template <class S>
void SceneToProto(const S& scene, v1::Scene* out) {
  ToProto(scene.settings(), out);
  out->set_version(scene.version());
  out->set_site_count(scene.site_count());
  out->set_rendered_version(scene.frame()->version());
  out->set_memory_bytes(scene.memory_bytes());
}
void ToProto(const Scene& scene, v1::Scene* out) { SceneToProto(scene, out); }
void ToProto(const SceneRegistry::StoreLag& lag, v1::Scene* out) {
  if (lag.store_version == 0) return;
  out->set_store_version(lag.store_version);
  out->set_store_read_age_seconds(lag.read_age_seconds);
}
void ToProto(const Scene3& scene, v1::Scene* out) { SceneToProto(scene, out); }

grpc::Status ToGrpc(const absl::Status& status) {
  if (status.ok()) return Status::OK;
  return Status(static_cast<StatusCode>(status.code()), std::string(status.message()));
}

grpc::Status ToPixelRect(const v1::Window& w, const Grid& grid, PixelRect* rect) {
  for (double v : {w.min_x(), w.min_y(), w.max_x(), w.max_y()}) {
    if (!std::isfinite(v)) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          absl::StrCat("window holds ", FormatNumber(v),
                                       "; coordinates must be finite"));
    }
  }
  *rect = grid.CentresIn({w.min_x(), w.min_y()}, {w.max_x(), w.max_y()});
  if (rect->empty()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat("window [", FormatNumber(w.min_x()), ", ",
                                     FormatNumber(w.max_x()), "] x [", FormatNumber(w.min_y()),
                                     ", ", FormatNumber(w.max_y()),
                                     "] holds no pixel centre of the scene"));
  }
  return grpc::Status::OK;
}

grpc::Status ToClearanceSamples3(const v1::GetClearanceFieldRequest& r, const Grid3& grid,
                                 size_t sites, const ServerLimits& limits,
                                 ClearanceSamples3* out) {
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
    const Vec3 b = grid.Center(first[0] + count[0] - 1, first[1] + count[1] - 1,
                               first[2] + count[2] - 1);
    const Vec3 half = grid.voxel_size() * 0.5;
    box = {a.x - half.x, a.y - half.y, a.z - half.z, b.x + half.x, b.y + half.y, b.z + half.z};
  } else {
    for (auto [v, name] : {std::pair{sizes[0], "width_px"}, {sizes[1], "height_px"},
                           {sizes[2], "depth_px"}}) {
      if (v == 0 || v > limits.max_side_px) {
        return Invalid(absl::StrCat(name, " is ", v, "; it must be 1 to ", limits.max_side_px,
                                    " (--max-side-px), or all three 0"));
      }
    }
    for (int a = 0; a < 3; ++a) count[a] = sizes[a];
  }
  const uint64_t n = uint64_t{count[0]} * count[1] * count[2];
  if (n > limits.max_voxels_per_scene) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("the field has ", n, " samples; the limit is ",
                               limits.max_voxels_per_scene, " (--max-voxels-per-scene)"));
  }
  if (!own && n > limits.max_points_per_query) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("the field has ", n, " samples; the limit is ",
                               limits.max_points_per_query,
                               " (--max-points-per-query); the scene's own voxels are not limited so"));
  }
  // A float each, three with a gradient, an index and, at most once a site, its id.
  uint64_t bytes = n * (5 + (r.gradients() ? 15 : 0) + (r.site_indices() ? 5 : 0));
  if (r.site_indices()) bytes += std::min<uint64_t>(n, sites) * (limits.max_site_id_bytes + 3);
  if (bytes > uint64_t(limits.max_message_bytes)) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("the field's ", n, " samples take up to ", bytes,
                               " bytes, over a message's ", limits.max_message_bytes,
                               " (--max-message-bytes)"));
  }
  out->box = box;
  out->width = count[0];
  out->height = count[1];
  out->depth = count[2];
  out->own = own;
  out->cells = own ? grid : Grid3{box, count[0], count[1], count[2]};
  for (int a = 0; a < 3; ++a) out->first[a] = own ? first[a] : 0;
  return Status::OK;
}

grpc::Status ToWindow(const v1::Window& w, const std::string& field, Window* out) {
  const FieldPath window(field.c_str());
  for (auto [v, name] : {std::pair{w.min_x(), "min_x"}, {w.min_y(), "min_y"},
                         {w.max_x(), "max_x"}, {w.max_y(), "max_y"}}) {
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
  return grpc::Status::OK;
}

grpc::Status ToGridSize(uint32_t width, uint32_t height, const ServerLimits& limits, Grid* grid) {
  for (auto [v, name] : {std::pair{width, "width_px"}, {height, "height_px"}}) {
    if (v == 0 || v > limits.max_side_px) {
      return Invalid(absl::StrCat(name, " is ", v, "; it must be 1 to ", limits.max_side_px,
                                  " (--max-side-px)"));
    }
  }
  uint64_t pixels = uint64_t{width} * height;
  if (pixels > limits.max_scene_pixels) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("width_px x height_px is ", pixels, " pixels; the limit is ",
                               limits.max_scene_pixels, " (--max-side-px squared)"));
  }
  grid->width = width;
  grid->height = height;
  return grpc::Status::OK;
}

void ToProto(const Window& w, v1::Window* out) {
  out->set_min_x(w.min_x);
  out->set_min_y(w.min_y);
  out->set_max_x(w.max_x);
  out->set_max_y(w.max_y);
}

grpc::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid& grid,
                            ImageOptions* options) {
  switch (request.layer()) {
    case v1::RenderImageRequest::LAYER_UNSPECIFIED:
    case v1::RenderImageRequest::IDS: options->layer = ImageLayer::kIds; break;
    case v1::RenderImageRequest::FEATURES: options->layer = ImageLayer::kFeatures; break;
    case v1::RenderImageRequest::DISTANCE: options->layer = ImageLayer::kDistance; break;
    case v1::RenderImageRequest::SITE_INDEX: options->layer = ImageLayer::kSiteIndex; break;
    default:
      return Invalid(absl::StrCat("layer is ", request.layer(),
                                  "; it must be IDS, FEATURES, DISTANCE or SITE_INDEX"));
  }
  switch (request.format()) {
    case v1::RenderImageRequest::FORMAT_UNSPECIFIED:
    case v1::RenderImageRequest::PNG: options->format = ImageFormat::kPng; break;
    case v1::RenderImageRequest::EXR: options->format = ImageFormat::kExr; break;
    default:
      return Invalid(absl::StrCat("format is ", request.format(), "; it must be PNG or EXR"));
  }
  const bool exr = options->format == ImageFormat::kExr;
  if (exr && options->layer != ImageLayer::kDistance) {
    return Invalid("format EXR holds the DISTANCE layer only");
  }
  if (exr && request.draw_sites()) return Invalid("draw_sites needs format PNG");
  if (options->layer == ImageLayer::kSiteIndex &&
      (request.draw_sites() || request.polyline_size() > 0)) {
    return Invalid("layer SITE_INDEX takes neither draw_sites nor polyline: its pixels are numbers");
  }
  if (request.has_z() || request.has_slice()) {
    return Invalid("z and slice are for 3D scenes; this scene is 2D");
  }
  options->draw_sites = request.draw_sites();
  options->rect = grid.all();
  if (request.has_window()) {
    if (auto s = ToPixelRect(request.window(), grid, &options->rect); !s.ok()) return s;
  }
  for (int k = 0; k < request.polyline_size(); ++k) {
    Vec2 p;
    if (auto s = ToPoint(request.polyline(k), FieldPath("polyline")[k], &p); !s.ok()) return s;
    options->polyline.push_back(p);
  }
  if (!options->polyline.empty() && exr) return Invalid("polyline needs format PNG");
  return Status::OK;
}

grpc::Status ToImageOptions3(const v1::RenderImageRequest& request, const Grid3& grid,
                             ImageOptions* options) {
  if (request.draw_sites() || request.polyline_size() > 0) {
    return Invalid("draw_sites and polyline are for 2D scenes");
  }
  if (request.width_px() != 0 || request.height_px() != 0) {
    return Invalid("width_px and height_px are for 2D scenes: a 3D scene's image is a slice "
                   "of its voxels");
  }
  if (request.has_z() == request.has_slice()) {
    return Invalid("a 3D scene's image is of one slice: set z or slice (one of them)");
  }
  uint32_t k = 0;
  if (request.has_slice()) {
    if (request.slice() >= grid.depth) {
      return Invalid(absl::StrCat("slice is ", request.slice(), "; the scene has ", grid.depth,
                                  " (0 to ", grid.depth - 1, ")"));
    }
    k = request.slice();
  } else {
    const double z = request.z();
    if (!(z >= grid.box.min_z && z <= grid.box.max_z)) {
      return Invalid(absl::StrCat("z is ", FormatNumber(z), "; it must lie in the box's [",
                                  FormatNumber(grid.box.min_z), ", ", FormatNumber(grid.box.max_z),
                                  "]"));
    }
    k = static_cast<uint32_t>(std::min<double>(grid.depth - 1, std::floor(grid.ToVoxel({0, 0, z}).z)));
  }
  v1::RenderImageRequest plane = request;
  plane.clear_z();
  plane.clear_slice();
  Grid g;
  g.window = {grid.box.min_x, grid.box.min_y, grid.box.max_x, grid.box.max_y};
  g.width = grid.width;
  g.height = grid.height;
  if (auto s = ToImageOptions(plane, g, options); !s.ok()) return s;
  options->slice = k;
  return Status::OK;
}

grpc::Status ToPoint(const v1::Point& p, const FieldPath& field, Vec2* out) {
  if (!std::isfinite(p.x()) || !std::isfinite(p.y())) {
    return Invalid(absl::StrCat(field.str(), " is (", FormatNumber(p.x()), ", ", FormatNumber(p.y()),
                                "); coordinates must be finite"));
  }
  if (p.z() != 0) {
    return Invalid(absl::StrCat(field.Member("z").str(), " is ", FormatNumber(p.z()),
                                "; points of a 2D scene have no z"));
  }
  *out = {p.x(), p.y()};
  return Status::OK;
}

namespace {
Status ToPickLimit(const v1::PickRequest& request, double* max_distance) {
  const double limit = request.max_distance();
  if (!std::isfinite(limit) || limit < 0) {
    return Invalid(absl::StrCat("max_distance is ", FormatNumber(limit),
                                "; it must be finite and not negative (0: no limit)"));
  }
  *max_distance = limit == 0 ? INFINITY : limit;
  return Status::OK;
}
}  // namespace

grpc::Status ToPick(const v1::PickRequest& request, Vec2* point, double* max_distance) {
  if (!request.has_point()) return Invalid("point is not set");
  if (auto s = ToPoint(request.point(), "point", point); !s.ok()) return s;
  return ToPickLimit(request, max_distance);
}

grpc::Status ToPick3(const v1::PickRequest& request, Vec3* point, double* max_distance) {
  if (!request.has_point()) return Invalid("point is not set");
  if (auto s = ToPoint3(request.point(), "point", point); !s.ok()) return s;
  return ToPickLimit(request, max_distance);
}

grpc::Status ToBoundaryMethod(const v1::GetBoundariesRequest& request, BoundaryMethod* method) {
  switch (request.method()) {
    case v1::GetBoundariesRequest::METHOD_UNSPECIFIED:
    case v1::GetBoundariesRequest::FULL_SCAN: *method = BoundaryMethod::kFullScan; break;
    case v1::GetBoundariesRequest::CONTINUATION: *method = BoundaryMethod::kContinuation; break;
    default:
      return Invalid(absl::StrCat("method is ", request.method(),
                                  "; it must be FULL_SCAN or CONTINUATION"));
  }
  return Status::OK;
}

grpc::Status ToPathPreference(const v1::PlanPathRequest& request, PathPreference* prefer) {
  switch (request.prefer()) {
    case v1::PlanPathRequest::PREFER_UNSPECIFIED:
    case v1::PlanPathRequest::MAX_CLEARANCE: *prefer = PathPreference::kMaxClearance; break;
    case v1::PlanPathRequest::SHORTEST: *prefer = PathPreference::kShortest; break;
    default:
      return Invalid(absl::StrCat("prefer is ", request.prefer(),
                                  "; it must be MAX_CLEARANCE or SHORTEST"));
  }
  return Status::OK;
}

v1::FeatureKind ToProto(FeatureKind k) {
  switch (k) {
    case FeatureKind::kVertex: return v1::VERTEX;
    case FeatureKind::kEdge: return v1::EDGE;
    case FeatureKind::kCurve: return v1::CURVE;
    case FeatureKind::kFace: return v1::FACE;
  }
  return v1::FEATURE_KIND_UNSPECIFIED;
}

}  // namespace gvd
