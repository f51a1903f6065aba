// Sites for store tests: random ones of every kind with awkward values, compared field by
// field and bit for bit (written here, not taken from the code under test); and a temporary
// directory.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "render/kernel/path2.h"
#include "render/kernel/site2.h"
#include "server/store/store.h"

namespace gvd::testing {

// What a store read holds of SiteT's: a stored scene's sites, and the sites a change read
// from the log puts; none where they are of the other dimension.
template <class SiteT = Site>
std::vector<SiteT> SitesOf(const StoredScene& scene) {
  const auto* sites = std::get_if<std::vector<SiteT>>(&scene.sites);
  return sites ? *sites : std::vector<SiteT>();
}
template <class SiteT = Site>
SharedSites<SiteT> PutOf(const SceneChanges& changes) {
  const auto* sites = std::get_if<SharedSites<SiteT>>(&changes.put);
  return sites ? *sites : SharedSites<SiteT>();
}

inline bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

inline bool SamePoints(const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!SameBits(a[i].x, b[i].x) || !SameBits(a[i].y, b[i].y)) return false;
  }
  return true;
}

// Field by field and bit for bit, written here rather than taken from the code under test.
inline bool SameSite(const Site& a, const Site& b) {
  if (a.id != b.id || !SameBits(a.additive, b.additive) ||
      !SameBits(a.multiplicative, b.multiplicative) || !SameBits(a.max_distance, b.max_distance) ||
      a.geometry.index() != b.geometry.index()) {
    return false;
  }
  if (auto* p = std::get_if<PointSite>(&a.geometry)) {
    return SamePoints({p->p}, {std::get<PointSite>(b.geometry).p});
  }
  if (auto* s = std::get_if<SegmentSite>(&a.geometry)) {
    const auto& t = std::get<SegmentSite>(b.geometry);
    return SamePoints({s->a, s->b}, {t.a, t.b});
  }
  if (auto* l = std::get_if<PolylineSite>(&a.geometry)) {
    return SamePoints(l->points, std::get<PolylineSite>(b.geometry).points);
  }
  if (auto* g = std::get_if<PolygonSite>(&a.geometry)) {
    const auto& h = std::get<PolygonSite>(b.geometry);
    return g->side == h.side && SamePoints(g->vertices, h.vertices);
  }
  if (auto* p = std::get_if<PathSite>(&a.geometry)) {
    const auto& q = std::get<PathSite>(b.geometry);
    if (p->fill != q.fill || p->side != q.side || !SameBits(p->tolerance, q.tolerance) ||
        !SameBits(p->approximation, q.approximation) || p->subpaths.size() != q.subpaths.size() || !SamePoints(p->flat, q.flat)) {
      return false;
    }
    for (size_t i = 0; i < p->subpaths.size(); ++i) {
      const Subpath &s = p->subpaths[i], &t = q.subpaths[i];
      if (s.closed != t.closed || s.degrees != t.degrees || !SamePoints(s.points, t.points)) {
        return false;
      }
    }
    return true;
  }
  const auto& c = std::get<BezierSite>(a.geometry);
  const auto& d = std::get<BezierSite>(b.geometry);
  return SameBits(c.tolerance, d.tolerance) && SamePoints(c.control, d.control) &&
         SamePoints(c.flat, d.flat);
}

// A random site of every kind in turn, with awkward values: -0, subnormals, huge and tiny
// magnitudes, infinite max_distance, ids with bytes of every value.
inline Site RandomSite(std::mt19937_64& rng, int kind, const std::string& id) {
  const double awkward[] = {-0.0, 5e-324, 1e308, -1e-300, 0.1, 1.0 / 3, -7.5e12};
  std::uniform_real_distribution<double> u(-1e6, 1e6);
  auto value = [&] { return rng() % 4 == 0 ? awkward[rng() % 7] : u(rng); };
  auto points = [&](size_t n) {
    std::vector<Vec2> v(n);
    for (Vec2& p : v) p = {value(), value()};
    return v;
  };
  Site s;
  s.id = id;
  s.additive = rng() % 2 ? 0 : std::abs(value());
  s.multiplicative = rng() % 2 ? 1 : 1 + std::abs(u(rng));
  s.max_distance = rng() % 2 ? INFINITY : 1 + std::abs(u(rng));
  switch (kind % 6) {
    case 0: s.geometry = PointSite{{value(), value()}}; break;
    case 1: s.geometry = SegmentSite{{value(), value()}, {value(), value()}}; break;
    case 2: s.geometry = PolylineSite{points(2 + rng() % 40)}; break;
    case 3: s.geometry = PolygonSite{points(3 + rng() % 40), static_cast<Side>(rng() % 3)}; break;
    case 4: s.geometry = BezierSite{points(3 + rng() % 2), std::abs(value()), points(2 + rng() % 90)}; break;
    default: {
      std::vector<Subpath> subpaths(1 + rng() % 3);
      for (Subpath& sub : subpaths) {
        sub.closed = rng() % 2;
        sub.points = points(1);
        for (size_t k = 1 + rng() % 6; k > 0; --k) {
          sub.degrees.push_back(static_cast<uint8_t>(1 + rng() % 3));
          for (Vec2 p : points(sub.degrees.back())) sub.points.push_back(p);
        }
      }
      const bool closed = std::all_of(subpaths.begin(), subpaths.end(), [](const Subpath& s) { return s.closed; });
      PathSite path = MakePath(subpaths, static_cast<FillRule>(rng() % 2),
                               closed ? static_cast<Side>(rng() % 3) : Side::kBoth, rng() % 2 ? 0 : std::abs(value()));
      if (rng() % 2) path.approximation = std::abs(value()) + 5e-324;  // finite and above 0
      s.geometry = std::move(path);
    }
  }
  return s;
}

// A fresh directory under /tmp, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    char t[] = "/tmp/gvd-store-XXXXXX";
    path_ = mkdtemp(t);
  }
  ~TempDir() { std::system(("rm -rf '" + path_ + "'").c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace gvd::testing
