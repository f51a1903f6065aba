#include "server/app/convert/sites.h"

#include <cmath>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/kernel/exact3.h"
#include "render/kernel/path2.h"
#include "server/log.h"

namespace gvd {
namespace {

// The weights and reach of a site of either dimension, checked, into `site`.
template <class S>
absl::Status ToWeights(const v1::Site& s, const FieldPath& field, S* site) {
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
  return absl::OkStatus();
}

// A polygon's or a path's side, named `at` in a refusal, into `side`; and back.
absl::Status ToSide(v1::Polygon::Side in, const std::string& at, Side* side) {
  switch (in) {
    case v1::Polygon::SIDE_UNSPECIFIED:
      *side = Side::kBoth;
      return absl::OkStatus();
    case v1::Polygon::SIDE_OUTSIDE:
      *side = Side::kOutside;
      return absl::OkStatus();
    case v1::Polygon::SIDE_INSIDE:
      *side = Side::kInside;
      return absl::OkStatus();
    default:
      return Invalid(absl::StrCat(at, " is ", in,
                                  "; it must be SIDE_UNSPECIFIED, SIDE_OUTSIDE or SIDE_INSIDE"));
  }
}

v1::Polygon::Side ToProto(Side side) {
  return side == Side::kOutside  ? v1::Polygon::SIDE_OUTSIDE
         : side == Side::kInside ? v1::Polygon::SIDE_INSIDE
                                 : v1::Polygon::SIDE_UNSPECIFIED;
}

}  // namespace

absl::Status ToSite(const v1::Site& s, const FieldPath& field, const ServerLimits& limits,
                    Site* site) {
  site->id = s.id();
  auto points = [&](const auto& list, const FieldPath& name, size_t min,
                    std::vector<Vec2>* out) -> absl::Status {
    if (size_t(list.size()) < min) {
      return Invalid(absl::StrCat(name.str(), " has ", list.size(), " points; it needs at least ",
                                  min, " (site ", Quoted(s.id()), ")"));
    }
    if (size_t(list.size()) > limits.max_vertices_per_site) {
      return absl::ResourceExhaustedError(
          absl::StrCat(name.str(), " has ", list.size(), " points; the limit is ",
                       limits.max_vertices_per_site, " (--max-vertices-per-site)"));
    }
    out->clear();
    out->reserve(list.size());
    for (int k = 0; k < list.size(); ++k) {
      Vec2 p;
      if (auto st = ToPoint(list[k], name[k], &p); !st.ok()) return st;
      out->push_back(p);
    }
    return absl::OkStatus();
  };
  switch (s.geometry_case()) {
    case v1::Site::kPoint: {
      PointSite g;
      if (auto st = ToPoint(s.point(), field.Member("point"), &g.p); !st.ok()) return st;
      site->geometry = g;
      break;
    }
    case v1::Site::kSegment: {
      const FieldPath segment = field.Member("segment");
      SegmentSite g;
      if (auto st = ToPoint(s.segment().a(), segment.Member("a"), &g.a); !st.ok()) return st;
      if (auto st = ToPoint(s.segment().b(), segment.Member("b"), &g.b); !st.ok()) return st;
      site->geometry = g;
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
      if (auto st = ToSide(s.polygon().side(), polygon.Member("side").str(), &poly.side); !st.ok()) {
        return st;
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
    case v1::Site::kPath: {
      const v1::Path& in = s.path();
      const FieldPath path = field.Member("path");
      if (in.subpaths().empty()) {
        return Invalid(absl::StrCat(path.str(), " has no subpath (site ", Quoted(s.id()), ")"));
      }
      std::vector<Subpath> subpaths(in.subpaths().size());
      size_t total = 0;
      const FieldPath list = path.Member("subpaths");  // outlives the paths below it
      for (int i = 0; i < in.subpaths().size(); ++i) {
        const v1::Path::Subpath& from = in.subpaths(i);
        const FieldPath at = list[i];
        Subpath& to = subpaths[i];
        if (auto st = points(from.points(), at.Member("points"), 2, &to.points); !st.ok()) return st;
        total += to.points.size();
        if (total > limits.max_vertices_per_site) {
          return absl::ResourceExhaustedError(absl::StrCat(
              path.str(), " has more than ", limits.max_vertices_per_site,
              " points in its subpaths; that is the limit (--max-vertices-per-site)"));
        }
        size_t taken = 1;
        for (int k = 0; k < from.degrees().size(); ++k) {
          const uint32_t d = from.degrees(k);
          if (d < 1 || d > 3) {
            return Invalid(absl::StrCat(at.Member("degrees")[k].str(), " is ", d,
                                        "; a piece is of degree 1 (a line), 2 or 3 (a Bezier) (site ",
                                        Quoted(s.id()), ")"));
          }
          to.degrees.push_back(static_cast<uint8_t>(d));
          taken += d;
        }
        if (from.degrees().empty()) {
          to.degrees.assign(to.points.size() - 1, 1);
          taken = to.points.size();
        }
        if (taken != to.points.size()) {
          return Invalid(absl::StrCat(at.Member("points").str(), " has ", to.points.size(),
                                      " points; its start and the pieces of its degrees take ",
                                      taken, " (site ", Quoted(s.id()), ")"));
        }
        to.closed = from.closed();
      }
      FillRule fill = FillRule::kNonZero;
      switch (in.fill_rule()) {
        case v1::Path::FILL_RULE_UNSPECIFIED:
        case v1::Path::FILL_RULE_NONZERO:
          break;
        case v1::Path::FILL_RULE_EVEN_ODD:
          fill = FillRule::kEvenOdd;
          break;
        default:
          return Invalid(absl::StrCat(path.str(), ".fill_rule is ", in.fill_rule(),
                                      "; it must be FILL_RULE_UNSPECIFIED, FILL_RULE_NONZERO or "
                                      "FILL_RULE_EVEN_ODD"));
      }
      Side side = Side::kBoth;
      if (auto st = ToSide(in.side(), path.Member("side").str(), &side); !st.ok()) return st;
      const double tol = in.tolerance();
      if (!std::isfinite(tol) || tol < 0) {
        return Invalid(absl::StrCat(path.str(), ".tolerance is ", FormatNumber(tol),
                                    "; it must be finite and not negative (0 means a "
                                    "thousandth of the control polygons' length)"));
      }
      const double approximation = in.approximation_error();
      if (!std::isfinite(approximation) || approximation < 0) {
        return Invalid(absl::StrCat(path.str(), ".approximation_error is ", FormatNumber(approximation),
                                    "; it must be finite and not negative"));
      }
      if (const std::string why = PathContractError(subpaths, side); !why.empty()) {
        return Invalid(absl::StrCat(path.str(), ": ", why, " (site ", Quoted(s.id()), ")"));
      }
      PathSite made = MakePath(std::move(subpaths), fill, side, tol, 4 * limits.max_vertices_per_site);
      made.approximation = approximation;
      site->geometry = std::move(made);
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
                                FormatNumber(box.height()), ", which overflows a double (site ",
                                Quoted(s.id()), ")"));
  }
  return ToWeights(s, field, site);
}

absl::Status ToSite(const v1::Site& s, const FieldPath& field, const ServerLimits& limits,
                    Site3* site) {
  site->id = s.id();
  switch (s.geometry_case()) {
    case v1::Site::kPoint: {
      Vec3 p;
      if (auto st = ToPoint(s.point(), field.Member("point"), &p); !st.ok()) return st;
      site->geometry = PointSite3{p};
      break;
    }
    case v1::Site::kSegment: {
      const FieldPath segment = field.Member("segment");
      SegmentSite3 g;
      if (auto st = ToPoint(s.segment().a(), segment.Member("a"), &g.a); !st.ok()) return st;
      if (auto st = ToPoint(s.segment().b(), segment.Member("b"), &g.b); !st.ok()) return st;
      site->geometry = g;
      break;
    }
    case v1::Site::kTriangle: {
      const FieldPath triangle = field.Member("triangle");
      TriangleSite3 g;
      if (auto st = ToPoint(s.triangle().a(), triangle.Member("a"), &g.a); !st.ok()) return st;
      if (auto st = ToPoint(s.triangle().b(), triangle.Member("b"), &g.b); !st.ok()) return st;
      if (auto st = ToPoint(s.triangle().c(), triangle.Member("c"), &g.c); !st.ok()) return st;
      site->geometry = g;
      break;
    }
    case v1::Site::kMesh: {
      const v1::Mesh& m = s.mesh();
      if (size_t(m.triangles_size()) / 3 > limits.max_triangles_per_mesh) {
        return absl::ResourceExhaustedError(
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
    case v1::Site::kPath:
      return Invalid(
          absl::StrCat(field.str(), " is a ",
                       s.has_polyline()  ? "polyline"
                       : s.has_polygon() ? "polygon"
                       : s.has_bezier()  ? "bezier"
                                         : "path",
                       "; a 3D scene takes point, segment, triangle and mesh sites (site ",
                       Quoted(s.id()), ")"));
    case v1::Site::GEOMETRY_NOT_SET:
      return Invalid(absl::StrCat(field.str(), ".geometry is not set (site ", Quoted(s.id()), ")"));
  }
  const Box3 box = BoundingBox(site->geometry);
  if (!std::isfinite(box.max_x - box.min_x) || !std::isfinite(box.max_y - box.min_y) ||
      !std::isfinite(box.max_z - box.min_z)) {
    return Invalid(
        absl::StrCat(field.str(), " spans more than a double holds (site ", Quoted(s.id()), ")"));
  }
  return ToWeights(s, field, site);
}

template <class SiteT>
absl::Status ToSites(const v1::UpsertSitesRequest& r, const ServerLimits& limits,
                     std::vector<SiteT>* sites) {
  if (r.sites_size() == 0) return Invalid("sites is empty");
  if (size_t(r.sites_size()) > limits.max_sites_per_request) {
    return absl::ResourceExhaustedError(
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
    SiteT site;
    if (auto st = ToSite(s, field, limits, &site); !st.ok()) return st;
    sites->push_back(std::move(site));
  }
  return absl::OkStatus();
}
template absl::Status ToSites(const v1::UpsertSitesRequest&, const ServerLimits&,
                              std::vector<Site>*);
template absl::Status ToSites(const v1::UpsertSitesRequest&, const ServerLimits&,
                              std::vector<Site3>*);

absl::Status ToDurability(v1::Durability durability, Durability* out) {
  switch (durability) {
    case v1::DURABILITY_UNSPECIFIED:
    case v1::DURABILITY_SYNC:
      *out = Durability::kSync;
      return absl::OkStatus();
    case v1::DURABILITY_RELAXED:
      *out = Durability::kRelaxed;
      return absl::OkStatus();
    default:
      return Invalid(absl::StrCat("durability is ", durability, "; it must be DURABILITY_SYNC or DURABILITY_RELAXED"));
  }
}

absl::Status ToSiteIds(const v1::DeleteSitesRequest& r, const ServerLimits& limits,
                       std::vector<std::string>* ids) {
  if (r.ids_size() == 0) return Invalid("ids is empty");
  if (size_t(r.ids_size()) > limits.max_sites_per_request) {
    return absl::ResourceExhaustedError(
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
  return absl::OkStatus();
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
    out->mutable_polygon()->set_side(ToProto(poly->side));
  } else if (const auto* b = std::get_if<BezierSite>(&site.geometry)) {
    for (Vec2 q : b->control) ToProto(q, out->mutable_bezier()->add_control_points());
    out->mutable_bezier()->set_tolerance(b->tolerance);
  } else if (const auto* path = std::get_if<PathSite>(&site.geometry)) {
    v1::Path* to = out->mutable_path();
    for (const Subpath& from : path->subpaths) {
      v1::Path::Subpath* sub = to->add_subpaths();
      for (Vec2 q : from.points) ToProto(q, sub->add_points());
      for (uint8_t d : from.degrees) sub->add_degrees(d);
      sub->set_closed(from.closed);
    }
    to->set_fill_rule(path->fill == FillRule::kEvenOdd ? v1::Path::FILL_RULE_EVEN_ODD
                                                       : v1::Path::FILL_RULE_NONZERO);
    to->set_side(ToProto(path->side));
    to->set_tolerance(path->tolerance);
    to->set_approximation_error(path->approximation);
  }
  if (site.additive != 0) out->set_additive_weight(site.additive);
  if (site.multiplicative != 1) out->set_multiplicative_weight(site.multiplicative);
  if (std::isfinite(site.max_distance)) out->set_max_distance(site.max_distance);
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

}  // namespace gvd
