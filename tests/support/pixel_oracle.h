// Checks of rendered frames against the tests' double-precision oracle (oracle.h), and random sites of
// every kind, shared by the GL tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "render/kernel/exact2.h"
#include "render/kernel/path2.h"
#include "tests/support/oracle.h"
#include "render/scene/frame.h"
#include "render/scene/slot_table.h"

namespace gvd {

// The site's value ignoring its max_distance and side.
inline double Unrestricted(Vec2 p, const Site& s) {
  return s.multiplicative * oracle::DrawnDistance(p, s.geometry) + s.additive;
}

// Whether the site may be drawn at p: within max_distance + margin (the margin widened by
// what a fan's corners and float arithmetic add), and on its polygon's side or within
// margin of the boundary (render/kernel/grid2.h: DrawMargin); a path's drawn boundary.
inline bool MayBeDrawn(Vec2 p, const Site& s, const Frame& f) {
  const double margin = DrawMargin(f.grid()) * (1 + 1e-5);
  double d = oracle::DrawnDistance(p, s.geometry);
  if (d > (s.max_distance + margin + f.grid().pixel_size() / 8) * f.error().overestimate)
    return false;
  const Side side = oracle::SideOf(s.geometry);
  return side == Side::kBoth || d <= margin || oracle::InsideOf(p, s.geometry) == (side == Side::kInside);
}

// The sites of `slots` as the oracle reads them, slot by slot: a free slot becomes a site
// that is never a candidate (max_distance 0), so that a frame's ids (slot + 1) index it.
inline SiteTable OracleSites(const SlotTable& slots) {
  SiteTable table;
  for (uint32_t s = 0; s < slots.size(); ++s) {
    const Site* site = slots.get(s);
    table.push_back(site ? *site : Site{"", PointSite{{1e30, 1e30}}, 0, 1, 0});
    if (!site) table.back().max_distance = 0;
  }
  return table;
}

struct PixelReport {
  size_t empty = 0;  // pixel centres where no site is a candidate
  size_t band = 0;   // centres held by a site present there but not a candidate
  double worst_px = 0;
};

// Every pixel centre p of the frame, against the oracle:
//  - an empty centre has no candidate site; a centre with a candidate holds some site;
//  - the stored value D is the stored site's value within the meshes' error (never below
//    it by more than the arithmetic slack), and the site is present at p;
//  - when that site is a candidate at p, it is within 2 eps (times the weight) of the best;
//  - D bounds the best value at p as the frame's error model says (what queries rely on),
//    the drawn flattenings of curves within the model's curve term of the curves.
//  The oracle's best site at each centre (oracle::BestSite, row by row) may come from
//  `truths`, computed once for several frames of one grid, sites and diagram (Truths).
inline std::vector<oracle::Best> Truths(const Grid& g, const SiteTable& sites, Diagram diagram) {
  std::vector<oracle::Best> out;
  out.reserve(g.pixel_count());
  for (uint32_t j = 0; j < g.height; ++j) {
    for (uint32_t i = 0; i < g.width; ++i) out.push_back(oracle::BestSite(g.Center(i, j), sites, diagram));
  }
  return out;
}

inline PixelReport CheckEveryPixel(const Frame& f, const SiteTable& sites, const std::string& what,
                                   const std::vector<oracle::Best>* truths = nullptr) {
  const Grid& g = f.grid();
  const ErrorModel& e = f.error();
  const double excess = e.max_excess;
  const bool nearest = e.diagram == Diagram::kNearest;
  PixelReport report;
  int failures = 0;
  for (uint32_t j = 0; j < g.height && failures < 5; ++j) {
    for (uint32_t i = 0; i < g.width && failures < 5; ++i) {
      Vec2 p = g.Center(i, j);
      const oracle::Best truth = truths ? (*truths)[size_t{j} * g.width + i]
                                        : oracle::BestSite(p, sites, e.diagram);
      uint32_t id = f.id_at(i, j);
      auto fail = [&](const std::string& why) {
        ++failures;
        ADD_FAILURE() << what << ": pixel " << i << "," << j << " at (" << p.x << ", " << p.y
                      << "): " << why << " (id " << id << ", stored " << f.distance_at(i, j)
                      << ", truth " << (truth.found ? sites[truth.index].id : "none") << " "
                      << truth.value << ")";
      };
      if (id == 0) {
        ++report.empty;
        if (truth.found) fail("empty, but a site is a candidate");
        continue;
      }
      if (id > sites.size()) {
        fail("names no site");
        continue;
      }
      const Site& s = sites[id - 1];
      const double stored = f.distance_at(i, j), slack = e.Slack(stored);
      const double v = Unrestricted(p, s);
      report.worst_px = std::max(report.worst_px, std::abs(stored - v) / g.pixel_size());
      if (!(stored >= v - slack && stored <= v + excess + slack)) fail("stored value off");
      if (!MayBeDrawn(p, s, f)) fail("site drawn where it is not present");
      if (!truth.found) {
        ++report.band;
        continue;
      }
      // The oracle's values are the true curves', the raster's their flattenings' (within
      // the error model's curve term).
      if (nearest ? !(e.LowerBound(stored) - e.curve <= truth.value)
                  : !(e.UpperBound(stored) + e.curve >= truth.value)) {
        fail("the error model's bound fails");
      }
      // (The best site's value is the truth's: a curve measured once.)
      const double value = id - 1 == truth.index ? truth.value : oracle::Value(p, s);
      if (!std::isfinite(value)) {
        ++report.band;
        continue;
      }
      double gap = nearest ? v - truth.value : truth.value - v;
      if (!(gap <= 2 * excess + 2 * slack + e.curve)) fail("stored site not within 2 eps of the best");
    }
  }
  return report;
}

// Random geometry of each kind, around the unit window (partly outside it).
struct Generator {
  // Kind(k) for k < kKinds gives a point, segment, polyline, polygon (both sides, outside,
  // inside), Bezier, path (both sides, outside, inside), as kKindNames says.
  static constexpr int kKinds = 10;
  static constexpr const char* kKindNames[kKinds] = {
      "point",  "segment", "polyline",     "polygon",     "polygon outside",
      "polygon inside", "bezier", "path", "path outside", "path inside"};
  std::mt19937_64 rng;
  explicit Generator(uint64_t seed) : rng(seed) {}
  double U(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  Vec2 P() { return {U(-0.1, 1.1), U(-0.1, 1.1)}; }
  Vec2 Near(Vec2 c, double r) { return {c.x + U(-r, r), c.y + U(-r, r)}; }

  Geometry Kind(int kind) {
    switch (kind) {
      case 0:
        return PointSite{P()};
      case 1: {
        Vec2 a = P();
        return SegmentSite{a, Near(a, 0.3)};
      }
      case 2: {
        PolylineSite l{{P()}};
        int n = 2 + int(U(0, 4));
        for (int k = 1; k < n; ++k) l.points.push_back(Near(l.points.back(), 0.2));
        return l;
      }
      case 3:
      case 4:
      case 5: {  // star-shaped, often concave
        Vec2 c = P();
        int n = 3 + int(U(0, 6));
        PolygonSite poly;
        for (int k = 0; k < n; ++k) {
          double t = 2 * M_PI * (k + U(0, 0.8)) / n, r = U(0.03, 0.2);
          poly.vertices.push_back({c.x + r * std::cos(t), c.y + r * std::sin(t)});
        }
        poly.side = kind == 3 ? Side::kBoth : kind == 4 ? Side::kOutside : Side::kInside;
        return poly;
      }
      case 6: {
        Vec2 a = P();
        std::vector<Vec2> control{a, Near(a, 0.3), Near(a, 0.3)};
        if (U(0, 1) < 0.5) control.push_back(Near(a, 0.3));
        return MakeBezier(control, 0.002);
      }
      default: {  // loops of lines and curves around one centre, open ones with no side
        const Vec2 c = P();
        std::vector<Subpath> subpaths(1 + int(U(0, 3)));
        double scale = U(0.1, 0.25);
        for (Subpath& s : subpaths) {
          s.closed = kind != 7 || U(0, 1) < 0.7;
          const int n = 2 + int(U(0, 5));
          for (int k = 0; k <= n; ++k) {
            const double t = 2 * M_PI * (k + U(0, 0.8)) / n, r = scale * U(0.4, 1);
            const Vec2 p{c.x + r * std::cos(t), c.y + r * std::sin(t)};
            if (k > 0) {
              const int degree = 1 + int(U(0, 3));
              for (int i = 1; i < degree; ++i) s.points.push_back(Near(s.points.back(), 0.1));
              s.degrees.push_back(static_cast<uint8_t>(degree));
            }
            s.points.push_back(p);
          }
          scale *= U(0.3, 0.8);  // the next loop nested within, often
        }
        const Side side = kind == 7 ? Side::kBoth : kind == 8 ? Side::kOutside : Side::kInside;
        return MakePath(subpaths, U(0, 1) < 0.5 ? FillRule::kNonZero : FillRule::kEvenOdd,
                        side, 0.002);
      }
    }
  }
};

}  // namespace gvd
