// Fuzz target: bytes as the store keeps a site or a scene's settings (the first byte picks
// which), through the decoders the store reads them with (render/scene/codec.h). Whatever the input:
// no crash; a refusal is DATA_LOSS; what is accepted encodes back to the very same bytes and
// keeps the contracts of Site and SceneSettings (checked here, field by field). An accepted
// site then joins a small scene as a loaded one would, and an exact query there agrees with
// the tests' oracle (tests/support/oracle.h).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "render/kernel/path2.h"
#include "render/scene/codec.h"
#include "render/scene/scene.h"
#include "tests/support/oracle.h"

namespace {

void Check(bool ok) {
  if (!ok) std::abort();
}

bool Finite(gvd::Vec2 p) { return std::isfinite(p.x) && std::isfinite(p.y); }

bool AllFinite(const std::vector<gvd::Vec2>& points) {
  for (gvd::Vec2 p : points) {
    if (!Finite(p)) return false;
  }
  return true;
}

void CheckContract(const gvd::Site& s) {
  Check(!s.id.empty());
  Check(std::isfinite(s.additive) && s.additive >= 0);
  Check(std::isfinite(s.multiplicative) && s.multiplicative > 0);
  Check(s.max_distance > 0);
  if (const auto* p = std::get_if<gvd::PointSite>(&s.geometry)) Check(Finite(p->p));
  if (const auto* g = std::get_if<gvd::SegmentSite>(&s.geometry)) Check(Finite(g->a) && Finite(g->b));
  if (const auto* g = std::get_if<gvd::PolylineSite>(&s.geometry)) {
    Check(g->points.size() >= 2 && AllFinite(g->points));
  }
  if (const auto* g = std::get_if<gvd::PolygonSite>(&s.geometry)) {
    Check(g->vertices.size() >= 3 && AllFinite(g->vertices));
  }
  if (const auto* g = std::get_if<gvd::PathSite>(&s.geometry)) {
    Check(gvd::PathContractError(g->subpaths, g->side).empty() && g->tolerance > 0);
    Check(!g->pieces.empty() && g->flat.size() >= 2 * g->pieces.size() && AllFinite(g->flat));
  }
  if (const auto* g = std::get_if<gvd::BezierSite>(&s.geometry)) {
    Check(g->control.size() == 3 || g->control.size() == 4);
    Check(AllFinite(g->control) && g->flat.size() >= 2 && AllFinite(g->flat));
    Check(std::isfinite(g->tolerance) && g->tolerance >= 0);
  }
}

gvd::SceneSettings SmallScene() {
  gvd::SceneSettings s;
  s.id = "fuzz";
  s.grid.window = {0, 0, 1, 1};
  s.grid.width = s.grid.height = 16;
  s.eps = 1.0 / 16;
  s.cone_triangles = 64;
  return s;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] % 2 == 0) {
    auto settings = gvd::DecodeSettings(bytes);
    if (!settings.ok()) {
      Check(settings.status().code() == absl::StatusCode::kDataLoss);
      return 0;
    }
    Check(gvd::EncodeSettings(*settings) == bytes);
    const gvd::Window& w = settings->grid.window;
    Check(!settings->id.empty() && settings->grid.width > 0 && settings->grid.height > 0);
    Check(std::isfinite(w.max_x - w.min_x) && w.max_x > w.min_x);
    Check(std::isfinite(w.max_y - w.min_y) && w.max_y > w.min_y);
    Check(std::isfinite(settings->eps) && settings->eps > 0 && settings->cone_triangles >= 3);
    return 0;
  }
  auto site = gvd::DecodeSite<gvd::Site>(bytes);
  if (!site.ok()) {
    Check(site.status().code() == absl::StatusCode::kDataLoss);
    return 0;
  }
  Check(gvd::EncodeSite(*site) == bytes);
  CheckContract(*site);
  // Bounded work per input: long polylines are the geometry fuzzer's business.
  if (gvd::oracle::Segments(site->geometry).size() > 64) return 0;
  gvd::Scene scene(SmallScene());
  std::vector<gvd::Site> sites = {*site};
  if (!scene.Upsert(sites, 8).ok()) return 0;
  const std::vector<gvd::Vec2> q = {{0.3, 0.7}};
  std::vector<gvd::Scene::ExactAnswer> answers;
  scene.NearestExact(q, &answers);
  const double expected = gvd::oracle::Value(q[0], *site);
  Check(answers.size() == 1);
  // The oracle's tolerance scales with the query point: compare where the site's coordinates
  // and weight are of the point's size (elsewhere: no crash is the check).
  double extent = site->multiplicative;
  for (auto [a, b] : gvd::oracle::Segments(site->geometry)) {
    extent = std::max({extent, std::abs(a.x), std::abs(a.y), std::abs(b.x), std::abs(b.y)});
  }
  if (extent > 1e3 || site->additive > 1e3) return 0;
  Check(answers[0].found == std::isfinite(expected));
  if (std::isfinite(expected)) {
    Check(std::abs(answers[0].distance - expected) <=
          gvd::oracle::Tolerance(q[0], expected, site->multiplicative) +
              gvd::oracle::CurveRounding(expected, *site));
  }
  return 0;
}
