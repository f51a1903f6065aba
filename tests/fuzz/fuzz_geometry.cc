// Fuzz target: the cone counts of sec. 4.1.1 and the coverage proof of render/coverage.h, on
// small scenes made from the bytes. Checks the properties themselves, against the oracle.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <numbers>

#include "render/coverage.h"
#include "render/exact.h"
#include "render/mesh.h"

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
  gvd::Coverage cov = gvd::ComputeCoverage(grid, sites, index, grid.all(), tile);
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      gvd::Vec2 p = grid.Center(i, j);
      double best = gvd::NearestBruteForce(p, table).distance;
      for (uint32_t s = 0; s < count; ++s) {
        if (gvd::ExactDistance(p, table[s].geometry) == best) Check(best <= cov.radius[s]);
      }
    }
  }
  return 0;
}
