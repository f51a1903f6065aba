// Small helpers shared by the integration tests.
#pragma once

#include <cmath>
#include <optional>
#include <random>
#include <string>

#include "gvd/v1/voronoi.pb.h"
#include "render/kernel/exact2.h"
#include "render/kernel/site2.h"
#include "tests/support/oracle.h"

namespace gvd::testing {

// The plane's feature kinds as the API names them; nullopt for any other value.
inline std::optional<FeatureKind> KindOf(v1::FeatureKind kind) {
  switch (kind) {
    case v1::FEATURE_KIND_VERTEX: return FeatureKind::kVertex;
    case v1::FEATURE_KIND_EDGE: return FeatureKind::kEdge;
    case v1::FEATURE_KIND_CURVE: return FeatureKind::kCurve;
    default: return std::nullopt;
  }
}

// Whether an answer's feature (as the API numbers it) is a part of the geometry nearest to
// q, by the tests' oracle.
inline bool IsNearestFeature(Vec2 q, const Geometry& g, v1::FeatureKind kind, uint32_t index) {
  const auto k = KindOf(kind);
  return k && oracle::IsNearestFeature(q, g, *k, index);
}

// Whether an answer's closest point lies on its feature and is a nearest point of the
// geometry to q, and its gradient is the unit vector from that point to q (zero on the
// site), by the tests' oracle.
inline bool IsClosestPoint(Vec2 q, const Geometry& g, v1::FeatureKind kind, uint32_t index,
                           const v1::Point& closest, const v1::Point& gradient) {
  const auto k = KindOf(kind);
  const Vec2 c{closest.x(), closest.y()};
  if (!k || !oracle::IsClosestPoint(q, g, *k, index, c)) return false;
  const long double dx = (long double)q.x - c.x, dy = (long double)q.y - c.y;
  const long double d = std::hypot(dx, dy);
  const long double gx = d > 0 ? dx / d : 0, gy = d > 0 ? dy / d : 0;
  return std::abs(gx - gradient.x()) <= 1e-12 && std::abs(gy - gradient.y()) <= 1e-12;
}

inline void SetPoint(Vec2 p, v1::Point* out) {
  out->set_x(p.x);
  out->set_y(p.y);
}

// The API's form of a render-layer site (Bezier: its control points and tolerance; path: its
// subpaths as MakePath left them and its tolerance).
inline v1::Site ToProtoSite(const Site& s) {
  v1::Site out;
  out.set_id(s.id);
  if (const auto* p = std::get_if<PointSite>(&s.geometry)) {
    SetPoint(p->p, out.mutable_point());
  } else if (const auto* seg = std::get_if<SegmentSite>(&s.geometry)) {
    SetPoint(seg->a, out.mutable_segment()->mutable_a());
    SetPoint(seg->b, out.mutable_segment()->mutable_b());
  } else if (const auto* l = std::get_if<PolylineSite>(&s.geometry)) {
    for (Vec2 q : l->points) SetPoint(q, out.mutable_polyline()->add_points());
  } else if (const auto* poly = std::get_if<PolygonSite>(&s.geometry)) {
    for (Vec2 q : poly->vertices) SetPoint(q, out.mutable_polygon()->add_vertices());
    out.mutable_polygon()->set_side(poly->side == Side::kOutside  ? v1::Polygon::SIDE_OUTSIDE
                                    : poly->side == Side::kInside ? v1::Polygon::SIDE_INSIDE
                                                                  : v1::Polygon::SIDE_UNSPECIFIED);
  } else if (const auto* b = std::get_if<BezierSite>(&s.geometry)) {
    for (Vec2 q : b->control) SetPoint(q, out.mutable_bezier()->add_control_points());
    out.mutable_bezier()->set_tolerance(b->tolerance);
  } else if (const auto* path = std::get_if<PathSite>(&s.geometry)) {
    v1::Path* to = out.mutable_path();
    for (const Subpath& from : path->subpaths) {
      v1::Path::Subpath* sub = to->add_subpaths();
      for (Vec2 q : from.points) SetPoint(q, sub->add_points());
      for (uint8_t d : from.degrees) sub->add_degrees(d);
      sub->set_closed(from.closed);
    }
    to->set_fill_rule(path->fill == FillRule::kEvenOdd ? v1::Path::FILL_RULE_EVEN_ODD
                                                       : v1::Path::FILL_RULE_NONZERO);
    to->set_side(path->side == Side::kOutside  ? v1::Polygon::SIDE_OUTSIDE
                 : path->side == Side::kInside ? v1::Polygon::SIDE_INSIDE
                                               : v1::Polygon::SIDE_UNSPECIFIED);
    to->set_tolerance(path->tolerance);
    to->set_approximation_error(path->approximation);
  }
  out.set_additive_weight(s.additive);
  out.set_multiplicative_weight(s.multiplicative);
  if (std::isfinite(s.max_distance)) out.set_max_distance(s.max_distance);
  return out;
}

// A CreateSceneRequest for the unit square at width x height pixels.
inline v1::CreateSceneRequest UnitScene(const std::string& id, uint32_t width, uint32_t height) {
  v1::CreateSceneRequest r;
  r.set_scene_id(id);
  r.mutable_window()->set_max_x(1);
  r.mutable_window()->set_max_y(1);
  r.set_width_px(width);
  r.set_height_px(height);
  return r;
}

// An UpsertSitesRequest of n points uniform in the unit square (x then y from one seeded
// generator), named prefix + their index.
inline v1::UpsertSitesRequest RandomPoints(const std::string& scene, int n, uint64_t seed,
                                           const std::string& prefix = "") {
  v1::UpsertSitesRequest r;
  r.set_scene_id(scene);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < n; ++i) {
    v1::Site* site = r.add_sites();
    site->set_id(prefix + std::to_string(i));
    site->mutable_point()->set_x(unit(rng));
    site->mutable_point()->set_y(unit(rng));
  }
  return r;
}

// The id of packed answer i's site: site_ids[site - 1], or "" where site is 0 (none).
inline std::string Named(const v1::PackedNearest& p, int i) {
  const uint32_t site = p.site(i);
  return site == 0 ? std::string() : p.site_ids(static_cast<int>(site) - 1);
}

// A stream's request of a FindNearestRequest's points and options (their fields share
// numbers), its answers in chunks of `chunk_size` points.
inline v1::FindNearestStreamRequest StreamOf(const v1::FindNearestRequest& r,
                                             uint32_t chunk_size = 0) {
  v1::FindNearestStreamRequest out;
  out.ParseFromString(r.SerializeAsString());
  out.set_chunk_size(chunk_size);
  return out;
}

}  // namespace gvd::testing
