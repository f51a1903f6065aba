// Writes the seed corpus: a few valid and invalid requests of each kind (the first byte picks
// the kind, as in fuzz_requests.cc), some geometry inputs, and the store's byte form of a scene's
// settings and of a site of each kind (as in fuzz_store.cc). Usage: make_seeds CORPUS_DIR
#include <cmath>
#include <fstream>
#include <string>

#include "render/kernel/path2.h"
#include "render/scene/codec.h"
#include "gvd/v1/voronoi.pb.h"

namespace {

void Write(const std::string& path, char kind, const google::protobuf::Message& m) {
  std::ofstream(path, std::ios::binary) << kind << m.SerializeAsString();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const std::string dir = argv[1];
  gvd::v1::CreateSceneRequest c;
  c.set_scene_id("seed");
  c.mutable_window()->set_max_x(1);
  c.mutable_window()->set_max_y(1);
  c.set_width_px(64);
  c.set_height_px(48);
  Write(dir + "/requests/create-valid", 0, c);
  c.mutable_window()->set_min_x(NAN);
  c.set_max_error(-1);
  Write(dir + "/requests/create-invalid", 0, c);

  gvd::v1::UpsertSitesRequest u;
  u.set_scene_id("fuzz");
  for (int i = 0; i < 4; ++i) {
    auto* s = u.add_sites();
    s->set_id("s" + std::to_string(i));
    s->mutable_point()->set_x(0.1 * i);
    s->mutable_point()->set_y(0.2 * i);
  }
  Write(dir + "/requests/upsert-valid", 1, u);
  u.mutable_sites(2)->set_id("s0");
  Write(dir + "/requests/upsert-duplicate", 1, u);

  gvd::v1::DeleteSitesRequest d;
  d.set_scene_id("fuzz");
  d.add_ids("a");
  d.add_ids("c");
  Write(dir + "/requests/delete-valid", 2, d);
  d.add_ids("ghost");
  Write(dir + "/requests/delete-unknown", 2, d);

  gvd::v1::FindNearestRequest q;
  q.set_scene_id("fuzz");
  for (double x : {0.0, 0.5, 1.0, -3.0, 7.5}) {
    auto* p = q.add_points();
    p->set_x(x);
    p->set_y(1 - x);
  }
  Write(dir + "/requests/nearest-points", 3, q);
  q.clear_points();
  for (double v : {0.1, 0.2, 0.3, 0.4, 2.0, -1.0}) q.add_xy(v);
  q.set_exact(true);
  Write(dir + "/requests/nearest-xy", 3, q);

  for (int s = 0; s < 4; ++s) {
    std::ofstream out(dir + "/geometry/seed-" + std::to_string(s), std::ios::binary);
    for (int i = 0; i < 64; ++i) out << static_cast<char>((i * 37 + s * 101) & 0xff);
  }

  gvd::SceneSettings settings;
  settings.id = "seed";
  settings.grid.window = {-1, 0, 3, 2};
  settings.grid.width = 64;
  settings.grid.height = 32;
  settings.eps = 0.05;
  settings.cone_triangles = 40;
  std::ofstream(dir + "/store/settings", std::ios::binary) << '\0' << gvd::EncodeSettings(settings);
  gvd::BezierSite bezier{{{0, 0}, {0.5, 1}, {1, 0}}, 0.01, {{0, 0}, {0.25, 0.375}, {0.5, 0.5}, {0.75, 0.375}, {1, 0}}};
  // A circle of four cubics, as an SVG reader writes one, with its stated distance from the
  // true circle.
  gvd::PathSite circle = gvd::MakePath(
      {{{{0.75, 0.5}, {0.75, 0.638}, {0.638, 0.75}, {0.5, 0.75}, {0.362, 0.75}, {0.25, 0.638}, {0.25, 0.5},
         {0.25, 0.362}, {0.362, 0.25}, {0.5, 0.25}, {0.638, 0.25}, {0.75, 0.362}, {0.75, 0.5}},
        {3, 3, 3, 3}, true}},
      gvd::FillRule::kNonZero, gvd::Side::kBoth, 0.001);
  circle.approximation = 1e-4;
  const std::vector<gvd::Site> sites = {
      {"point", gvd::PointSite{{0.25, 0.5}}},
      {"segment", gvd::SegmentSite{{0.1, 0.1}, {0.9, 0.4}}},
      {"polyline", gvd::PolylineSite{{{0, 0}, {0.5, 0.5}, {0.2, 0.9}}}},
      {"polygon", gvd::PolygonSite{{{0.2, 0.2}, {0.8, 0.2}, {0.5, 0.8}}, gvd::Side::kInside}},
      {"bezier", bezier},
      {"path", gvd::MakePath({{{{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.5, 1}, {0.1, 0.9}}, {1, 1, 2}, true},
                              {{{0.4, 0.4}, {0.6, 0.5}, {0.7, 0.6}, {0.5, 0.7}}, {3}, false}},
                             gvd::FillRule::kEvenOdd, gvd::Side::kBoth, 0.01)},
      {"circle", circle}};
  for (gvd::Site site : sites) {
    site.additive = site.id == "segment" ? 0.25 : 0;
    site.multiplicative = site.id == "polyline" ? 2 : 1;
    std::ofstream(dir + "/store/site-" + site.id, std::ios::binary) << '\1' << gvd::EncodeSite(site);
  }
  return 0;
}
