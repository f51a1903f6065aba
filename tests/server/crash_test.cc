// Durability: a writer streams upserts, moves and deletes, each SYNC or RELAXED at random; the
// real server is killed with SIGKILL at random moments and restarted on the same store. Every
// acknowledged update must be there after the restart, RELAXED ones too (they were written to
// the store before the answer), and the request in flight at the kill entirely or not at all.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>

#include <atomic>
#include <map>
#include <optional>
#include <random>
#include <thread>

#include "gvd/client.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using SceneState = std::map<std::string, std::pair<double, double>>;  // site -> (x, y)

struct Op {
  std::string scene;
  std::map<std::string, std::optional<std::pair<double, double>>> changes;  // none: delete
};

void ApplyOp(const Op& op, std::map<std::string, SceneState>* state,
             std::map<std::string, uint64_t>* versions) {
  SceneState& s = (*state)[op.scene];
  for (const auto& [id, p] : op.changes) {
    if (p) {
      s[id] = *p;
    } else {
      s.erase(id);
    }
  }
  ++(*versions)[op.scene];
}

// What the restarted server holds.
void ReadBack(Client& client, const std::vector<std::string>& scenes,
              std::map<std::string, SceneState>* state, std::map<std::string, uint64_t>* versions) {
  for (const auto& name : scenes) {
    v1::Scene scene;
    grpc::Status s = client.GetScene(name, &scene);
    ASSERT_TRUE(s.ok()) << s.error_message();
    (*versions)[name] = scene.version();
    std::vector<v1::Site> sites;
    ASSERT_TRUE(client.ListAllSites(name, &sites).ok());
    SceneState& st = (*state)[name];
    st.clear();
    for (const auto& site : sites) st[site.id()] = {site.point().x(), site.point().y()};
    ASSERT_EQ(scene.site_count(), st.size());
  }
}

TEST(CrashTest, AcknowledgedUpdatesSurviveSigkill) {
  char dir_template[] = "/tmp/gvd-crash-XXXXXX";
  const std::string data = std::string(mkdtemp(dir_template)) + "/store";
  const std::vector<std::string> scenes = {"left", "right"};
  std::map<std::string, SceneState> acked;
  std::map<std::string, uint64_t> acked_versions;
  std::optional<Op> in_flight;
  std::mt19937_64 rng(2026);
  int applied_in_flight = 0, lost_in_flight = 0;
  std::atomic<int> acknowledged{0};

  const int kRounds = 12;
  for (int round = 0; round <= kRounds; ++round) {
    // Writes of 8 sites or more as packs, folded 1 ms after the last: the kills land before,
    // during and after their folds.
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data, "--store-pack-sites", "8",
                                                    "--store-fold-after-ms", "1"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    ASSERT_TRUE(client->WaitForConnected(std::chrono::seconds(10)));
    if (round == 0) {
      for (const auto& name : scenes) {
        v1::Scene scene;
        ASSERT_TRUE(client->CreateScene(testing::UnitScene(name, 64, 64), &scene).ok());
        acked[name] = {};
        acked_versions[name] = scene.version();
      }
    } else {
      // The restarted store: the acknowledged state, plus at most the whole request that was
      // in flight at the kill.
      std::map<std::string, SceneState> got;
      std::map<std::string, uint64_t> got_versions;
      ReadBack(*client, scenes, &got, &got_versions);
      if (got == acked && got_versions == acked_versions) {
        lost_in_flight += in_flight.has_value();
      } else {
        ASSERT_TRUE(in_flight.has_value()) << "round " << round << ": the store differs from "
                                           << "what was acknowledged, with nothing in flight";
        auto with = acked;
        auto with_versions = acked_versions;
        ApplyOp(*in_flight, &with, &with_versions);
        ASSERT_EQ(got, with) << "round " << round << ": neither the acknowledged state nor it "
                             << "plus the whole request in flight";
        ASSERT_EQ(got_versions, with_versions) << "round " << round;
        acked = with;
        acked_versions = with_versions;
        ++applied_in_flight;
      }
      in_flight.reset();
    }
    if (round == kRounds) break;

    // The writer: one request at a time, each recorded as in flight until acknowledged.
    std::atomic<bool> dead{false};
    std::mutex mu;
    uint64_t seed = rng();
    std::thread writer([&] {
      std::mt19937_64 r(seed);
      std::uniform_real_distribution<double> u(0, 1);
      int next = 0;
      while (!dead) {
        Op op;
        op.scene = scenes[r() % scenes.size()];
        const SceneState& current = acked[op.scene];
        bool remove = !current.empty() && r() % 4 == 0;
        if (remove) {
          auto it = current.begin();
          std::advance(it, r() % current.size());
          for (int k = 0; k < 3 && it != current.end(); ++k, ++it) op.changes[it->first] = std::nullopt;
        } else {
          int n = 1 + static_cast<int>(r() % 40);
          for (int k = 0; k < n; ++k) {
            std::string id;
            if (!current.empty() && r() % 2) {  // a move
              auto it = current.begin();
              std::advance(it, r() % current.size());
              id = it->first;
            } else {
              id = "r" + std::to_string(round) + "-" + std::to_string(next++);
            }
            op.changes[id] = std::make_pair(u(r), u(r));
          }
        }
        {
          std::lock_guard<std::mutex> lock(mu);
          in_flight = op;
        }
        const v1::Durability durability = r() % 2 ? v1::DURABILITY_RELAXED : v1::DURABILITY_SYNC;
        grpc::Status s;
        uint64_t version = 0;
        if (remove) {
          std::vector<std::string> ids;
          for (const auto& [id, p] : op.changes) ids.push_back(id);
          s = client->DeleteSites(op.scene, ids, &version, durability);
        } else {
          v1::UpsertSitesRequest req;
          req.set_scene_id(op.scene);
          req.set_durability(durability);
          for (const auto& [id, p] : op.changes) {
            auto* site = req.add_sites();
            site->set_id(id);
            site->mutable_point()->set_x(p->first);
            site->mutable_point()->set_y(p->second);
          }
          s = client->UpsertSites(req, &version);
        }
        if (!s.ok()) return;  // the server is gone: the request stays in flight
        std::lock_guard<std::mutex> lock(mu);
        ApplyOp(op, &acked, &acked_versions);
        EXPECT_EQ(version, acked_versions[op.scene]);
        in_flight.reset();
        ++acknowledged;
      }
    });
    // The kill comes after a number of acknowledgements drawn for the round, and then while
    // the next request is in flight at a random point of its path (sent, committing, or
    // answered but not yet read), however fast or slow the machine is.
    const int target = acknowledged + 1 + static_cast<int>(rng() % 8);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (acknowledged < target && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const bool reached = acknowledged >= target;
    if (reached) std::this_thread::sleep_for(std::chrono::microseconds(rng() % 5000));
    server.Kill();
    dead = true;
    writer.join();
    ASSERT_TRUE(reached) << "round " << round << ": the server acknowledged " << acknowledged
                         << " of " << target << " requests in 120 s";
  }
  std::printf("acknowledged %d requests over %d kills; in flight at the kill: %d applied, "
              "%d not\n", acknowledged.load(), kRounds, applied_in_flight, lost_in_flight);
  std::system(("rm -rf " + data.substr(0, data.rfind('/'))).c_str());
}

// SIGTERM drains: a query waiting for a render when the signal comes still gets its answer,
// and the server exits 0.
// SIGTERM while a query waits for a render: the drain lets the render finish and the query be
// answered, and the server exits cleanly having cancelled nothing. The render is held until
// the query is known to be in flight and the server to be draining, so the order is the same
// however fast the machine renders.
TEST(CrashTest, SigtermDrainsCallsInFlight) {
  testing::ServerProcess server(
      GVD_SERVER_PATH, {"--shutdown-grace-ms", "120000", "--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  const int port = testing::MetricsPort(server.log());
  ASSERT_NE(port, 0) << server.log();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("draining", 256, 256), &scene).ok());
  auto hold = std::make_unique<testing::HoldRenders>(server);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Site> sites;
  v1::UpsertSitesRequest u;
  u.set_scene_id("draining");
  // Weighted: the index does not answer in place of the held frame (see min_version).
  for (int i = 0; i < 1000; ++i) {
    sites.push_back({std::to_string(i), PointSite{{unit(rng), unit(rng)}}});
    sites.back().additive = 0.01 * (i % 3);
    *u.add_sites() = testing::ToProtoSite(sites.back());
  }
  uint64_t v;
  ASSERT_TRUE(client->UpsertSites(u, &v).ok());
  const Vec2 q{0.5, 0.25};
  grpc::Status answered;
  v1::FindNearestResponse r;
  std::atomic<bool> done = false;
  std::thread waiting([&] {
    v1::FindNearestRequest find;
    find.set_scene_id("draining");
    find.set_min_version(v);
    find.add_points()->set_x(q.x);
    find.mutable_points(0)->set_y(q.y);
    answered = client->FindNearest(find, &r);
    done = true;
  });
  const std::string in_flight = "gvd_rpc_in_flight{method=\"FindNearest\"} 1";
  std::string text = testing::WaitForMetric(port, in_flight, 120);
  ASSERT_NE(text.find(in_flight), std::string::npos) << text;
  server.Terminate();
  for (int tries = 0; tries < 2400 && server.log().find("event=shutting_down") == std::string::npos;
       ++tries) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_NE(server.log().find("event=shutting_down"), std::string::npos) << server.log();
  EXPECT_FALSE(done) << "the query was answered while its version's render was held";
  hold.reset();  // the render goes on, during the drain
  waiting.join();
  const int status = server.Wait();
  ASSERT_TRUE(answered.ok()) << answered.error_message();
  ASSERT_EQ(r.results_size(), 1);
  // The answer of the version the query waited for: a site of it, at its distance, no
  // farther from the true nearest than the answer's bound.
  const v1::NearestSite& n = r.results(0);
  ASSERT_FALSE(n.site_id().empty());
  const Site& named = sites.at(std::stoul(n.site_id()));
  const double tolerance = oracle::Tolerance(q, n.distance());
  EXPECT_NEAR(n.distance(), oracle::Value(q, named), tolerance) << n.site_id();
  EXPECT_GE(oracle::BestSite(q, sites).value + tolerance, n.distance() - n.error_bound());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.log();
  EXPECT_NE(server.log().find("event=stopped cancelled_calls=0"), std::string::npos) << server.log();
}

// A clean restart keeps every scene, site and version.
TEST(CrashTest, CleanRestartKeepsEverything) {
  char dir_template[] = "/tmp/gvd-restart-XXXXXX";
  const std::string data = std::string(mkdtemp(dir_template)) + "/store";
  {
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    v1::CreateSceneRequest c;
    c.set_scene_id("kept");
    c.mutable_window()->set_max_x(10);
    c.mutable_window()->set_max_y(10);
    c.set_width_px(32);
    c.set_height_px(32);
    c.set_render_mode(v1::RENDER_MODE_EXACT);
    v1::Scene scene;
    ASSERT_TRUE(client->CreateScene(c, &scene).ok());
    v1::UpsertSitesRequest u;
    u.set_scene_id("kept");
    auto* s = u.add_sites();
    s->set_id("a");
    s->mutable_point()->set_x(3);
    s->mutable_point()->set_y(4);
    uint64_t v;
    ASSERT_TRUE(client->UpsertSites(u, &v).ok());
    int status = server.Stop();
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  }
  testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->GetScene("kept", &scene).ok());
  EXPECT_EQ(scene.version(), 2u);
  EXPECT_EQ(scene.site_count(), 1u);
  EXPECT_EQ(scene.render_mode(), v1::RENDER_MODE_EXACT);
  v1::FindNearestRequest q;
  q.set_scene_id("kept");
  q.add_points();
  q.set_min_version(2);
  v1::FindNearestResponse r;
  ASSERT_TRUE(client->FindNearest(q, &r).ok());
  EXPECT_EQ(r.results(0).site_id(), "a");
  EXPECT_EQ(r.results(0).distance(), 5);
  std::system(("rm -rf " + data.substr(0, data.rfind('/'))).c_str());
}

// Runs SQL with one blob parameter per '?' on a database file, as an earlier release did.
void RawSql(const std::string& path, const std::string& sql,
            const std::vector<std::string>& blobs = {}) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK) << sql;
  for (size_t i = 0; i < blobs.size(); ++i) {
    sqlite3_bind_blob(stmt, static_cast<int>(i + 1), blobs[i].data(),
                      static_cast<int>(blobs[i].size()), SQLITE_TRANSIENT);
  }
  EXPECT_EQ(sqlite3_step(stmt), SQLITE_DONE) << sql << ": " << sqlite3_errmsg(db);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
}

// A database written by the release that kept request messages (scenes as their
// CreateSceneRequest, sites as their Site message) is converted when the server starts, with
// every scene setting, site, weight and version kept.
TEST(StoreUpgrade, AnEarlierDatabaseIsConvertedOnStart) {
  char dir_template[] = "/tmp/gvd-upgrade-XXXXXX";
  const std::string data = std::string(mkdtemp(dir_template)) + "/store";
  ASSERT_EQ(mkdir(data.c_str(), 0700), 0);
  const std::string db = data + "/gvd.sqlite3";
  RawSql(db, "CREATE TABLE scenes (id TEXT PRIMARY KEY, request BLOB NOT NULL, version INTEGER NOT NULL)");
  RawSql(db, "CREATE TABLE sites (scene TEXT NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,"
             " id TEXT NOT NULL, site BLOB NOT NULL, PRIMARY KEY (scene, id)) WITHOUT ROWID");
  v1::CreateSceneRequest create = testing::UnitScene("old", 48, 32);
  create.set_diagram(v1::DIAGRAM_FARTHEST);
  RawSql(db, "INSERT INTO scenes VALUES ('old', ?, 9)", {create.SerializeAsString()});
  v1::Site p, g;
  p.set_id("p");
  p.mutable_point()->set_x(0.25);
  p.mutable_point()->set_y(0.5);
  p.set_additive_weight(0.125);
  p.set_multiplicative_weight(2);
  g.set_id("g");
  for (auto [x, y] : {std::pair{0.1, 0.1}, {0.9, 0.1}, {0.5, 0.8}}) {
    auto* v = g.mutable_polygon()->add_vertices();
    v->set_x(x);
    v->set_y(y);
  }
  g.mutable_polygon()->set_side(v1::Polygon::SIDE_INSIDE);
  for (const v1::Site& site : {p, g}) {
    RawSql(db, "INSERT INTO sites VALUES ('old', '" + site.id() + "', ?)",
           {site.SerializeAsString()});
  }
  auto expect_sites = [&](Client& client, uint64_t version, size_t count) {
    v1::Scene scene;
    ASSERT_TRUE(client.GetScene("old", &scene).ok());
    EXPECT_EQ(scene.version(), version);
    EXPECT_EQ(scene.width_px(), 48u);
    EXPECT_EQ(scene.height_px(), 32u);
    EXPECT_EQ(scene.diagram(), v1::DIAGRAM_FARTHEST);
    std::vector<v1::Site> sites;
    ASSERT_TRUE(client.ListAllSites("old", &sites).ok());
    ASSERT_EQ(sites.size(), count);
    EXPECT_EQ(sites[0].id(), "g");
    EXPECT_EQ(sites[0].polygon().side(), v1::Polygon::SIDE_INSIDE);
    ASSERT_EQ(sites[0].polygon().vertices_size(), 3);
    EXPECT_EQ(sites[0].polygon().vertices(2).y(), 0.8);
    EXPECT_EQ(sites[1].id(), "p");
    EXPECT_EQ(sites[1].point().x(), 0.25);
    EXPECT_EQ(sites[1].point().y(), 0.5);
    EXPECT_EQ(sites[1].additive_weight(), 0.125);
    EXPECT_EQ(sites[1].multiplicative_weight(), 2);
  };
  {
    testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data});
    ASSERT_TRUE(server.error().empty()) << server.error();
    auto client = Client::Connect(server.address());
    ASSERT_TRUE(client->WaitForConnected(std::chrono::seconds(10)));
    expect_sites(*client, 9, 2);
    v1::UpsertSitesRequest r;
    r.set_scene_id("old");
    auto* q = r.add_sites();
    q->set_id("q");
    q->mutable_point()->set_x(0.75);
    q->mutable_point()->set_y(0.75);
    uint64_t version = 0;
    ASSERT_TRUE(client->UpsertSites(r, &version).ok());
    EXPECT_EQ(version, 10u);
  }
  // Converted once: the restarted server reads the new form, with the later write.
  testing::ServerProcess server(GVD_SERVER_PATH, {"--data", data});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  ASSERT_TRUE(client->WaitForConnected(std::chrono::seconds(10)));
  expect_sites(*client, 10, 3);
  std::system(("rm -rf " + data.substr(0, data.rfind('/'))).c_str());
}

}  // namespace
}  // namespace gvd
