// The tests' own oracle for the 3D kernel (render/kernel/exact3.h), written apart from it: in
// long double, with the plainest formulas. A triangle's distance is its plane's when the
// point's projection falls inside it (three signed volumes), else its nearest edge's; the
// code it judges decides Voronoi regions from dot products instead.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "render/kernel/site3.h"

namespace gvd::oracle3 {

using Real = long double;

struct P {
  Real x, y, z;
};
inline P Of(Vec3 v) { return {v.x, v.y, v.z}; }
inline P Sub(P a, P b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Real Dot(P a, P b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline P Cross(P a, P b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Real Norm(P a) { return std::sqrt(Dot(a, a)); }

// Distance from q to the closed segment ab.
inline Real ToSegment(Vec3 q, Vec3 a, Vec3 b) {
  const P ab = Sub(Of(b), Of(a)), aq = Sub(Of(q), Of(a));
  const Real len2 = Dot(ab, ab);
  const Real t = len2 > 0 ? std::clamp(Dot(aq, ab) / len2, Real(0), Real(1)) : Real(0);
  return Norm(Sub(aq, P{t * ab.x, t * ab.y, t * ab.z}));
}

// Distance from q to the closed triangle abc.
inline Real ToTriangle(Vec3 q, Vec3 a, Vec3 b, Vec3 c) {
  const Real edges = std::min({ToSegment(q, a, b), ToSegment(q, b, c), ToSegment(q, c, a)});
  const P n = Cross(Sub(Of(b), Of(a)), Sub(Of(c), Of(a)));
  const Real n2 = Dot(n, n);
  if (n2 == 0) return edges;
  const P aq = Sub(Of(q), Of(a));
  const Real h = Dot(aq, n) / n2;
  const P p{q.x - h * n.x, q.y - h * n.y, q.z - h * n.z};  // q's projection on the plane
  auto side = [&](Vec3 u, Vec3 v) { return Dot(Cross(Sub(Of(v), Of(u)), Sub(p, Of(u))), n); };
  if (side(a, b) >= 0 && side(b, c) >= 0 && side(c, a) >= 0) {
    return std::min(edges, std::abs(Dot(aq, n)) / std::sqrt(n2));
  }
  return edges;
}

// Distance from q to the geometry.
inline Real ToGeometry(Vec3 q, const Geometry3& g) {
  if (const auto* p = std::get_if<PointSite3>(&g)) return Norm(Sub(Of(q), Of(p->p)));
  if (const auto* s = std::get_if<SegmentSite3>(&g)) return ToSegment(q, s->a, s->b);
  if (const auto* t = std::get_if<TriangleSite3>(&g)) return ToTriangle(q, t->a, t->b, t->c);
  const auto& mesh = std::get<MeshSite3>(g);
  Real best = INFINITY;
  for (const auto& t : mesh.triangles) {
    best = std::min(best, ToTriangle(q, mesh.vertices[t[0]], mesh.vertices[t[1]],
                                     mesh.vertices[t[2]]));
  }
  return best;
}

}  // namespace gvd::oracle3
