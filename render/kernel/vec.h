// Vectors shared by every dimension of the kernel: GLM's double-precision vectors, the types
// the GL code shares with its shaders (vec2/vec3 uniforms there), and what GLM lacks: a length
// that neither overflows nor underflows. GLM_FORCE_CTOR_INIT (set for every target by
// gvd_kernel) makes a default-constructed vector zero, as the code relies on.
#pragma once

#ifndef GLM_FORCE_CTOR_INIT
#error "gvd's kernel needs GLM_FORCE_CTOR_INIT: link gvd_kernel, which defines it"
#endif

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace gvd {

using Vec2 = glm::dvec2;
using Vec3 = glm::dvec3;

// Euclidean length, without undue overflow or underflow: sqrt(x^2 + y^2) where the squares
// can neither overflow nor lose precision to underflow (within an ulp or so of hypot), hypot
// elsewhere. glm::length squares blindly: 1e200 would come back infinite.
inline double Length(Vec2 a) {
  double m = std::max(std::abs(a.x), std::abs(a.y));
  if (m < 0x1p500 && m > 0x1p-500) return std::sqrt(a.x * a.x + a.y * a.y);
  return std::hypot(a.x, a.y);
}
inline double Length(Vec3 a) {
  double m = std::max({std::abs(a.x), std::abs(a.y), std::abs(a.z)});
  if (m < 0x1p500 && m > 0x1p-500) return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  return std::hypot(a.x, a.y, a.z);
}
inline double Distance(Vec2 a, Vec2 b) { return Length(a - b); }
inline double Distance(Vec3 a, Vec3 b) { return Length(a - b); }

// The unit gradient at q of the distance to a set whose nearest point to q is `closest`:
// (q - closest) / |q - closest|, and zero where q is on the set (a minimum of the distance,
// where zero is a subgradient). Where several points of the set are nearest, the distance
// is not differentiable there, and this is its one-sided gradient towards `closest`.
template <class V>
V UnitGradient(V q, V closest) {
  const double d = Length(q - closest);
  return d > 0 ? (q - closest) / d : V(0);
}

}  // namespace gvd
