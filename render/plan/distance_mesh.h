// Bounded-error distance meshes (paper sec. 4): the triangle fans that the rasterizer draws
// so that interpolated depth approximates each site's distance function.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <variant>
#include <vector>

#include "render/kernel/exact2.h"
#include "render/kernel/site2.h"

namespace gvd {

// Fan triangles needed for a point's distance cone of radius `radius` to stay within `eps`
// of the true distance (paper sec. 4.1.1): the spokes lie on the cone, the base polygon's
// edges come within eps of the base circle, alpha = 2 acos((R - eps) / R), n = ceil(2 pi / alpha).
// At least 3; eps >= radius gives 3.
// CONTRACT: radius > 0 and eps > 0, both finite.
uint32_t ConeSegments(double radius, double eps);

// The most triangles a cone may have; beyond it the error bound grows instead (it is always
// reported honestly through `overestimate`).
inline constexpr uint32_t kMaxConeSegments = 16384;

// A unit distance cone for instanced drawing: `segments` triangles around the apex (0, 0, 0)
// whose ring vertices (cos t, sin t, 1) lie on the cone z = r. Scaled by rho in all three
// axes it covers every point within rho * cos(pi / n) of the apex, and there its height h
// satisfies d <= h <= d * overestimate for the true distance d, overestimate = 1 / cos(pi / n).
struct ConeMesh {
  uint32_t segments = 0;
  double overestimate = 1;
  std::vector<float> vertices;  // x, y, z per vertex; three vertices per triangle
};

// The unit cone with `segments` triangles. CONTRACT: 3 <= segments <= kMaxConeSegments.
ConeMesh BuildUnitCone(uint32_t segments);

// The cone that meshes, within eps, every distance up to `reach`: with
// n = ConeSegments(reach + eps, eps), reach * (overestimate - 1) <= eps, so scaling the unit
// cone by reach * overestimate covers radius `reach` with error at most eps. Capped at
// kMaxConeSegments.
ConeMesh ConeForReach(double reach, double eps);

// The triangles of a fan of `n` that cover the directions from `from` to `to` (radians,
// from <= to): `count` of them from triangle `first` on (mod n: in a buffer of two turns
// they are contiguous), with one more on each side so that rounding cannot leave a pixel
// centre on a boundary ray uncovered.
struct FanRange {
  uint32_t first = 0, count = 0;
};
FanRange FanTriangles(double from, double to, uint32_t n);

// The pieces of a site's distance mesh in kMesh (paper sec. 4), in this order: g(a, b) and
// g(b, a) for each edge ab of positive length, which gets a tent (its slab), each call for
// the half on the left of the direction given (so that the halves of a tent, one on each
// side, can be drawn apart), then f(p, from, to) for each
// vertex, which gets a fan over the directions (radians, from <= to <= from + 2 pi) in which
// it is the site's nearest point: all of them for a point (or a chain of one point), the
// half-plane beyond the end of an open chain, the wedge between the normals of the two edges
// at a joint (empty on the inner side of the turn), chain after chain (ForEachChain,
// exact2.h). A point q whose nearest point on the site is inside an edge lies in that edge's
// slab; one whose nearest point is a vertex v lies beyond the end of the edge
// arriving at v and before the start of the edge leaving it: in v's wedge.
template <class F, class G>
void ForEachPiece(const Geometry& geometry, F&& f, G&& g) {
  constexpr double kPi = std::numbers::pi;
  if (const auto* p = std::get_if<PointSite>(&geometry)) {
    f(p->p, 0.0, 2 * kPi);
    return;
  }
  // The edges of positive length, chain after chain (ForEachChain): each chain's range of
  // them, its first point and whether it is closed. A chain without any is a point.
  struct ChainEdges {
    size_t begin, end;
    Vec2 start;
    bool closed;
  };
  thread_local std::vector<std::pair<Vec2, Vec2>> segments, edges;
  thread_local std::vector<ChainEdges> chains;
  segments.clear();
  edges.clear();
  chains.clear();
  ForEachSegment(geometry, [&](Vec2 a, Vec2 b) { segments.emplace_back(a, b); });
  ForEachChain(geometry, [&](uint32_t begin, uint32_t end, bool closed) {
    const size_t first = edges.size();
    for (uint32_t i = begin; i < end; ++i) {
      const auto [a, b] = segments[i];
      if (a.x != b.x || a.y != b.y) edges.emplace_back(a, b);
    }
    chains.push_back({first, edges.size(), segments[begin].first, closed});
  });
  auto angle = [](Vec2 from, Vec2 to) { return std::atan2(to.y - from.y, to.x - from.x); };
  for (const auto& [a, b] : edges) {
    g(a, b);
    g(b, a);
  }
  for (const ChainEdges& chain : chains) {
    const size_t n = chain.end - chain.begin;
    if (n == 0) {  // every vertex at one point
      f(chain.start, 0.0, 2 * kPi);
      continue;
    }
    auto edge = [&](size_t i) { return edges[chain.begin + i]; };
    if (!chain.closed) {
      const double first = angle(edge(0).second, edge(0).first);
      const double last = angle(edge(n - 1).first, edge(n - 1).second);
      f(edge(0).first, first - kPi / 2, first + kPi / 2);
      f(edge(n - 1).second, last - kPi / 2, last + kPi / 2);
    }
    const size_t joints = chain.closed ? n : n - 1;
    for (size_t i = 0; i < joints; ++i) {
      const auto [a, v] = edge(i);
      const Vec2 b = edge((i + 1) % n).second;
      // Beyond the arriving edge: within pi/2 of its direction c1; before the leaving edge:
      // within pi/2 of its reverse c2. Both half-planes meet in the wedge around the middle.
      const double c1 = angle(a, v), c2 = angle(b, v);
      const double delta = std::remainder(c2 - c1, 2 * kPi);
      const double half = kPi / 2 - std::abs(delta) / 2;
      f(v, c1 + delta / 2 - half, c1 + delta / 2 + half);
    }
  }
}

}  // namespace gvd
