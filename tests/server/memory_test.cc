// The memory budget (--max-memory) against the real server: scenes and sites past it are
// refused by name before anything is stored, GetScene and the metrics report what scenes
// hold, and a store larger than the budget starts with the scenes that fit.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

#include "gvd/client.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;
using testing::UnitScene;

// A scene's raster is charged 24 bytes a pixel (the API's documented figure).
constexpr uint64_t kPerPixel = 24;
constexpr uint64_t kMiB = 1 << 20;

v1::UpsertSitesRequest Points(const std::string& scene, int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  v1::UpsertSitesRequest r;
  r.set_scene_id(scene);
  for (int i = 0; i < n; ++i) {
    v1::Site* s = r.add_sites();
    s->set_id("p" + std::to_string(i));
    s->mutable_point()->set_x(u(rng));
    s->mutable_point()->set_y(u(rng));
  }
  return r;
}

uint64_t Memory(Client& client, const std::string& scene) {
  v1::Scene s;
  EXPECT_TRUE(client.GetScene(scene, &s).ok());
  return s.memory_bytes();
}

TEST(MemoryBudget, ScenesAndSitesPastTheBudgetAreRefusedByName) {
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--max-memory", "150M", "--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  EXPECT_NE(server.log().find("event=memory_budget max_memory=157286400"), std::string::npos)
      << server.log();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(UnitScene("a", 2048, 2048), &scene).ok());
  EXPECT_EQ(scene.memory_bytes(), 2048 * 2048 * kPerPixel);

  // 96 MiB more would pass 150 MiB: refused, naming the flag and the scene, nothing stored.
  auto refused = client->CreateScene(UnitScene("b", 2048, 2048), &scene);
  EXPECT_EQ(refused.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(refused.error_message().find("--max-memory"), std::string::npos) << refused.error_message();
  EXPECT_NE(refused.error_message().find("scene \"b\""), std::string::npos) << refused.error_message();
  std::vector<v1::Scene> scenes;
  ASSERT_TRUE(client->ListScenes(&scenes).ok());
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_EQ(scenes[0].scene_id(), "a");
  // A smaller one fits.
  ASSERT_TRUE(client->CreateScene(UnitScene("c", 1024, 1024), &scene).ok());

  // Sites: 150 MiB - 120 MiB leaves 30 MiB. Each point takes over 150 bytes (its Site, id,
  // slot, index and id-map entries) and under 1,000: 30,000 fit, 100,000 more do not.
  uint64_t version = 0;
  auto st = client->UpsertSites(Points("c", 30000, 1), &version);
  ASSERT_TRUE(st.ok()) << st.error_message();
  auto more = Points("c", 100000, 2);
  for (auto& s : *more.mutable_sites()) s.set_id("q" + s.id());
  refused = client->UpsertSites(more, &version);
  EXPECT_EQ(refused.error_code(), StatusCode::RESOURCE_EXHAUSTED) << refused.error_message();
  EXPECT_NE(refused.error_message().find("--max-memory"), std::string::npos) << refused.error_message();
  EXPECT_NE(refused.error_message().find("100000 sites for scene \"c\""), std::string::npos)
      << refused.error_message();
  ASSERT_TRUE(client->GetScene("c", &scene).ok());
  EXPECT_EQ(scene.site_count(), 30000u);
  EXPECT_EQ(scene.version(), version);
  const uint64_t with_sites = scene.memory_bytes();
  EXPECT_GT(with_sites, 1024 * 1024 * kPerPixel + 30000 * 150);
  EXPECT_LT(with_sites, 1024 * 1024 * kPerPixel + 30000 * 1000);

  // Replacing sites by others of the same size changes nothing; deleting them gives their
  // bytes back.
  ASSERT_TRUE(client->UpsertSites(Points("c", 30000, 3), &version).ok());
  EXPECT_EQ(Memory(*client, "c"), with_sites);
  std::vector<std::string> ids;
  for (int i = 0; i < 30000; ++i) ids.push_back("p" + std::to_string(i));
  ASSERT_TRUE(client->DeleteSites("c", ids, &version).ok());
  EXPECT_EQ(Memory(*client, "c"), 1024 * 1024 * kPerPixel);

  // The metrics: the budget, each scene's bytes and their total.
  const int port = testing::MetricsPort(server.log());
  ASSERT_GT(port, 0);
  const std::string text = testing::Scrape(port);
  EXPECT_NE(text.find("gvd_memory_limit_bytes 157286400"), std::string::npos) << text;
  EXPECT_NE(text.find("gvd_memory_bytes " + std::to_string((2048 * 2048 + 1024 * 1024) * kPerPixel)),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("gvd_scene_memory_bytes{scene=\"a\"} " + std::to_string(2048 * 2048 * kPerPixel)),
            std::string::npos)
      << text;

  // Deleting a scene frees its raster for another.
  ASSERT_TRUE(client->DeleteScene("a").ok());
  ASSERT_TRUE(client->CreateScene(UnitScene("b", 2048, 2048), &scene).ok());
}

TEST(MemoryBudget, AStoreLargerThanTheBudgetServesWhatFits) {
  char dir_template[] = "/tmp/gvd-memory-XXXXXX";
  const std::string data = std::string(mkdtemp(dir_template)) + "/store";
  {
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data, "--max-memory", "1G"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    v1::Scene scene;
    uint64_t version;
    for (auto [id, side] : {std::pair{"a", 2048}, {"b", 1024}, {"c", 2048}}) {
      ASSERT_TRUE(client->CreateScene(UnitScene(id, side, side), &scene).ok());
      ASSERT_TRUE(client->UpsertSites(Points(id, 10, 4), &version).ok());
    }
  }
  {
    // 130 MiB: a (96 MiB) and b (24 MiB) load, in id order; c would pass the budget.
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data, "--max-memory", "130M"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    EXPECT_NE(server.log().find("event=scene_unavailable scene=c"), std::string::npos) << server.log();
    auto client = Client::Connect(server.address());
    std::vector<v1::Scene> scenes;
    ASSERT_TRUE(client->ListScenes(&scenes).ok());
    ASSERT_EQ(scenes.size(), 3u);
    EXPECT_EQ(scenes[0].unavailable(), "");
    EXPECT_EQ(scenes[1].unavailable(), "");
    EXPECT_EQ(scenes[2].scene_id(), "c");
    EXPECT_NE(scenes[2].unavailable().find("--max-memory"), std::string::npos) << scenes[2].unavailable();
    EXPECT_EQ(scenes[2].site_count(), 10u);
    v1::Scene c;
    auto got = client->GetScene("c", &c);
    ASSERT_TRUE(got.ok()) << got.error_message();
    EXPECT_EQ(c.unavailable(), scenes[2].unavailable());
    EXPECT_EQ(c.width_px(), 2048u);
    // Every other call on it says why; it cannot be created again; it can be deleted.
    v1::FindNearestRequest q;
    q.set_scene_id("c");
    q.add_points()->set_x(0.5);
    v1::FindNearestResponse answer;
    auto st = client->FindNearest(q, &answer);
    EXPECT_EQ(st.error_code(), StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(st.error_message().find("--max-memory"), std::string::npos) << st.error_message();
    uint64_t version;
    EXPECT_EQ(client->UpsertSites(Points("c", 1, 5), &version).error_code(), StatusCode::FAILED_PRECONDITION);
    EXPECT_EQ(client->CreateScene(UnitScene("c", 8, 8), &c).error_code(), StatusCode::ALREADY_EXISTS);
    // The loaded scenes answer.
    q.set_scene_id("b");
    ASSERT_TRUE(client->FindNearest(q, &answer).ok());
    ASSERT_TRUE(client->DeleteScene("c").ok());
    ASSERT_TRUE(client->ListScenes(&scenes).ok());
    EXPECT_EQ(scenes.size(), 2u);
  }
  {
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data, "--max-memory", "1G"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    std::vector<v1::Scene> scenes;
    ASSERT_TRUE(client->ListScenes(&scenes).ok());
    ASSERT_EQ(scenes.size(), 2u);  // c's deletion is durable
    EXPECT_EQ(scenes[1].site_count(), 10u);
  }
  std::system(("rm -rf " + data.substr(0, data.rfind('/'))).c_str());
}

#ifdef GVD_TCMALLOC
// The server's heap (tcmalloc's page heap, server/huge_pages.cc) grows in transparent huge
// pages where the kernel gives them on request: a load of 50,000 points leaves some of the
// server's anonymous memory in huge pages. Nothing else in the server asks for them, so with
// the kernel's "madvise" setting none would be there without it.
TEST(Allocator, TheHeapGrowsInHugePages) {
  std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string modes((std::istreambuf_iterator<char>(mode)), std::istreambuf_iterator<char>());
  if (modes.empty() || modes.find("[never]") != std::string::npos) {
    GTEST_SKIP() << "the kernel gives no transparent huge pages: \"" << modes << "\"";
  }
  testing::ServerProcess server(GVD_SERVER_PATH);
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(UnitScene("s", 1024, 1024), &scene).ok());
  uint64_t v = 0;
  ASSERT_TRUE(client->UpsertSites(Points("s", 50000, 3), &v).ok());
  ASSERT_TRUE(testing::WaitForRender(*client, "s", v));
  std::ifstream rollup("/proc/" + std::to_string(server.pid()) + "/smaps_rollup");
  std::string line;
  uint64_t huge_kib = 0;
  bool found = false;
  while (std::getline(rollup, line)) {
    if (line.rfind("AnonHugePages:", 0) == 0) {
      huge_kib = std::stoull(line.substr(line.find_first_of("0123456789")));
      found = true;
    }
  }
  ASSERT_TRUE(found) << "no AnonHugePages line in /proc/PID/smaps_rollup";
  EXPECT_GE(huge_kib, 2048u);
}
#endif

}  // namespace
}  // namespace gvd
