// The coverage radii, clips and pieces against the oracle, pixel by pixel: every pixel centre
// lies within the radius and clip of each of its exact best sites (render/plan/coverage.h states
// the proof).
#include "render/plan/coverage.h"

#include <gtest/gtest.h>

#include <random>

#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "render/plan/tile_lists.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

// A site's value as drawn (render/plan/coverage.h): present DrawMargin beyond its max_distance
// and beyond the boundary of the side of a polygon it excludes; +infinity elsewhere.
double DrawnValue(Vec2 q, const Site& s, double margin) {
  const double d = oracle::DrawnDistance(q, s.geometry);
  if (d > s.max_distance + margin) return INFINITY;
  if (auto* poly = std::get_if<PolygonSite>(&s.geometry)) {
    if (poly->side != Side::kBoth && d > margin &&
        oracle::Inside(q, poly->vertices) != (poly->side == Side::kInside)) {
      return INFINITY;
    }
  }
  return s.multiplicative * d + s.additive;
}

// The features of a site's mesh pieces, in ForEachPiece's order: an edge (a != b) for the
// half-tent on its left, a vertex (a == b) for a fan.
std::vector<std::pair<Vec2, Vec2>> PieceFeatures(const Geometry& g) {
  std::vector<std::pair<Vec2, Vec2>> out;
  ForEachPiece(g, [&](Vec2 v, double, double) { out.push_back({v, v}); },
               [&](Vec2 a, Vec2 b) { out.push_back({a, b}); });
  return out;
}

// How far a piece's feature is from q where q lies in the piece's region (a half-tent's half
// of the slab, with a little slack at its edges), else infinity. A fan's wedge is not tested: the callers only
// ask for vertices as near as the whole site, and those lie in their wedges.
oracle::Real PieceDistance(Vec2 q, std::pair<Vec2, Vec2> f) {
  const auto [a, b] = f;
  if (a == b) return oracle::ToSegment(q, a, a);
  const oracle::Real dx = oracle::Real(b.x) - a.x, dy = oracle::Real(b.y) - a.y;
  const oracle::Real t = ((oracle::Real(q.x) - a.x) * dx + (oracle::Real(q.y) - a.y) * dy) /
                         (dx * dx + dy * dy);
  if (t < -1e-9 || t > 1 + 1e-9) return INFINITY;
  const oracle::Real left = dx * (oracle::Real(q.y) - a.y) - dy * (oracle::Real(q.x) - a.x);
  if (left < -1e-9 * std::sqrt(dx * dx + dy * dy)) return INFINITY;
  return oracle::ToSegment(q, a, b);
}

// Whether q projects on a half-tent's edge ab within the part of it the piece is drawn
// over (a fan is drawn whole).
bool WithinRange(Vec2 q, std::pair<Vec2, Vec2> f, const PieceDraw& piece) {
  const auto [a, b] = f;
  if (a == b) return true;
  const oracle::Real dx = oracle::Real(b.x) - a.x, dy = oracle::Real(b.y) - a.y;
  const oracle::Real t =
      ((oracle::Real(q.x) - a.x) * dx + (oracle::Real(q.y) - a.y) * dy) / std::sqrt(dx * dx + dy * dy);
  const oracle::Real slack = 1e-12 * (1 + std::abs(t));
  return piece.from - slack <= t && t <= piece.to + slack;
}

bool Holds(const PixelRect& c, uint32_t i, uint32_t j) {
  return i >= c.x0 && i < c.x1 && j >= c.y0 && j < c.y1;
}

// Every site best at a pixel centre in the drawn diagram, ties included, must reach it
// within its clip; and in kNearest, unless it is a plain point, one of its pieces that holds
// its nearest point to the centre must reach it within that piece's clip.
void ExpectCovered(const Grid& grid, const SiteTable& sites, uint32_t tile_px = 0,
                   Diagram diagram = Diagram::kNearest) {
  SlotTable slots(sites);
  SiteIndex index = SiteIndex::Build(slots);
  Coverage cov = ComputeCoverage(grid, slots, index, {0, 0, grid.width, grid.height}, tile_px,
                                 diagram, true);
  const bool farthest = diagram == Diagram::kFarthest;
  ASSERT_EQ(cov.pieces.size(), farthest ? 0 : sites.size());
  int failures = 0;
  for (uint32_t j = 0; j < grid.height && failures < 5; ++j) {
    for (uint32_t i = 0; i < grid.width && failures < 5; ++i) {
      Vec2 p = grid.Center(i, j);
      // The least value, or the greatest of those present (finite).
      double best = farthest ? -INFINITY : INFINITY;
      for (const Site& s : sites) {
        const double v = DrawnValue(p, s, DrawMargin(grid));
        if (!farthest) best = std::min(best, v);
        if (farthest && std::isfinite(v)) best = std::max(best, v);
      }
      for (size_t s = 0; s < sites.size() && std::isfinite(best); ++s) {
        if (DrawnValue(p, sites[s], DrawMargin(grid)) != best) continue;
        const double d = oracle::DrawnDistance(p, sites[s].geometry);
        if (!(d <= cov.radius[s])) {
          ++failures;
          ADD_FAILURE() << "pixel " << i << "," << j << ": best site " << s << " at " << d
                        << " but radius " << cov.radius[s] << " (tile " << cov.tile_px << ")";
        }
        const PixelRect& c = cov.clip[s];
        if (!Holds(c, i, j)) {
          ++failures;
          ADD_FAILURE() << "pixel " << i << "," << j << ": best site " << s
                        << " but its clip is [" << c.x0 << ", " << c.x1 << ") x [" << c.y0
                        << ", " << c.y1 << ") (tile " << cov.tile_px << ")";
        }
        const Site& site = sites[s];
        if (farthest) continue;  // drawn whole
        if (std::holds_alternative<PointSite>(site.geometry) && site.multiplicative == 1 &&
            site.additive == 0 && std::isinf(site.max_distance)) {
          continue;  // a plain point is drawn as one cone
        }
        const auto features = PieceFeatures(site.geometry);
        const std::vector<PieceDraw>& pieces = cov.pieces[s];
        // A centre within a 128th of a pixel of an edge's line, in its slab: the rasterizer's
        // snapping (1/256 pixel) may give it to either half of the tent, so both must reach it.
        for (size_t k = 0; k < features.size(); ++k) {
          const auto [a, b] = features[k];
          if (a == b || !(PieceDistance(p, features[k]) <= d + 1e-9 * (1 + d))) continue;
          if (!(d <= grid.pixel_size() / 128)) continue;
          const size_t other = k ^ 1;  // the other half: g(a, b) and g(b, a) come in pairs
          if (other >= pieces.size() || !(pieces[other].radius >= 0) ||
              !Holds(pieces[other].clip, i, j) ||
              !WithinRange(p, {features[other].first, features[other].second}, pieces[other])) {
            ++failures;
            ADD_FAILURE() << "pixel " << i << "," << j << ": best site " << s << " at " << d
                          << " from an edge, but the far half of its tent does not reach it";
          }
        }
        bool reached = false;
        for (size_t k = 0; k < features.size() && !reached; ++k) {
          const oracle::Real dk = PieceDistance(p, features[k]);
          if (!(dk <= d + 1e-9 * (1 + d))) continue;  // not where the site's nearest point is
          reached = k < pieces.size() && dk <= pieces[k].radius && Holds(pieces[k].clip, i, j) &&
                    WithinRange(p, features[k], pieces[k]);
        }
        if (!reached) {
          ++failures;
          ADD_FAILURE() << "pixel " << i << "," << j << ": best site " << s
                        << " but none of its pieces nearest there reaches it (tile "
                        << cov.tile_px << ")";
        }
      }
    }
  }
}

SiteTable RandomPoints(size_t n, const Window& w, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
  SiteTable sites;
  for (size_t i = 0; i < n; ++i) sites.push_back({std::to_string(i), PointSite{{ux(rng), uy(rng)}}});
  return sites;
}

TEST(Coverage, RandomScenesAndTileSizes) {
  Window w{-3, 1, 5, 4};
  Grid grid{w, 160, 90};
  for (size_t n : {1, 2, 10, 300}) {
    for (uint32_t tile : {0u, 1u, 4u, 13u, 64u}) ExpectCovered(grid, RandomPoints(n, w, n), tile);
  }
  ExpectCovered(grid, RandomPoints(3000, w, 3), 0);
}

TEST(Coverage, LatticeTiesAndCoincidentSites) {
  // Sites on the pixel-centre lattice and at tile corners: many exact ties.
  Grid grid{{0, 0, 64, 64}, 64, 64};
  SiteTable sites;
  for (int y = 0; y <= 64; y += 8) {
    for (int x = 0; x <= 64; x += 8) sites.push_back({"", PointSite{{x + 0.5, y + 0.5}}});
  }
  sites.push_back({"", PointSite{{20.5, 20.5}}});
  sites.push_back({"", PointSite{{20.5, 20.5}}});
  for (uint32_t tile : {0u, 3u, 8u, 16u}) ExpectCovered(grid, sites, tile);
}

TEST(Coverage, SitesOutsideTheWindowAndSitesThatOwnNothing) {
  Grid grid{{0, 0, 1, 1}, 50, 50};
  SiteTable sites = {{"", PointSite{{-0.5, 0.5}}}, {"", PointSite{{30, -40}}},
                     {"", PointSite{{1.2, 1.3}}},  {"", PointSite{{0.7, 0.2}}},
                     {"", PointSite{{-5, 0.5}}}};  // hidden behind (-0.5, 0.5)
  ExpectCovered(grid, sites);
  SlotTable slots(sites);
  SiteIndex index = SiteIndex::Build(slots);
  Coverage cov = ComputeCoverage(grid, slots, index, {0, 0, 50, 50});
  EXPECT_LT(cov.radius[4], 0) << "a site nearest to no pixel centre needs no mesh";
  EXPECT_LT(cov.radius[1], 0);
}

// Every kind of site, weights, max_distance and sides, ties between coincident sites, and
// sites beyond the window: radii and clips hold every pixel centre each is best at.
TEST(Coverage, SitesOfEveryKind) {
  Window w{0, 0, 1, 1};
  Grid grid{w, 96, 80};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.2, 1.2), d(-0.08, 0.08), weight(0.5, 3);
  for (int scene = 0; scene < 4; ++scene) {
    SiteTable sites;
    for (int k = 0; k < 60; ++k) {
      Vec2 c{u(rng), u(rng)};
      auto near = [&] { return Vec2{c.x + d(rng), c.y + d(rng)}; };
      Site s{std::to_string(k), PointSite{c}};
      switch (k % 6) {
        case 0: s.geometry = SegmentSite{near(), near()}; break;
        case 1: s.geometry = PolylineSite{{near(), near(), near(), near()}}; break;
        case 2: {
          PolygonSite poly{{near(), near(), near(), near(), near()}};
          poly.side = static_cast<Side>(k / 6 % 3);
          s.geometry = poly;
          break;
        }
        case 3: s.geometry = MakeBezier({near(), near(), near(), near()}, grid.pixel_size()); break;
        case 4:
          s.multiplicative = weight(rng);
          s.additive = 0.01 * weight(rng);
          s.max_distance = 0.1 * weight(rng);
          break;
        default: break;
      }
      sites.push_back(s);
    }
    sites.push_back(sites[5]);  // coincident twins tie everywhere
    for (uint32_t tile : {0u, 1u, 3u, 8u}) {
      ExpectCovered(grid, sites, tile);
      ExpectCovered(grid, sites, tile, Diagram::kFarthest);
    }
  }
}

// Sites long enough for their segment trees (render/kernel/segment_tree.h), which coverage then
// searches for the pieces and segments near each tile: random walks, scribbles crossing the
// window and one another, many-sided polygons (each side), with small sites and points
// among them.
SiteTable LongSites(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.1, 1.1), step(-0.04, 0.04);
  SiteTable sites;
  for (int k = 0; k < 12; ++k) {
    Site s{"long" + std::to_string(k), PointSite{}};
    const int n = 40 + 40 * (k % 3);
    if (k % 4 == 0) {  // a random walk
      PolylineSite walk{{{u(rng), u(rng)}}};
      for (int i = 0; i < n; ++i) {
        walk.points.push_back(walk.points.back() + Vec2{step(rng), step(rng)});
      }
      s.geometry = walk;
    } else if (k % 4 == 1) {  // a scribble across the window
      PolylineSite scribble;
      for (int i = 0; i < n; ++i) scribble.points.push_back({u(rng), u(rng)});
      s.geometry = scribble;
    } else {  // a wobbly many-sided polygon
      const Vec2 c{u(rng), u(rng)};
      PolygonSite poly;
      for (int i = 0; i < n; ++i) {
        const double t = 2 * M_PI * i / n, r = 0.15 + step(rng);
        poly.vertices.push_back({c.x + r * std::cos(t), c.y + r * std::sin(t)});
      }
      poly.side = static_cast<Side>(k / 4 % 3);
      s.geometry = poly;
    }
    if (k == 5) s.multiplicative = 1.7;
    if (k == 6) s.additive = 0.02;
    sites.push_back(s);
  }
  for (const Site& p : RandomPoints(30, {0, 0, 1, 1}, seed)) sites.push_back(p);
  sites.push_back({"seg", SegmentSite{{0.2, 0.2}, {0.3, 0.25}}});
  return sites;
}

TEST(Coverage, LongSitesThroughTheirSegmentTrees) {
  Grid grid{{0, 0, 1, 1}, 96, 96};
  for (uint64_t seed : {1, 2}) {
    const SiteTable sites = LongSites(seed);
    SlotTable slots(sites);
    ASSERT_NE(slots.get(0)->segment_tree, nullptr);
    for (uint32_t tile : {0u, 1u, 4u}) ExpectCovered(grid, sites, tile);
  }
}

// TileCover::NeededSegments: at every pixel centre of a tile where a site kept for the tile
// is best, some segment it names holds the site's nearest point; on long sites (through
// their trees) and short ones.
TEST(Coverage, NeededSegmentsHoldTheNearestPointWhereTheSiteIsBest) {
  Grid grid{{0, 0, 1, 1}, 96, 96};
  SiteTable sites = LongSites(3);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> d(-0.05, 0.05);
  for (int k = 0; k < 20; ++k) {  // short polylines among them
    const Vec2 c{0.05 * k, 1 - 0.05 * k};
    sites.push_back({"short" + std::to_string(k),
                     PolylineSite{{c, c + Vec2{d(rng), d(rng)}, c + Vec2{d(rng), d(rng)}}}});
  }
  SlotTable slots(sites);
  SiteIndex index = SiteIndex::Build(slots);
  const TileCover cover(grid, slots, index);
  const double margin = DrawMargin(grid);
  size_t checked = 0, needed_total = 0, segments_total = 0;
  for (uint32_t size : {8u, 3u}) {
    for (uint32_t y0 = 0; y0 < grid.height; y0 += size) {
      for (uint32_t x0 = 0; x0 < grid.width; x0 += size) {
        const PixelRect tile{x0, y0, std::min(x0 + size, grid.width), std::min(y0 + size, grid.height)};
        std::vector<uint32_t> kept;
        std::vector<double> radii;
        std::vector<uint32_t> all(sites.size());
        for (uint32_t s = 0; s < all.size(); ++s) all[s] = s;
        const double upper = cover.Keep(tile, all, &kept, &radii);
        for (uint32_t slot : kept) {
          const Site& site = sites[slot];
          if (std::holds_alternative<PointSite>(site.geometry)) continue;
          std::vector<uint32_t> needed;
          TileCover::NeededSegments(grid, tile, site, upper, &needed);
          const auto segments = oracle::Segments(site.geometry);
          needed_total += needed.size();
          segments_total += segments.size();
          ASSERT_TRUE(std::is_sorted(needed.begin(), needed.end()));
          ASSERT_EQ(std::adjacent_find(needed.begin(), needed.end()), needed.end());
          for (uint32_t j = tile.y0; j < tile.y1; ++j) {
            for (uint32_t i = tile.x0; i < tile.x1; ++i) {
              const Vec2 p = grid.Center(i, j);
              double best = INFINITY;
              for (const Site& other : sites) best = std::min(best, DrawnValue(p, other, margin));
              if (DrawnValue(p, site, margin) != best) continue;
              const double dist = oracle::DrawnDistance(p, site.geometry);
              bool held = false;
              for (uint32_t n : needed) {
                ASSERT_LT(n, segments.size());
                held = held || std::abs(static_cast<double>(oracle::ToSegment(
                                   p, segments[n].first, segments[n].second)) -
                               dist) <= oracle::Tolerance(p, dist);
              }
              ASSERT_TRUE(held) << "pixel " << i << "," << j << ", site " << slot;
              ++checked;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(checked, 5000u);
  // The point of it: most segments are left out of most tiles.
  EXPECT_LT(needed_total * 5, segments_total);
}

// Farthest-site diagrams of points, with ties on a lattice and twins; and points inside a
// ring of others, which are farther than them from every point of the plane, are drawn
// nowhere.
TEST(Coverage, FarthestPoints) {
  Window w{-3, 1, 5, 4};
  Grid grid{w, 160, 90};
  for (size_t n : {1, 2, 10, 300}) {
    for (uint32_t tile : {0u, 1u, 4u, 13u}) {
      ExpectCovered(grid, RandomPoints(n, w, n), tile, Diagram::kFarthest);
    }
  }
  Grid lattice{{0, 0, 64, 64}, 64, 64};
  SiteTable sites;
  for (int y = 0; y <= 64; y += 16) {
    for (int x = 0; x <= 64; x += 16) sites.push_back({"", PointSite{{x + 0.5, y + 0.5}}});
  }
  sites.push_back(sites[0]);
  sites.push_back({"", PointSite{{-40, 32.5}}});
  for (uint32_t tile : {0u, 3u, 8u}) ExpectCovered(lattice, sites, tile, Diagram::kFarthest);

  Grid unit{{0, 0, 1, 1}, 128, 128};
  SiteTable ring;
  for (int k = 0; k < 24; ++k) {
    const double t = 2 * M_PI * k / 24;
    ring.push_back({"", PointSite{{0.5 + 0.4 * std::cos(t), 0.5 + 0.4 * std::sin(t)}}});
  }
  const size_t inner = ring.size();
  for (const Site& s : RandomPoints(200, {0.4, 0.4, 0.6, 0.6}, 9)) ring.push_back(s);
  ExpectCovered(unit, ring, 0, Diagram::kFarthest);
  SlotTable slots(ring);
  SiteIndex index = SiteIndex::Build(slots);
  Coverage cov = ComputeCoverage(unit, slots, index, unit.all(), 0, Diagram::kFarthest);
  for (size_t s = inner; s < ring.size(); ++s) EXPECT_LT(cov.radius[s], 0) << s;
}

// Dense random points: the radii stay near the cells' size, and the clips near the cells'
// boxes, so the meshes are drawn over a small multiple of the window (the point of the
// exercise), not sites x window.
TEST(Coverage, FillIsASmallMultipleOfTheGrid) {
  Window w{0, 0, 1, 1};
  Grid grid{w, 512, 512};
  SlotTable slots(RandomPoints(20000, w, 5));
  SiteIndex index = SiteIndex::Build(slots);
  Coverage cov = ComputeCoverage(grid, slots, index, {0, 0, 512, 512});
  double discs = 0, clipped = 0;
  for (uint32_t s = 0; s < slots.size(); ++s) {
    const double r = cov.radius[s];
    if (r < 0) continue;
    discs += M_PI * r * r;
    // The part of the disc's box inside the clip.
    const Vec2 p = std::get<PointSite>(slots.get(s)->geometry).p;
    const Window c = grid.Area(cov.clip[s]);
    clipped += std::max(0.0, std::min(p.x + r, c.max_x) - std::max(p.x - r, c.min_x)) *
               std::max(0.0, std::min(p.y + r, c.max_y) - std::max(p.y - r, c.min_y));
  }
  EXPECT_LT(discs, 5.0);  // against 20,000 for full cones
  EXPECT_LT(clipped, 3.0);
}

// A scene of plain points only takes its tiles' lists from PointCover's uniform grid: every
// point nearest to a pixel centre (ties included, by the oracle's distances) must be in the
// list of the centre's tile, with a radius and clip that reach the centre.
// Where PointCover declines the scene (`gridded` false), the index's path must do as well.
// Each tile's points must also come in ascending id order (the scan's tie rule).
void ExpectListed(const Grid& grid, const SiteTable& sites, const std::string& what,
                  bool gridded = true) {
  SlotTable slots(sites);
  SiteIndex index = SiteIndex::Build(slots);
  ASSERT_EQ(PointCover::Of(grid, slots) != nullptr, gridded) << what;
  TileLists lists;
  const Coverage cov = TileCandidates(grid, slots, index, &lists);
  const uint32_t tiles_x = (grid.width + kScanTile - 1) / kScanTile;
  for (size_t t = 0; t + 1 < lists.offsets.size() / 3; ++t) {
    ASSERT_TRUE(std::is_sorted(lists.points.begin() + lists.offsets[3 * t],
                               lists.points.begin() + lists.offsets[3 * t + 3],
                               [](const TileLists::Point& a, const TileLists::Point& b) {
                                 return a.id < b.id;
                               }))
        << what << ": tile " << t << "'s points are not in id order";
  }
  std::vector<double> d(sites.size());
  int failures = 0;
  for (uint32_t j = 0; j < grid.height && failures < 5; ++j) {
    for (uint32_t i = 0; i < grid.width && failures < 5; ++i) {
      const Vec2 p = grid.Center(i, j);
      double best = INFINITY;
      for (size_t s = 0; s < sites.size(); ++s) {
        d[s] = oracle::DrawnDistance(p, sites[s].geometry);
        best = std::min(best, d[s]);
      }
      const size_t t = size_t{j / kScanTile} * tiles_x + i / kScanTile;
      for (size_t s = 0; s < sites.size(); ++s) {
        if (d[s] != best) continue;
        bool listed = false;
        for (uint32_t k = lists.offsets[3 * t]; k < lists.offsets[3 * t + 3]; ++k) {
          listed = listed || lists.points[k].id == s + 1;
        }
        if (!listed || !(d[s] <= cov.radius[s]) || !Holds(cov.clip[s], i, j)) {
          ++failures;
          ADD_FAILURE() << what << ": pixel " << i << "," << j << ": nearest point " << s
                        << " at " << d[s] << (listed ? "" : " is not in its tile's list")
                        << ", radius " << cov.radius[s];
        }
      }
    }
  }
}

TEST(PointCover, RandomPointsAgainstTheOracle) {
  // Pixels that are not square, a grid that is not a multiple of the tiles, and from one
  // point to several per pixel.
  Window w{-3, 1, 5, 4};
  Grid grid{w, 100, 61};
  for (size_t n : {1, 2, 10, 300, 3000, 8000}) {
    ExpectListed(grid, RandomPoints(n, w, n), "points " + std::to_string(n));
  }
  // A fifth of them outside the window (in the buckets at its edge), near or far.
  auto with = [](SiteTable inside, const SiteTable& outside) {
    inside.insert(inside.end(), outside.begin(), outside.end());
    return inside;
  };
  ExpectListed(grid, with(RandomPoints(320, w, 4), RandomPoints(80, {-11, -7, 13, 12}, 44)),
               "outside");
  ExpectListed(grid, with(RandomPoints(60, w, 5), RandomPoints(15, {-1e9, -1e9, 1e9, 1e9}, 55)),
               "far");
}

TEST(PointCover, LatticeTiesCoincidentPointsAndClusters) {
  // Points on the pixel-centre lattice, at tile corners and on bucket edges: many exact
  // ties; two coincident points.
  Grid grid{{0, 0, 64, 64}, 64, 64};
  SiteTable lattice;
  for (int y = 0; y <= 64; y += 4) {
    for (int x = 0; x <= 64; x += 4) lattice.push_back({"", PointSite{{x + 0.5, y + 0.5}}});
  }
  for (int y = 0; y <= 64; y += 8) {
    for (int x = 0; x <= 64; x += 8) lattice.push_back({"", PointSite{{double(x), double(y)}}});
  }
  lattice.push_back({"", PointSite{{20.5, 20.5}}});
  ExpectListed(grid, lattice, "lattice");
  // All but three points in one bucket, far from most tiles; the window far from the origin.
  Window w{1e6, 2e6, 1e6 + 1, 2e6 + 1};
  SiteTable cluster = RandomPoints(2000, {1e6 + 0.01, 2e6 + 0.01, 1e6 + 0.02, 2e6 + 0.02}, 6);
  cluster.push_back({"", PointSite{{1e6 + 0.9, 2e6 + 0.5}}});
  cluster.push_back({"", PointSite{{1e6 + 0.5, 2e6 + 0.95}}});
  cluster.push_back({"", PointSite{{1e6 + 3, 2e6 - 2}}});
  ExpectListed({w, 90, 70}, cluster, "cluster");
}

TEST(PointCover, ScalesWhereSquaresWouldUnderOrOverflowAndMostPointsOutside) {
  // A window of 1e-160 (squared distances underflow), points 1e200 away (they overflow),
  // and a window on a small part of the scene: the index's path takes them, and lists them
  // as well.
  const Window tiny{0, 0, 1e-160, 1e-160};
  ExpectListed({tiny, 40, 30}, RandomPoints(200, tiny, 8), "tiny", false);
  SiteTable far = RandomPoints(200, {0, 0, 1, 1}, 9);
  far.push_back({"", PointSite{{1e200, -1e200}}});
  ExpectListed({{0, 0, 1, 1}, 40, 30}, far, "far", false);
  ExpectListed({{0, 0, 1, 1}, 40, 30}, RandomPoints(300, {-2, -2, 3, 3}, 10), "outside", false);
}

TEST(PointCover, OnlyForScenesOfPlainPoints) {
  const Grid grid{{0, 0, 1, 1}, 32, 32};
  SiteTable sites = RandomPoints(20, {0, 0, 1, 1}, 7);
  EXPECT_NE(PointCover::Of(grid, SlotTable(sites)), nullptr);
  sites[3].multiplicative = 2;
  EXPECT_EQ(PointCover::Of(grid, SlotTable(sites)), nullptr);
  sites[3].multiplicative = 1;
  sites[5].geometry = SegmentSite{{0.1, 0.1}, {0.2, 0.3}};
  EXPECT_EQ(PointCover::Of(grid, SlotTable(sites)), nullptr);
  EXPECT_EQ(PointCover::Of(grid, SlotTable()), nullptr);
}

TEST(SiteIndex, NearestAndWithinAgreeWithBruteForce) {
  Window w{0, 0, 10, 10};
  SiteTable sites = RandomPoints(500, w, 8);
  SlotTable slots(sites);
  SiteIndex index = SiteIndex::Build(slots);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-2, 12);
  for (int t = 0; t < 300; ++t) {
    Vec2 q{u(rng), u(rng)};
    const double truth = oracle::BestSite(q, sites).value;
    EXPECT_NEAR(index.Nearest(q).distance, truth, oracle::Tolerance(q, truth));
    std::vector<uint32_t> within;
    index.Within(q, 1.5, &within);
    for (size_t s = 0; s < sites.size(); ++s) {
      bool inside = oracle::Distance(q, sites[s].geometry) <= 1.5 * (1 - 1e-12);
      bool found = std::find(within.begin(), within.end(), s) != within.end();
      if (inside) {
        EXPECT_TRUE(found) << s;
      }
    }
  }
  // A moved site: the updated index finds it, and the index it was made from still answers
  // for the table it was made of.
  SlotTable moved = slots;
  Site m = sites[0];
  m.geometry = PointSite{{5, 5}};
  moved.Set(0, m);
  const uint32_t changed[] = {0};
  SiteIndex next = index.Update(moved, changed);
  EXPECT_EQ(next.Nearest({5, 5}).distance, 0);
  EXPECT_EQ(next.size(), 500u);
  EXPECT_NEAR(index.Nearest({5, 5}).distance, oracle::BestSite({5, 5}, sites).value, 1e-12);
  EXPECT_NE(index.Nearest({5, 5}).distance, 0);
}

}  // namespace
}  // namespace gvd
