// WatchScene against a real gvd-server: events follow every published frame, the changed
// windows cover every pixel whose best site changed (by the oracle, between the versions of
// consecutive events), deletion ends the stream, hundreds of watchers keep up, and the drain
// ends the streams. A watch on one replica follows the writes made through another.
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <random>
#include <functional>
#include <thread>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "gvd/client.h"
#include "tests/support/postgres.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;

// A watch on its own thread, collecting events until its stream ends (or it is destroyed:
// then the call is cancelled).
class Watcher {
 public:
  Watcher(const std::string& address, const std::string& scene, uint64_t after = 0)
      : stub_(v1::VoronoiService::NewStub(
            grpc::CreateChannel(address, grpc::InsecureChannelCredentials()))) {
    v1::WatchSceneRequest r;
    r.set_scene_id(scene);
    r.set_after_version(after);
    thread_ = std::thread([this, r] {
      auto reader = stub_->WatchScene(&ctx_, r);
      v1::WatchSceneResponse e;
      while (reader->Read(&e)) {
        std::lock_guard<std::mutex> lock(mu_);
        events_.push_back(e);
        cv_.notify_all();
      }
      grpc::Status s = reader->Finish();
      std::lock_guard<std::mutex> lock(mu_);
      status_ = s;
      ended_ = true;
      cv_.notify_all();
    });
  }
  ~Watcher() {
    ctx_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }
  // Waits (up to a minute) for an event of at least `version`, or for the deletion.
  bool WaitFor(uint64_t version) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, std::chrono::seconds(60), [&] {
      return ended_ || (!events_.empty() && (events_.back().version() >= version ||
                                             events_.back().deleted()));
    });
  }
  // Waits for the stream to end; its status.
  grpc::Status WaitEnd() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait_for(lock, std::chrono::seconds(60), [&] { return ended_; });
    return ended_ ? status_ : grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "still open");
  }
  std::vector<v1::WatchSceneResponse> events() {
    std::lock_guard<std::mutex> lock(mu_);
    return events_;
  }

 private:
  std::unique_ptr<v1::VoronoiService::Stub> stub_;
  grpc::ClientContext ctx_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<v1::WatchSceneResponse> events_;
  grpc::Status status_;
  bool ended_ = false;
};

// The events of a stream, against the sites at each version (`at`): versions in order, the
// last `last`, each with its version's site count; the first covers the whole window, and
// each later one every pixel centre whose nearest site (by the oracle) differs between its
// version and the previous event's.
void ExpectEventsCoverChanges(const std::vector<v1::WatchSceneResponse>& events,
                              std::map<uint64_t, SiteTable>& at, uint64_t last, const Grid& grid,
                              const std::string& scene) {
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().version(), last);
  uint64_t before = 0;
  for (const auto& e : events) {
    SCOPED_TRACE(::testing::Message() << "event of version " << e.version());
    EXPECT_EQ(e.scene_id(), scene);
    EXPECT_FALSE(e.deleted());
    ASSERT_GT(e.version(), before);
    ASSERT_TRUE(at.count(e.version()));
    EXPECT_EQ(e.site_count(), at[e.version()].size());
    if (before == 0) {  // the first event: the whole window
      ASSERT_TRUE(e.has_changed());
      EXPECT_LE(e.changed().min_x(), grid.window.min_x);
      EXPECT_GE(e.changed().max_x(), grid.window.max_x);
      before = e.version();
      continue;
    }
    const SiteTable& a = at[before];
    const SiteTable& b = at[e.version()];
    for (uint32_t j = 0; j < grid.height; ++j) {
      for (uint32_t i = 0; i < grid.width; ++i) {
        const Vec2 p = grid.Center(i, j);
        const auto x = oracle::BestSite(p, a), y = oracle::BestSite(p, b);
        const bool same = x.found == y.found &&
                          (!x.found || (a[x.index].id == b[y.index].id && x.value == y.value));
        if (same) continue;
        ASSERT_TRUE(e.has_changed()) << "pixel " << i << "," << j << " changed";
        const auto& c = e.changed();
        ASSERT_TRUE(c.min_x() <= p.x && p.x <= c.max_x() && c.min_y() <= p.y && p.y <= c.max_y())
            << "pixel " << i << "," << j << " changed outside [" << c.min_x() << ", "
            << c.max_x() << "] x [" << c.min_y() << ", " << c.max_y() << "]";
      }
    }
    before = e.version();
  }
}

// Random adds, moves and deletes of points in the scene, recording the sites at each
// version; returns the last version.
uint64_t RandomChanges(const std::string& scene, int steps, uint64_t seed, SiteTable* sites,
                       std::map<uint64_t, SiteTable>* at, Client* client,
                       const std::function<void(uint64_t)>& after_each = nullptr) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  uint64_t version = 0;
  for (int step = 0; step < steps; ++step) {
    const int what = sites->size() < 3 ? 0 : static_cast<int>(rng() % 3);
    v1::UpsertSitesRequest r;
    r.set_scene_id(scene);
    if (what == 0) {
      sites->push_back({scene + std::to_string(seed) + "_" + std::to_string(step),
                        PointSite{{u(rng), u(rng)}}});
      *r.add_sites() = testing::ToProtoSite(sites->back());
      EXPECT_TRUE(client->UpsertSites(r, &version).ok());
    } else if (what == 1) {
      Site& s = (*sites)[rng() % sites->size()];
      s.geometry = PointSite{{u(rng), u(rng)}};
      *r.add_sites() = testing::ToProtoSite(s);
      EXPECT_TRUE(client->UpsertSites(r, &version).ok());
    } else {
      const size_t k = rng() % sites->size();
      EXPECT_TRUE(client->DeleteSites(scene, {(*sites)[k].id}, &version).ok());
      sites->erase(sites->begin() + static_cast<long>(k));
    }
    (*at)[version] = *sites;
    if (after_each) after_each(version);
  }
  return version;
}

class WatchTest : public testing::SharedServerTest {
 protected:
  static void Create(const std::string& id, uint32_t size) {
    v1::CreateSceneRequest r;
    r.set_scene_id(id);
    r.mutable_window()->set_max_x(1);
    r.mutable_window()->set_max_y(1);
    r.set_width_px(size);
    r.set_height_px(size);
    v1::Scene scene;
    ASSERT_TRUE(client_->CreateScene(r, &scene).ok());
  }
};

// Random adds, moves and deletes of points, read as they come: every event in order, with
// its version's site count, its changed window holding every pixel whose nearest site
// changed since the event before.
TEST_F(WatchTest, EventsFollowEveryFrameAndCoverWhatChanged) {
  Create("watched", 48);
  const Grid grid{{0, 0, 1, 1}, 48, 48};
  std::map<uint64_t, SiteTable> at{{1, {}}};  // the sites at each version
  SiteTable sites;
  Watcher watcher(server_->address(), "watched");
  ASSERT_TRUE(watcher.WaitFor(1));  // the empty scene's frame
  const uint64_t last = RandomChanges("watched", 60, 5, &sites, &at, client_, [&](uint64_t v) {
    if (v % 7 == 0) {
      EXPECT_TRUE(watcher.WaitFor(v));
    }
  });
  ASSERT_TRUE(watcher.WaitFor(last));
  ExpectEventsCoverChanges(watcher.events(), at, last, grid, "watched");
}

// Changes made while the renders are held come in one frame, whose changed window joins the
// windows the render redraws (a few small ones, in a scene of many sites), and in one event.
TEST_F(WatchTest, ChangesRenderedTogetherComeInOneEvent) {
  Create("held", 160);
  const Grid grid{{0, 0, 1, 1}, 160, 160};
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  SiteTable sites;
  for (int i = 0; i < 150; ++i) sites.push_back({"h" + std::to_string(i), PointSite{{u(rng), u(rng)}}});
  const uint64_t first = Upsert("held", sites);
  std::map<uint64_t, SiteTable> at{{1, {}}, {first, sites}};
  Watcher watcher(server_->address(), "held");
  ASSERT_TRUE(watcher.WaitFor(first));
  const size_t before = watcher.events().size();
  uint64_t last = 0;
  {
    testing::HoldRenders hold(*server_);
    last = RandomChanges("held", 4, 8, &sites, &at, client_);
  }
  ASSERT_TRUE(watcher.WaitFor(last));
  const auto events = watcher.events();
  EXPECT_EQ(events.size(), before + 1) << "the held changes did not come in one event";
  ExpectEventsCoverChanges(events, at, last, grid, "held");
}

// Watching from a version: nothing until a newer frame; a deletion ends the stream OK with a
// last event that says so; an unknown scene is NOT_FOUND.
TEST_F(WatchTest, AfterVersionDeletionAndUnknownScenes) {
  Create("gone", 16);
  const uint64_t v = Upsert("gone", {{"a", PointSite{{0.5, 0.5}}}});
  ASSERT_TRUE(testing::WaitForRender(*client_, "gone", v));
  Watcher later(server_->address(), "gone", v);
  Watcher from_start(server_->address(), "gone");
  ASSERT_TRUE(from_start.WaitFor(v));
  const uint64_t w = Upsert("gone", {{"b", PointSite{{0.2, 0.2}}}});
  ASSERT_TRUE(later.WaitFor(w));
  auto events = later.events();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().version(), w) << "an event for a version not after after_version";
  ASSERT_TRUE(client_->DeleteScene("gone").ok());
  for (Watcher* watcher : {&later, &from_start}) {
    EXPECT_TRUE(watcher->WaitEnd().ok());
    events = watcher->events();
    ASSERT_FALSE(events.empty());
    EXPECT_TRUE(events.back().deleted());
    EXPECT_EQ(events.back().scene_id(), "gone");
  }
  Watcher unknown(server_->address(), "never");
  EXPECT_EQ(unknown.WaitEnd().error_code(), StatusCode::NOT_FOUND);
  Watcher bad(server_->address(), "no spaces");
  EXPECT_EQ(bad.WaitEnd().error_code(), StatusCode::INVALID_ARGUMENT);
}

// Two hundred watchers of one scene under a stream of writes all reach the last version.
TEST_F(WatchTest, HundredsOfWatchersKeepUp) {
  Create("crowd", 32);
  std::vector<std::unique_ptr<Watcher>> watchers;
  for (int i = 0; i < 200; ++i) watchers.push_back(std::make_unique<Watcher>(server_->address(), "crowd"));
  uint64_t version = 0;
  for (int i = 0; i < 100; ++i) {
    version = Upsert("crowd", {{"s" + std::to_string(i % 10), PointSite{{i / 100.0, 0.5}}}});
  }
  for (auto& w : watchers) {
    ASSERT_TRUE(w->WaitFor(version));
    const auto events = w->events();
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.back().version(), version);
    EXPECT_EQ(events.back().site_count(), 10u);
  }
  ASSERT_TRUE(client_->DeleteScene("crowd").ok());
  for (auto& w : watchers) EXPECT_TRUE(w->WaitEnd().ok());
}

// A drain ends the open streams with UNAVAILABLE, and the server exits 0 without waiting
// out its grace period for them.
TEST(WatchDrain, ShutdownEndsTheStreams) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--shutdown-grace-ms", "600000"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  ASSERT_TRUE(client->WaitForConnected(std::chrono::seconds(10)));
  v1::CreateSceneRequest r;
  r.set_scene_id("s");
  r.mutable_window()->set_max_x(1);
  r.mutable_window()->set_max_y(1);
  r.set_width_px(8);
  r.set_height_px(8);
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(r, &scene).ok());
  Watcher a(server.address(), "s"), b(server.address(), "s");
  ASSERT_TRUE(a.WaitFor(1));
  ASSERT_TRUE(b.WaitFor(1));
  server.Terminate();
  EXPECT_EQ(a.WaitEnd().error_code(), StatusCode::UNAVAILABLE);
  EXPECT_EQ(b.WaitEnd().error_code(), StatusCode::UNAVAILABLE);
  const int status = server.Wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.log();
}

// Two replicas on one PostgreSQL: a watch on the second sees the first's random writes as
// they reach it, every event in order with its version's site count and a changed window
// holding every pixel whose nearest site changed since the event before (several versions
// read from the log at once come as one event), and the deletion made through the first
// ends the stream.
TEST(WatchReplicas, AWatchOnOneReplicaFollowsWritesThroughAnother) {
  testing::TempPostgres pg;
  ASSERT_EQ(pg.error(), "");
  std::vector<std::unique_ptr<testing::ServerProcess>> replicas;
  for (int i = 0; i < 2; ++i) {
    replicas.push_back(std::make_unique<testing::ServerProcess>(
        GVD_SERVER_PATH, std::vector<std::string>{"--store", pg.url(), "--render-threads", "1"}));
    ASSERT_EQ(replicas.back()->error(), "");
  }
  auto writer = Client::Connect(replicas[0]->address());
  auto reader = Client::Connect(replicas[1]->address());
  v1::Scene scene;
  ASSERT_TRUE(writer->CreateScene(testing::UnitScene("watched", 48, 48), &scene).ok());
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!reader->GetScene("watched", &scene).ok()) {
    ASSERT_LT(std::chrono::steady_clock::now(), until) << "the scene did not reach the second";
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const Grid grid{{0, 0, 1, 1}, 48, 48};
  std::map<uint64_t, SiteTable> at{{1, {}}};
  SiteTable sites;
  Watcher watcher(replicas[1]->address(), "watched");
  ASSERT_TRUE(watcher.WaitFor(1));
  const uint64_t last = RandomChanges("watched", 60, 6, &sites, &at, writer.get(),
                                      [&](uint64_t v) {
                                        if (v % 9 == 0) {
                                          EXPECT_TRUE(watcher.WaitFor(v));
                                        }
                                      });
  ASSERT_TRUE(watcher.WaitFor(last));
  ExpectEventsCoverChanges(watcher.events(), at, last, grid, "watched");
  ASSERT_TRUE(writer->DeleteScene("watched").ok());
  EXPECT_TRUE(watcher.WaitEnd().ok());
  const auto events = watcher.events();
  ASSERT_FALSE(events.empty());
  EXPECT_TRUE(events.back().deleted());
}

// The store a server follows goes back in time (its data directory restored from a copy
// taken five versions earlier): a watch ends OK with an event that says the scene was
// reloaded, and the server then lists exactly what the store holds and takes writes after it.
TEST(WatchReplicas, AStoreGoneBackInTimeEndsTheWatchWithAReload) {
  testing::TempPostgres pg;
  ASSERT_EQ(pg.error(), "");
  testing::ServerProcess server(GVD_SERVER_PATH, {"--store", pg.url(), "--render-threads", "1"});
  ASSERT_EQ(server.error(), "");
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("s", 32, 32), &scene).ok());
  std::map<std::string, double> x_of;  // the oracle: each site's x, as written
  auto put = [&](int k) {
    v1::UpsertSitesRequest r;
    r.set_scene_id("s");
    const double x = (k % 16 + 0.5) / 16;
    *r.add_sites() = testing::ToProtoSite({"p" + std::to_string(k % 8), PointSite{{x, 0.5}}});
    uint64_t version = 0;
    grpc::Status status = client->UpsertSites(r, &version);
    EXPECT_TRUE(status.ok()) << status.error_message();
    x_of["p" + std::to_string(k % 8)] = x;
    return version;
  };
  for (int k = 0; k < 5; ++k) put(k);
  const std::map<std::string, double> saved = x_of;
  pg.Stop();
  ASSERT_TRUE(pg.SaveData("backup"));
  ASSERT_TRUE(pg.Start());
  uint64_t last = 0;
  for (int k = 5; k < 10; ++k) last = put(k);
  ASSERT_EQ(last, 11u);
  Watcher watcher(server.address(), "s");
  ASSERT_TRUE(watcher.WaitFor(last));
  pg.Stop();
  ASSERT_TRUE(pg.RestoreData("backup"));
  ASSERT_TRUE(pg.Start());
  EXPECT_TRUE(watcher.WaitEnd().ok());
  const auto events = watcher.events();
  ASSERT_FALSE(events.empty());
  EXPECT_TRUE(events.back().reloaded());
  EXPECT_FALSE(events.back().deleted());
  ASSERT_TRUE(client->GetScene("s", &scene).ok());
  EXPECT_EQ(scene.version(), 6u);
  std::vector<v1::Site> listed;
  ASSERT_TRUE(client->ListAllSites("s", &listed).ok());
  std::map<std::string, double> held;
  for (const v1::Site& site : listed) held[site.id()] = site.point().x();
  EXPECT_EQ(held, saved);
  x_of = saved;
  EXPECT_EQ(put(11), 7u);
}

}  // namespace
}  // namespace gvd
