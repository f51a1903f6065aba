// Fuzz target: the cone counts of sec. 4.1.1, the coverage proof of render/plan/coverage.h and the
// structure of id images (analysis/analysis.h), on small scenes made from the bytes. Checks
// the properties themselves, against the oracle.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <numbers>

#include "render/analysis/analysis.h"
#include "render/plan/coverage.h"
#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "tests/support/oracle.h"

namespace {

void Check(bool ok) {
  if (!ok) std::abort();
}

struct Reader {
  const uint8_t* p;
  size_t n;
  uint16_t U16() {
    uint16_t v = 0;
    if (n >= 2) {
      std::memcpy(&v, p, 2);
      p += 2;
      n -= 2;
    }
    return v;
  }
  double Unit() { return U16() / 65535.0; }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Reader in{data, size};
  // Cone counts: radius and eps over many orders of magnitude.
  double radius = std::ldexp(1 + in.Unit(), static_cast<int>(in.U16() % 80) - 40);
  double eps = std::ldexp(1 + in.Unit(), static_cast<int>(in.U16() % 80) - 40);
  uint32_t segments = gvd::ConeSegments(radius, eps);
  Check(segments >= 3 && segments <= gvd::kMaxConeSegments);
  if (segments < gvd::kMaxConeSegments) {
    Check(radius - radius * std::cos(std::numbers::pi / segments) <= eps * (1 + 1e-9));
  }

  // Coverage: up to 12 sites in and around the unit square, a small grid, any tile size.
  gvd::SlotTable sites;
  uint32_t count = 1 + in.U16() % 12;
  gvd::SiteTable table;
  for (uint32_t i = 0; i < count; ++i) {
    gvd::Site s{std::to_string(i), gvd::PointSite{{in.Unit() * 2 - 0.5, in.Unit() * 2 - 0.5}}};
    sites.Set(i, s);
    table.push_back(s);
  }
  gvd::Grid grid{{0, 0, 1, 1}, 1 + in.U16() % 24u, 1 + in.U16() % 24u};
  uint32_t tile = in.U16() % 9;
  gvd::SiteIndex index = gvd::SiteIndex::Build(sites);
  for (gvd::Diagram diagram : {gvd::Diagram::kNearest, gvd::Diagram::kFarthest}) {
    gvd::Coverage cov = gvd::ComputeCoverage(grid, sites, index, grid.all(), tile, diagram);
    for (uint32_t j = 0; j < grid.height; ++j) {
      for (uint32_t i = 0; i < grid.width; ++i) {
        // Every site that is best at a pixel centre (ties within the oracle's tolerance
        // included) is drawn at least that far.
        gvd::Vec2 p = grid.Center(i, j);
        const double best = gvd::oracle::BestSite(p, table, diagram).value;
        const double tolerance = gvd::oracle::Tolerance(p, best);
        for (uint32_t s = 0; s < count; ++s) {
          const double d = gvd::oracle::Distance(p, table[s].geometry);
          if (std::abs(d - best) > tolerance) continue;
          Check(d <= cov.radius[s] + tolerance);
          if (d == best) {  // ties within the tolerance may fall to either side of a clip
            const gvd::PixelRect& c = cov.clip[s];
            Check(i >= c.x0 && i < c.x1 && j >= c.y0 && j < c.y1);
          }
        }
      }
    }
    // The sparse form of the proof gives the same radii.
    auto sparse = gvd::SparseCoverage(grid, sites, index, grid.all(),
                                      tile ? tile : gvd::DefaultTilePx(grid, count), diagram);
    size_t drawn = 0;
    for (uint32_t s = 0; s < count; ++s) drawn += cov.radius[s] >= 0;
    Check(sparse.size() == drawn);
    for (const gvd::SiteDraw& d : sparse) {
      Check(d.radius == cov.radius[d.slot] && d.clip == cov.clip[d.slot]);
    }
  }

  // Structure of an id image: the oracle's labels, a few of them changed by the input.
  gvd::IdImage image{grid, std::vector<uint32_t>(grid.pixel_count())};
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      auto n = gvd::oracle::BestSite(grid.Center(i, j), table);
      image.ids[size_t{j} * grid.width + i] = static_cast<uint32_t>(n.index) + 1;
    }
  }
  for (uint32_t flips = in.U16() % 8; flips > 0; --flips) {
    image.ids[in.U16() % image.ids.size()] = in.U16() % (count + 1);  // 0: no site
  }
  auto full = gvd::FindBoundaryEdges(image, gvd::BoundaryMethod::kFullScan);
  auto walk = gvd::FindBoundaryEdges(image, gvd::BoundaryMethod::kContinuation);
  for (size_t k = 0; k < full.horizontal.size(); ++k) Check(walk.horizontal[k] <= full.horizontal[k]);
  for (size_t k = 0; k < full.vertical.size(); ++k) Check(walk.vertical[k] <= full.vertical[k]);
  Check(walk.count <= full.count);
  for (const auto& line : gvd::TraceBoundaries(image, full, sites, gvd::Diagram::kNearest)) {
    Check(!line.points.empty() && line.a < line.b && line.b <= count);
    for (gvd::Vec2 p : line.points) Check(std::isfinite(p.x) && std::isfinite(p.y));
  }
  auto pairs = gvd::NeighborPairs(image, full);
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (const auto& [pair, n] : pairs) {
    Check(pair.first < pair.second && pair.second <= count && n > 0);
    edges.push_back({pair.first - 1, pair.second - 1});
  }
  for (uint32_t s : gvd::HiddenSites(image, sites)) {
    for (uint32_t id : image.ids) Check(id != s + 1);
  }
  std::vector<gvd::Vec2> points;
  for (const auto& site : table) points.push_back(std::get<gvd::PointSite>(site.geometry).p);
  for (const auto& t : gvd::TrianglesFromEdges(points, edges)) {
    gvd::Vec2 a = points[t[0]], b = points[t[1]], c = points[t[2]];
    Check((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x) > 0);
  }
  return 0;
}
