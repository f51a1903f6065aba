// nearest TARGET X Y: puts three point sites into a new scene of the server at TARGET and
// prints the id of the site nearest to (X, Y) and its distance, certified exact.
#include <cstdio>
#include <cstdlib>

#include "gvd/client.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: nearest TARGET X Y\n");
    return 2;
  }
  auto client = gvd::Client::Connect(argv[1]);
  gvd::v1::CreateSceneRequest create;
  create.set_scene_id("package");
  create.mutable_window()->set_max_x(100);
  create.mutable_window()->set_max_y(100);
  create.set_width_px(64);
  create.set_height_px(64);
  gvd::v1::Scene scene;
  grpc::Status status = client->CreateScene(create, &scene);
  gvd::v1::UpsertSitesRequest upsert;
  upsert.set_scene_id("package");
  const struct { const char* id; double x, y; } points[] = {{"a", 10, 10}, {"b", 80, 20}, {"c", 50, 90}};
  for (const auto& p : points) {
    gvd::v1::Site* site = upsert.add_sites();
    site->set_id(p.id);
    site->mutable_point()->set_x(p.x);
    site->mutable_point()->set_y(p.y);
  }
  uint64_t version = 0;
  if (status.ok()) status = client->UpsertSites(upsert, &version);
  gvd::v1::FindNearestRequest find;
  find.set_scene_id("package");
  find.set_exact(true);
  find.set_min_version(version);
  gvd::v1::Point* q = find.add_points();
  q->set_x(std::atof(argv[2]));
  q->set_y(std::atof(argv[3]));
  gvd::v1::FindNearestResponse answer;
  if (status.ok()) status = client->FindNearest(find, &answer);
  if (!status.ok()) {
    std::fprintf(stderr, "nearest: %s\n", status.error_message().c_str());
    return 1;
  }
  std::printf("%s %.17g\n", answer.results(0).site_id().c_str(), answer.results(0).distance());
  return 0;
}
