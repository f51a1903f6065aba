#include "render/exact.h"

#include <cassert>

namespace gvd {
namespace {

template <class... Fs>
struct Overloaded : Fs... {
  using Fs::operator()...;
};
template <class... Fs>
Overloaded(Fs...) -> Overloaded<Fs...>;  // clang 14 lacks C++20's aggregate deduction

}  // namespace

double ExactDistance(Vec2 q, const Geometry& g) {
  return std::visit(Overloaded{[&](const PointSite& s) { return Distance(q, s.p); }}, g);
}

Window BoundingBox(const Geometry& g) {
  return std::visit(Overloaded{[](const PointSite& s) { return Window{s.p.x, s.p.y, s.p.x, s.p.y}; }},
                    g);
}

double FarthestDistance(const Window& rect, const Geometry& g) {
  // For a point the distance is convex in p, so its maximum over the rectangle is at a corner.
  return std::visit(Overloaded{[&](const PointSite& s) { return rect.FarthestDistance(s.p); }}, g);
}

ExactNearest NearestBruteForce(Vec2 q, std::span<const Site> sites) {
  assert(!sites.empty());
  ExactNearest best{0, ExactDistance(q, sites[0].geometry)};
  for (size_t i = 1; i < sites.size(); ++i) {
    double d = ExactDistance(q, sites[i].geometry);
    if (d < best.distance) best = {i, d};
  }
  return best;
}

}  // namespace gvd
