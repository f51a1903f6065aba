// Fuzz target: bytes parsed as each request type (the first byte picks it), then the server's
// validation and scene logic. Whatever the input: no crash, and whatever is accepted keeps the
// scene consistent, with exact answers within the tolerance of the tests' oracle (tests/support/oracle.h).
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include <google/protobuf/stubs/logging.h>

#include "gvd/v1/voronoi.pb.h"
#include "server/app/convert/queries.h"
#include "server/app/convert/scenes.h"
#include "server/app/convert/sites.h"
#include "render/scene/scene.h"
#include "tests/support/oracle.h"

namespace {

void Check(bool ok) {
  if (!ok) std::abort();
}

gvd::ServerLimits Limits() {
  gvd::ServerLimits l;
  l.max_side_px = 256;
  l.max_scene_pixels = 256 * 256;
  l.max_sites_per_scene = 200;
  l.max_sites_per_request = 100;
  l.max_points_per_query = 64;
  return l;
}

// A small scene with a few sites, made fresh for each input so that a crash reproduces.
std::shared_ptr<gvd::Scene> Fixture() {
  gvd::v1::CreateSceneRequest r;
  r.set_scene_id("fuzz");
  r.mutable_window()->set_max_x(1);
  r.mutable_window()->set_max_y(1);
  r.set_width_px(16);
  r.set_height_px(16);
  gvd::SceneSettings settings;
  Check(gvd::ToSceneSettings(r, Limits(), &settings).ok());
  auto scene = std::make_shared<gvd::Scene>(settings);
  std::vector<gvd::Site> sites = {{"a", gvd::PointSite{{0.25, 0.25}}},
                                  {"b", gvd::PointSite{{0.75, 0.5}}},
                                  {"c", gvd::PointSite{{0.5, 0.9}}}};
  Check(scene->Upsert(sites, 200).ok());
  return scene;
}

}  // namespace

// Invalid UTF-8 in string fields is a refusal, not news: keep protobuf from logging each one.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const gvd::ServerLimits limits = Limits();
  const uint8_t kind = data[0] % 4;
  const void* body = data + 1;
  const int n = static_cast<int>(size - 1);
  if (kind == 0) {
    gvd::v1::CreateSceneRequest r;
    if (!r.ParseFromArray(body, n)) return 0;
    gvd::SceneSettings s;
    if (gvd::ToSceneSettings(r, limits, &s).ok()) {
      Check(s.eps > 0 && s.grid.width >= 1 && s.grid.width <= limits.max_side_px);
      Check(s.grid.window.min_x < s.grid.window.max_x && s.grid.window.min_y < s.grid.window.max_y);
      Check(s.cone_triangles >= 3);
    }
    return 0;
  }
  auto scene = Fixture();
  const uint64_t before = scene->version();
  if (kind == 1) {
    gvd::v1::UpsertSitesRequest r;
    if (!r.ParseFromArray(body, n)) return 0;
    std::vector<gvd::Site> sites;
    if (!gvd::ToSites(r, limits, &sites).ok()) return 0;
    size_t count = sites.size();
    auto v = scene->Upsert(std::move(sites), limits.max_sites_per_scene);
    if (v.ok()) {
      Check(*v == before + 1 && scene->site_count() >= 3 && scene->site_count() <= 3 + count);
    } else {
      Check(scene->version() == before && scene->site_count() == 3);  // nothing half-applied
    }
  } else if (kind == 2) {
    gvd::v1::DeleteSitesRequest r;
    if (!r.ParseFromArray(body, n)) return 0;
    std::vector<std::string> ids;
    if (!gvd::ToSiteIds(r, limits, &ids).ok()) return 0;
    auto v = scene->Delete(ids);
    Check(v.ok() ? scene->site_count() == 3 - ids.size() : scene->site_count() == 3);
  } else {
    gvd::v1::FindNearestRequest r;
    if (!r.ParseFromArray(body, n)) return 0;
    std::vector<gvd::Vec2> points;
    bool outside = false;
    if (!gvd::ToQueryPoints(r, scene->settings().grid.window, limits, &points, &outside).ok()) {
      return 0;
    }
    std::vector<gvd::Scene::ExactAnswer> answers;
    scene->NearestExact(points, &answers);
    gvd::SiteTable sites = {{"a", gvd::PointSite{{0.25, 0.25}}},
                             {"b", gvd::PointSite{{0.75, 0.5}}},
                             {"c", gvd::PointSite{{0.5, 0.9}}}};
    for (size_t i = 0; i < points.size(); ++i) {
      const double best = gvd::oracle::BestSite(points[i], sites).value;
      Check(std::abs(answers[i].distance - best) <= gvd::oracle::Tolerance(points[i], best));
    }
  }
  return 0;
}
