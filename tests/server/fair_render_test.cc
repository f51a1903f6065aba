// Render threads against the real server: a scene whose render goes on and on (held by the
// test hook, so at any machine's speed) holds up only itself; every other scene's updates
// are published meanwhile, whichever thread held their GPU state before.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "gvd/client.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

uint64_t Upsert(Client& client, const std::string& scene, double x) {
  v1::UpsertSitesRequest r;
  r.set_scene_id(scene);
  v1::Site* s = r.add_sites();
  s->set_id("a");
  s->mutable_point()->set_x(x);
  s->mutable_point()->set_y(0.5);
  uint64_t version = 0;
  EXPECT_TRUE(client.UpsertSites(r, &version).ok());
  return version;
}

TEST(FairRenders, ALongRenderHoldsUpOnlyItsOwnScene) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  EXPECT_NE(server.log().find("render_threads=2"), std::string::npos) << server.log();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  for (const char* id : {"big", "small", "other"}) {
    ASSERT_TRUE(client->CreateScene(testing::UnitScene(id, 64, 64), &scene).ok());
    ASSERT_TRUE(testing::WaitForRender(*client, id, Upsert(*client, id, 0.1)));
  }
  // From here the render of "big" goes on until the file goes.
  const std::string held = server.hold_renders_path() + ".big";
  std::ofstream(held).put('x');
  const uint64_t big = Upsert(*client, "big", 0.2);
  for (int k = 0; k < 20; ++k) {
    for (const char* id : {"small", "other"}) {
      const uint64_t v = Upsert(*client, id, 0.3 + 0.01 * k);
      ASSERT_TRUE(testing::WaitForRender(*client, id, v)) << id << " version " << v << " waits for the render of big";
    }
  }
  EXPECT_LT(testing::RenderedVersion(*client, "big"), big);
  std::remove(held.c_str());
  ASSERT_TRUE(testing::WaitForRender(*client, "big", big));
  // Each scene's render cost is a metric.
  const int port = testing::MetricsPort(server.log());
  ASSERT_GT(port, 0);
  const std::string text = testing::Scrape(port);
  EXPECT_NE(text.find("gvd_scene_render_seconds_total{scene=\"big\"}"), std::string::npos) << text;
}

}  // namespace
}  // namespace gvd
