// The store on a disk that fills up, and store files that cannot be read, against the real
// server: writes refused whole with a clear status while reads go on, writes back by
// themselves once space is freed, and a clear error at start naming a bad file.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <set>
#include <thread>

#include "gvd/client.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;

v1::UpsertSitesRequest Points(const std::string& scene, int first, int n) {
  v1::UpsertSitesRequest r;
  r.set_scene_id(scene);
  for (int i = first; i < first + n; ++i) {
    v1::Site* s = r.add_sites();
    s->set_id("p" + std::to_string(i));
    s->mutable_point()->set_x((i % 997) / 997.0);
    s->mutable_point()->set_y((i % 991) / 991.0);
  }
  return r;
}

bool WaitForFile(const std::string& path) {
  for (int k = 0; k < 400; ++k) {
    if (std::ifstream(path).good()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return false;
}

std::set<std::string> Ids(Client& client, const std::string& scene) {
  std::vector<v1::Site> sites;
  EXPECT_TRUE(client.ListAllSites(scene, &sites).ok());
  std::set<std::string> ids;
  for (const v1::Site& s : sites) ids.insert(s.id());
  return ids;
}

TEST(DiskTest, AFullDiskRefusesWritesWholeAndTheyResumeOnceSpaceIsFreed) {
  char dir_template[] = "/tmp/gvd-disk-XXXXXX";
  const std::string dir = mkdtemp(dir_template);
  const std::string disk = dir + "/disk", control = dir + "/control";
  mkdir(disk.c_str(), 0700);
  mkdir(control.c_str(), 0700);
  if (std::system(("unshare -rm mount -t tmpfs -o size=1m gvd-probe " + disk + " >/dev/null 2>&1").c_str()) != 0) {
    std::system(("rm -rf " + dir).c_str());
    GTEST_SKIP() << "this machine allows no tmpfs in a user and mount namespace (unshare -rm), "
                    "so there is no small filesystem to fill";
  }
  setenv("GVD_SERVER", GVD_SERVER_PATH, 1);
  setenv("GVD_SMALL_DISK_SIZE", "16m", 1);
  setenv("GVD_SMALL_DISK_DIR", disk.c_str(), 1);
  setenv("GVD_SMALL_DISK_CONTROL", control.c_str(), 1);
  {
    testing::ServerProcess server(GVD_SMALL_DISK_SCRIPT, {"--data", disk + "/data"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    v1::Scene scene;
    ASSERT_TRUE(client->CreateScene(testing::UnitScene("d", 64, 64), &scene).ok());
    uint64_t version = 0;
    ASSERT_TRUE(client->UpsertSites(Points("d", 0, 500), &version).ok());
    std::set<std::string> acked = Ids(*client, "d");

    std::ofstream(control + "/fill");
    ASSERT_TRUE(WaitForFile(control + "/filled"));
    // Writes go on until the store's free pages are used up, then are refused whole.
    grpc::Status refused;
    int next = 500;
    for (int k = 0; k < 200 && refused.ok(); ++k, next += 500) {
      uint64_t v = 0;
      refused = client->UpsertSites(Points("d", next, 500), &v);
      if (refused.ok()) {
        version = v;
        for (int i = next; i < next + 500; ++i) acked.insert("p" + std::to_string(i));
      }
    }
    ASSERT_FALSE(refused.ok()) << "the disk never filled";
    EXPECT_EQ(refused.error_code(), StatusCode::RESOURCE_EXHAUSTED) << refused.error_message();
    EXPECT_NE(refused.error_message().find("disk is full"), std::string::npos) << refused.error_message();
    EXPECT_NE(refused.error_message().find(disk + "/data/gvd.sqlite3"), std::string::npos)
        << refused.error_message();
    // Nothing of the refused write, everything acknowledged; reads answer.
    ASSERT_TRUE(client->GetScene("d", &scene).ok());
    EXPECT_EQ(scene.version(), version);
    EXPECT_EQ(Ids(*client, "d"), acked);
    v1::FindNearestRequest q;
    q.set_scene_id("d");
    q.set_min_version(version);
    q.add_points()->set_x(0.25);
    v1::FindNearestResponse answer;
    ASSERT_TRUE(client->FindNearest(q, &answer).ok());
    EXPECT_FALSE(answer.results(0).site_id().empty());
    auto create = client->CreateScene(testing::UnitScene("e", 64, 64), &scene);
    EXPECT_EQ(create.error_code(), StatusCode::RESOURCE_EXHAUSTED) << create.error_message();
    std::vector<v1::Scene> scenes;
    ASSERT_TRUE(client->ListScenes(&scenes).ok());
    EXPECT_EQ(scenes.size(), 1u);

    // Space freed: the next write succeeds, with no restart.
    std::ofstream(control + "/free");
    ASSERT_TRUE(WaitForFile(control + "/freed"));
    uint64_t after = 0;
    auto st = client->UpsertSites(Points("d", next, 500), &after);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(after, version + 1);
    for (int i = next; i < next + 500; ++i) acked.insert("p" + std::to_string(i));
    EXPECT_EQ(Ids(*client, "d"), acked);
    ASSERT_TRUE(client->CreateScene(testing::UnitScene("e", 64, 64), &scene).ok());
  }
  std::system(("rm -rf " + dir).c_str());
}

// A store file that is damaged, or from a newer release: the server says so at start, naming
// the file, and exits; it never starts empty.
TEST(DiskTest, ABadStoreFileStopsTheStartByName) {
  char dir_template[] = "/tmp/gvd-badstore-XXXXXX";
  const std::string dir = mkdtemp(dir_template);
  const std::string data = dir + "/data";
  mkdir(data.c_str(), 0700);
  std::ofstream(data + "/gvd.sqlite3") << std::string(8192, 'x');
  testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data});
  EXPECT_NE(server.error().find("gvd-server exited at start"), std::string::npos) << server.error();
  EXPECT_NE(server.log().find("event=store_failed"), std::string::npos) << server.log();
  EXPECT_NE(server.log().find("DATA_LOSS: store " + data + "/gvd.sqlite3"), std::string::npos)
      << server.log();
  std::system(("rm -rf " + dir).c_str());
}

}  // namespace
}  // namespace gvd
