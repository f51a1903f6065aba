// Render threads against the real server: a scene whose render goes on and on (held by the
// test hook, so at any machine's speed) holds up only itself; every other scene's updates
// are published meanwhile, whichever thread held their GPU state before. And the two render
// threads rendering at once, each move read at its version, without a crash.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

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

// A render thread keeps the GPU state of the scenes it rendered, and the other thread takes
// one over only while that thread is busy. Here one thread holds the state of both "big" and
// "small" (the other was held in the render of "blocker" while they were made), and both are
// queued while renders are held; then that thread goes into the long render of "big". The
// other thread must take "small" although nothing was queued after "big" was taken.
TEST(FairRenders, TheOtherThreadTakesOverTheScenesOfOneInALongRender) {
  testing::ServerProcess server(GVD_SERVER_PATH, {});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ASSERT_NE(server.log().find("render_threads=2"), std::string::npos) << server.log();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("blocker", 64, 64), &scene).ok());
  const std::string blocker = server.hold_renders_path() + ".blocker";
  std::ofstream(blocker).put('x');
  const uint64_t blocked = Upsert(*client, "blocker", 0.1);
  ASSERT_TRUE(testing::WaitForHeldRender(server, "blocker")) << "the render of blocker never began";
  for (const char* id : {"big", "small"}) {
    ASSERT_TRUE(client->CreateScene(testing::UnitScene(id, 64, 64), &scene).ok());
    ASSERT_TRUE(testing::WaitForRender(*client, id, Upsert(*client, id, 0.1)));
  }
  std::remove(blocker.c_str());
  ASSERT_TRUE(testing::WaitForRender(*client, "blocker", blocked));
  // Both queued before either is taken; then the render of "big" goes on until its file goes.
  const std::string held = server.hold_renders_path() + ".big";
  std::ofstream(held).put('x');
  uint64_t small = 0;
  {
    testing::HoldRenders hold(server);
    Upsert(*client, "big", 0.2);
    small = Upsert(*client, "small", 0.3);
  }
  ASSERT_TRUE(testing::WaitForHeldRender(server, "big")) << "the render of big never began";
  EXPECT_TRUE(testing::WaitForRender(*client, "small", small))
      << "small waits for the render of big on the thread that rendered it before";
  std::remove(held.c_str());
}

// The two render threads, each with a GL context of its own, render scenes at once. On
// Mesa's software device both contexts share one screen, and a context's flush of a resource
// (before glBufferData, glReadPixels) reads the queued work of the other context while the
// other's thread frees it: the server crashed in lp_scene_is_resource_referenced unless the
// threads take turns at GL (GlTurn). glibc's malloc.perturb fills freed memory with junk, so
// that such a read crashes instead of now and then reading stale memory that is still mapped.
// Every move is read at its version and must be seen; the server must stop cleanly after.
TEST(FairRenders, TwoRenderThreadsRenderAtOnce) {
  setenv("GLIBC_TUNABLES", "glibc.malloc.perturb=165", 1);
  testing::ServerProcess server(GVD_SERVER_PATH, {"--data", ":memory:"});
  unsetenv("GLIBC_TUNABLES");
  ASSERT_TRUE(server.error().empty()) << server.error();
  ASSERT_NE(server.log().find("render_threads=2"), std::string::npos) << server.log();
  constexpr int kScenes = 6, kSites = 400, kMoves = 3000;
  std::mutex mu;
  std::vector<std::string> failures;  // guarded by mu
  auto fail = [&](std::string what) {
    std::lock_guard<std::mutex> lock(mu);
    failures.push_back(std::move(what));
  };
  std::vector<std::thread> movers;
  for (int k = 0; k < kScenes; ++k) {
    movers.emplace_back([&, k] {
      const std::string id = "s" + std::to_string(k);
      auto client = Client::Connect(server.address());
      v1::Scene scene;
      uint64_t version = 0;
      if (!client->CreateScene(testing::UnitScene(id, 128, 128), &scene).ok() ||
          !client->UpsertSites(testing::RandomPoints(id, kSites, k), &version).ok()) {
        return fail(id + ": the scene could not be made");
      }
      std::mt19937_64 rng(100 + k);
      std::uniform_real_distribution<double> unit(0, 1);
      std::uniform_int_distribution<int> site(0, kSites - 1);
      for (int m = 0; m < kMoves; ++m) {
        v1::UpsertSitesRequest move;
        move.set_scene_id(id);
        v1::Site* s = move.add_sites();
        s->set_id(std::to_string(site(rng)));
        const double x = unit(rng), y = unit(rng);
        s->mutable_point()->set_x(x);
        s->mutable_point()->set_y(y);
        if (auto st = client->UpsertSites(move, &version); !st.ok()) {
          return fail(id + " move " + std::to_string(m) + ": " + st.error_message());
        }
        v1::FindNearestRequest read;
        read.set_scene_id(id);
        read.set_min_version(version);
        v1::Point* p = read.add_points();
        p->set_x(x);
        p->set_y(y);
        v1::FindNearestResponse answer;
        if (auto st = client->FindNearest(read, &answer); !st.ok()) {
          return fail(id + " read " + std::to_string(m) + ": " + st.error_message());
        }
        // The moved site is at distance 0 from the point: the answer is within its bound of it.
        if (answer.results(0).distance() > answer.results(0).error_bound()) {
          return fail(id + " move " + std::to_string(m) + " unseen at version " +
                      std::to_string(version));
        }
      }
    });
  }
  for (auto& t : movers) t.join();
  EXPECT_TRUE(failures.empty()) << failures.front() << "\n" << server.log();
}

}  // namespace
}  // namespace gvd
