#include "render/plan/distance_mesh.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

namespace gvd {

uint32_t ConeSegments(double radius, double eps) {
  assert(radius > 0 && eps > 0);
  if (eps >= radius) return 3;
  double alpha = 2 * std::acos((radius - eps) / radius);
  double n = std::ceil(2 * std::numbers::pi / alpha);
  if (!(n < kMaxConeSegments)) return kMaxConeSegments;  // also catches alpha == 0
  return std::max<uint32_t>(3, static_cast<uint32_t>(n));
}

ConeMesh BuildUnitCone(uint32_t segments) {
  assert(segments >= 3 && segments <= kMaxConeSegments);
  ConeMesh mesh;
  mesh.segments = segments;
  mesh.overestimate = 1 / std::cos(std::numbers::pi / segments);
  mesh.vertices.reserve(size_t{segments} * 9);
  auto ring = [&](uint32_t k) {
    double t = 2 * std::numbers::pi * (k % segments) / segments;
    mesh.vertices.insert(mesh.vertices.end(),
                         {static_cast<float>(std::cos(t)), static_cast<float>(std::sin(t)), 1.f});
  };
  for (uint32_t k = 0; k < segments; ++k) {
    mesh.vertices.insert(mesh.vertices.end(), {0.f, 0.f, 0.f});
    ring(k);
    ring(k + 1);
  }
  return mesh;
}

ConeMesh ConeForReach(double reach, double eps) {
  return BuildUnitCone(ConeSegments(reach + eps, eps));
}

FanRange FanTriangles(double from, double to, uint32_t n) {
  constexpr double kTurn = 2 * std::numbers::pi;
  if (!(to - from < kTurn)) return {0, n};
  const double k0 = std::floor(from / kTurn * n) - 1, k1 = std::ceil(to / kTurn * n) + 1;
  if (!(k1 - k0 < n)) return {0, n};
  const int64_t first = static_cast<int64_t>(k0) % int64_t{n};
  return {static_cast<uint32_t>(first < 0 ? first + n : first), static_cast<uint32_t>(k1 - k0)};
}

}  // namespace gvd
