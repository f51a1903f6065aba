#include "render/kernel/exact3.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "render/kernel/mesh_regions.h"

namespace gvd {

namespace {

// A power of two that brings the largest magnitude among the vectors near 1, so that the
// products of four coordinates below neither overflow nor underflow (the regions and the
// parameters they give do not change under scaling, and scaling by 2^k is exact).
template <class... V>
inline double Scale(const V&... vs) {
  Vec3 largest(0);
  ((largest = glm::max(largest, glm::abs(vs))), ...);
  const double m = std::max({largest.x, largest.y, largest.z});
  if (m == 0 || !std::isfinite(m) || (m < 0x1p200 && m > 0x1p-200)) return 1;
  return std::ldexp(1.0, -std::ilogb(m));
}

Hit3 Make(Vec3 q, Vec3 closest, FeatureKind kind, uint32_t index) {
  return {Distance(q, closest), closest, kind, index, UnitGradient(q, closest)};
}

}  // namespace

namespace {

// The nearest point of a segment or triangle and what it lies on, without the distance and
// gradient (which NearestOnSegment and NearestOnTriangle add, and a distance alone does not
// need).
struct Foot {
  Vec3 closest;
  FeatureKind kind;
  uint32_t index;
};

Foot SegmentFoot(Vec3 q, Vec3 a, Vec3 b) {
  const double s = Scale(b - a, q - a);
  const Vec3 ab = (b - a) * s, aq = (q - a) * s;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0 ? std::clamp(glm::dot(aq, ab) / len2, 0.0, 1.0) : 0.0;
  if (t == 0) return {a, FeatureKind::kVertex, 0};
  if (t == 1) return {b, FeatureKind::kVertex, 1};
  return {a + t * (b - a), FeatureKind::kEdge, 0};
}

// The nearest point of the non-degenerate triangle abc to q, after Ericson, Real-Time
// Collision Detection, 5.1.5: the Voronoi regions of the corners, then of the edges, then
// the face, each decided by dot products of the edge vectors ab and ac with ap, bp = ap - ab
// and cp = ap - ac: d1 = ab.ap, d2 = ac.ap, d3 = ab.bp, d4 = ac.bp, (d5, d6) = d56() =
// (ab.cp, ac.cp), asked for only when the regions of a, b and ab have not held q.
template <class D56>
Foot RegionFoot(Vec3 a, Vec3 b, Vec3 c, double d1, double d2, double d3, double d4, D56&& d56) {
  if (d1 <= 0 && d2 <= 0) return {a, FeatureKind::kVertex, 0};
  if (d3 >= 0 && d4 <= d3) return {b, FeatureKind::kVertex, 1};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * (b - a), FeatureKind::kEdge, 0};
  }
  const auto [d5, d6] = d56();
  if (d6 >= 0 && d5 <= d6) return {c, FeatureKind::kVertex, 2};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * (c - a), FeatureKind::kEdge, 2};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), FeatureKind::kEdge, 1};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {a + v * (b - a) + w * (c - a), FeatureKind::kFace, 0};
}

// The nearest point of the closed triangle abc to q: a degenerate one's as the union of its
// edges, any other's by Ericson's regions (RegionFoot) in coordinates scaled by Scale.
Foot TriangleFoot(Vec3 q, Vec3 a, Vec3 b, Vec3 c) {
  const double s = Scale(b - a, c - a, q - a);
  const Vec3 ab = (b - a) * s, ac = (c - a) * s, ap = (q - a) * s;
  // A degenerate triangle, or one so thin that the face's parameters lose their precision,
  // is the union of its edges.
  const Vec3 n = glm::cross(ab, ac);
  const double n2 = glm::dot(n, n);
  if (!(n2 > 0x1p-80 * glm::dot(ab, ab) * glm::dot(ac, ac))) {
    Foot best = SegmentFoot(q, a, b);
    double best_distance = Distance(q, best.closest);
    const std::pair<Vec3, Vec3> edges[2] = {{b, c}, {c, a}};
    for (uint32_t e = 0; e < 2; ++e) {
      Foot h = SegmentFoot(q, edges[e].first, edges[e].second);
      const double d = Distance(q, h.closest);
      if (d < best_distance) {
        // The edge's ends are the triangle's corners e + 1 and (e + 2) mod 3.
        h.index = h.kind == FeatureKind::kEdge ? e + 1 : (e + 1 + h.index) % 3;
        best = h;
        best_distance = d;
      }
    }
    return best;
  }
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  const Vec3 bp = ap - ab, cp = ap - ac;
  return RegionFoot(a, b, c, d1, d2, glm::dot(ab, bp), glm::dot(ac, bp),
                    [&] { return std::pair(glm::dot(ab, cp), glm::dot(ac, cp)); });
}

// TriangleFoot of a mesh's triangle t, from its prepared form where that is plain and q lies
// within 2^100 of it (so TriangleFoot's scale would be 1): the same regions, decided by the
// same dot products, two of them computed ahead (d3 = ab.(ap - ab) = d1 - ab.ab, ...).
Foot MeshFoot(Vec3 q, const MeshSite3& mesh, uint32_t t) {
  const PreparedTriangle& p = mesh.tree->prepared(t);
  const Vec3 ap = q - p.a;
  const Vec3 m = glm::abs(ap);
  const auto& tri = mesh.triangles[t];
  if (!p.plain || !(std::max({m.x, m.y, m.z}) < 0x1p100)) {
    return TriangleFoot(q, mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]]);
  }
  const double d1 = glm::dot(p.ab, ap), d2 = glm::dot(p.ac, ap);
  return RegionFoot(p.a, mesh.vertices[tri[1]], mesh.vertices[tri[2]], d1, d2, d1 - p.abab,
                    d2 - p.abac, [&] { return std::pair(d1 - p.abac, d2 - p.acac); });
}

}  // namespace

double TriangleDistance(Vec3 q, const MeshSite3& mesh, uint32_t t) {
  return Distance(q, MeshFoot(q, mesh, t).closest);
}

Hit3 NearestOnSegment(Vec3 q, Vec3 a, Vec3 b) {
  const Foot f = SegmentFoot(q, a, b);
  return Make(q, f.closest, f.kind, f.index);
}

Hit3 NearestOnTriangle(Vec3 q, Vec3 a, Vec3 b, Vec3 c) {
  const Foot f = TriangleFoot(q, a, b, c);
  return Make(q, f.closest, f.kind, f.index);
}

Hit3 NearestFeature(Vec3 q, const Geometry3& g, double within) {
  if (const auto* p = std::get_if<PointSite3>(&g)) return Make(q, p->p, FeatureKind::kVertex, 0);
  if (const auto* s = std::get_if<SegmentSite3>(&g)) return NearestOnSegment(q, s->a, s->b);
  if (const auto* t = std::get_if<TriangleSite3>(&g)) return NearestOnTriangle(q, t->a, t->b, t->c);
  // Each triangle's nearest point without its distance's gradient; the hit of the best.
  const auto& mesh = std::get<MeshSite3>(g);
  Foot best{Vec3(NAN), FeatureKind::kVertex, 0};
  double best_distance = INFINITY;
  uint32_t best_triangle = UINT32_MAX;
  double bound = within;
  mesh.tree->Nearest(q, &bound, [&](uint32_t i) {
    const Foot f = MeshFoot(q, mesh, i);
    const double d = Distance(q, f.closest);
    if (d > within || d > best_distance || (d == best_distance && i > best_triangle)) return d;
    best = f;
    best_distance = d;
    best_triangle = i;
    return d;
  });
  if (best_triangle == UINT32_MAX) return {INFINITY, Vec3(NAN), FeatureKind::kVertex, 0, Vec3(0)};
  // The triangle's own numbering, to the mesh's.
  const auto& tri = mesh.triangles[best_triangle];
  const uint32_t index = best.kind == FeatureKind::kFace   ? best_triangle
                         : best.kind == FeatureKind::kEdge ? mesh.triangle_edges[best_triangle][best.index]
                                                           : tri[best.index];
  return Make(q, best.closest, best.kind, index);
}

double ExactDistance(Vec3 q, const Geometry3& g, double within) {
  if (const auto* p = std::get_if<PointSite3>(&g)) return Distance(q, p->p);
  if (const auto* s = std::get_if<SegmentSite3>(&g)) {
    return Distance(q, SegmentFoot(q, s->a, s->b).closest);
  }
  if (const auto* t = std::get_if<TriangleSite3>(&g)) {
    return Distance(q, TriangleFoot(q, t->a, t->b, t->c).closest);
  }
  return MeshDistance(q, std::get<MeshSite3>(g), within);
}

double MeshDistance(Vec3 q, const MeshSite3& mesh, double within) {
  // The least over its triangles within `within`, as NearestFeature finds it, but without
  // each one's feature and gradient (the volume render asks this per voxel).
  double best = INFINITY, bound = within;
  mesh.tree->Nearest(q, &bound, [&](uint32_t t) {
    const double d = TriangleDistance(q, mesh, t);
    if (d <= within && d < best) best = d;
    return d;
  });
  return best;
}

double SiteValue(Vec3 q, const Site3& site) {
  const double d = ExactDistance(q, site.geometry);
  if (d > site.max_distance) return INFINITY;
  return site.multiplicative * d + site.additive;
}

namespace {

// Calls f(v) for every point of the geometry that is a vertex of it.
template <class F>
void ForEachVertex(const Geometry3& g, F&& f) {
  if (const auto* p = std::get_if<PointSite3>(&g)) {
    f(p->p);
  } else if (const auto* s = std::get_if<SegmentSite3>(&g)) {
    f(s->a);
    f(s->b);
  } else if (const auto* t = std::get_if<TriangleSite3>(&g)) {
    f(t->a);
    f(t->b);
    f(t->c);
  } else {
    const auto& mesh = std::get<MeshSite3>(g);
    for (const auto& e : mesh.edges) {  // every vertex of a triangle ends an edge
      f(mesh.vertices[e[0]]);
      f(mesh.vertices[e[1]]);
    }
  }
}

}  // namespace

Box3 BoundingBox(const Geometry3& g) {
  if (const auto* mesh = std::get_if<MeshSite3>(&g); mesh != nullptr && mesh->tree != nullptr) {
    // The tree's root box, made from the same vertices: O(1) rather than O(edges), for the
    // callers that ask per brick and per change.
    const Vec3 lo = mesh->tree->lo(), hi = mesh->tree->hi();
    return Box3{lo.x, lo.y, lo.z, hi.x, hi.y, hi.z};
  }
  Box3 box{INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
  ForEachVertex(g, [&](Vec3 v) {
    box.min_x = std::min(box.min_x, v.x);
    box.min_y = std::min(box.min_y, v.y);
    box.min_z = std::min(box.min_z, v.z);
    box.max_x = std::max(box.max_x, v.x);
    box.max_y = std::max(box.max_y, v.y);
    box.max_z = std::max(box.max_z, v.z);
  });
  return box;
}

double FarthestDistance(const Box3& box, const Geometry3& g) {
  double best = INFINITY;
  ForEachVertex(g, [&](Vec3 v) {
    // The farthest corner from v, axis by axis.
    const Vec3 far(std::max(std::abs(v.x - box.min_x), std::abs(v.x - box.max_x)),
                   std::max(std::abs(v.y - box.min_y), std::abs(v.y - box.max_y)),
                   std::max(std::abs(v.z - box.min_z), std::abs(v.z - box.max_z)));
    best = std::min(best, Length(far));
  });
  return best;
}

absl::StatusOr<MeshSite3> MakeMesh(const std::vector<double>& xyz,
                                   const std::vector<uint32_t>& triangles, size_t max_triangles) {
  if (xyz.size() % 3 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("xyz has ", xyz.size(), " values; it must hold three a vertex"));
  }
  if (triangles.empty() || triangles.size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "triangles has ", triangles.size(), " indices; it must hold three a triangle, at least one"));
  }
  if (triangles.size() / 3 > max_triangles) {
    return absl::InvalidArgumentError(absl::StrCat("triangles holds ", triangles.size() / 3,
                                                   " triangles, over the limit of ",
                                                   max_triangles));
  }
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (!std::isfinite(xyz[i])) {
      return absl::InvalidArgumentError(absl::StrCat("xyz[", i, "] is ", xyz[i]));
    }
  }
  const size_t n = xyz.size() / 3;
  MeshSite3 mesh;
  mesh.vertices.reserve(n);
  for (size_t i = 0; i < n; ++i) mesh.vertices.emplace_back(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> edge_of;
  mesh.triangles.reserve(triangles.size() / 3);
  mesh.triangle_edges.reserve(triangles.size() / 3);
  for (size_t t = 0; t < triangles.size(); t += 3) {
    std::array<uint32_t, 3> tri{triangles[t], triangles[t + 1], triangles[t + 2]};
    for (size_t k = 0; k < 3; ++k) {
      if (tri[k] >= n) {
        return absl::InvalidArgumentError(absl::StrCat("triangles[", t + k, "] is ", tri[k],
                                                       ", past the ", n, " vertices"));
      }
    }
    std::array<uint32_t, 3> named{};
    for (size_t k = 0; k < 3; ++k) {
      const auto key = std::minmax(tri[k], tri[(k + 1) % 3]);
      auto [it, added] = edge_of.emplace(std::make_pair(key.first, key.second),
                                         static_cast<uint32_t>(mesh.edges.size()));
      if (added) mesh.edges.push_back({key.first, key.second});
      named[k] = it->second;
    }
    mesh.triangles.push_back(tri);
    mesh.triangle_edges.push_back(named);
  }
  mesh.tree = std::make_shared<const TriangleTree>(mesh.vertices, mesh.triangles);
  mesh.regions = std::make_shared<const MeshRegions>(mesh);
  return mesh;
}

}  // namespace gvd
