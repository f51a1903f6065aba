// Replicas in process: several scene registries, each on a PostgresStore of its own over one
// PostgreSQL database that the test starts (tests/support/postgres.h), each following the
// store. The oracle is the acknowledged writes, applied here in the order of the versions
// they were given: every replica must end up holding exactly that.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "server/app/registry.h"
#include "server/store/postgres_store.h"
#include "tests/server/app/registry_support.h"
#include "tests/support/postgres.h"
#include "tests/support/stored_sites.h"

namespace gvd {
namespace {

using testing::SameSite;
using testing::SharedPostgres;


// One server: its own connections to the shared database, its own registry (no renderer).
struct Replica {
  std::unique_ptr<PostgresStore> store;
  std::unique_ptr<SceneRegistry> registry;
  explicit Replica(const std::string& url, bool follow = true) {
    auto s = PostgresStore::Open(url);
    EXPECT_TRUE(s.ok()) << s.status();
    store = std::move(*s);
    registry = std::make_unique<SceneRegistry>(store.get(), Renderers{}, ServerLimits());
    EXPECT_TRUE(registry->Load().ok());
    if (follow) registry->StartFollowing();
  }
};

std::vector<std::unique_ptr<Replica>> Replicas(int n) {
  static int databases = 0;
  EXPECT_EQ(SharedPostgres().error(), "");
  const std::string url = SharedPostgres().NewDatabase("replicas" + std::to_string(++databases));
  std::vector<std::unique_ptr<Replica>> out;
  for (int i = 0; i < n; ++i) out.push_back(std::make_unique<Replica>(url));
  return out;
}

// Polls `done` until it holds or 20 seconds pass.
bool Eventually(const std::function<bool()>& done) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!done()) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

uint64_t VersionOn(const Replica& r, const std::string& id) {
  auto scene = r.registry->Find(id);
  return scene.ok() ? scene->version() : 0;
}

// Three servers write one scene at once, over the same site ids: each acknowledged write has
// a version of its own, and every server ends up with the writes applied in version order.
TEST(Replicas, InterleavedWritesConvergeInVersionOrder) {
  auto replicas = Replicas(3);
  ASSERT_TRUE(replicas[0]->registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(Eventually([&] {
    for (const auto& r : replicas) {
      if (!r->registry->Find("s").ok()) return false;
    }
    return true;
  }));
  struct Op {
    std::vector<Site> put;
    std::vector<std::string> removed;
  };
  std::mutex mu;
  std::map<uint64_t, Op> acknowledged;
  std::vector<std::thread> writers;
  for (int w = 0; w < 3; ++w) {
    writers.emplace_back([&, w] {
      std::mt19937_64 rng(41 + w);
      std::uniform_real_distribution<double> u(0, 1);
      for (int k = 0; k < 40; ++k) {
        Op op;
        absl::StatusOr<uint64_t> version;
        if (rng() % 4 == 0) {
          op.removed = {"id" + std::to_string(rng() % 12)};
          version = replicas[w]->registry->DeleteSites("s", op.removed);
          if (version.status().code() == absl::StatusCode::kNotFound) continue;
        } else {
          for (int i = 0, n = 1 + rng() % 3; i < n; ++i) {
            const std::string id = "id" + std::to_string(rng() % 12);
            bool repeated = false;
            for (const Site& s : op.put) repeated |= s.id == id;
            if (!repeated) op.put.push_back({id, PointSite{{u(rng), u(rng)}}});
          }
          version = replicas[w]->registry->UpsertSites("s", op.put);
        }
        ASSERT_TRUE(version.ok()) << version.status();
        std::lock_guard<std::mutex> lock(mu);
        EXPECT_TRUE(acknowledged.emplace(*version, std::move(op)).second) << *version;
      }
    });
  }
  for (auto& t : writers) t.join();
  std::map<std::string, Site> want;
  uint64_t head = 1;
  for (const auto& [version, op] : acknowledged) {
    EXPECT_EQ(version, head + 1);  // every version from 2 up was given once
    head = version;
    for (const std::string& id : op.removed) want.erase(id);
    for (const Site& s : op.put) want[s.id] = s;
  }
  for (size_t i = 0; i < replicas.size(); ++i) {
    SCOPED_TRACE(i);
    ASSERT_TRUE(Eventually([&] { return VersionOn(*replicas[i], "s") == head; }))
        << VersionOn(*replicas[i], "s") << " of " << head;
    auto snapshot = (*As(replicas[i]->registry->Find("s")))->snapshot();
    ASSERT_EQ(snapshot->size(), want.size());
    for (const auto& [id, site] : want) {
      auto slot = snapshot->Find(id);
      ASSERT_TRUE(slot.has_value()) << id;
      EXPECT_TRUE(SameSite(*snapshot->sites().get(*slot), site)) << id;
    }
    EXPECT_EQ(replicas[i]->registry->Lag("s").store_version, head);
  }
}

// A client reads its own write through another server: a read at the written version waits
// for the follower rather than answering OUT_OF_RANGE; a version the store never reached
// still ends in OUT_OF_RANGE.
TEST(Replicas, AReadAtAVersionWaitsForTheLog) {
  auto replicas = Replicas(2);
  Replica& a = *replicas[0];
  Replica& b = *replicas[1];
  ASSERT_TRUE(a.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(Eventually([&] { return b.registry->Find("s").ok(); }));
  auto on_b = *As(b.registry->Find("s"));
  for (int k = 0; k < 20; ++k) {
    auto written = a.registry->UpsertSites("s", {{"p" + std::to_string(k), PointSite{{0.5, 0.5}}}});
    ASSERT_TRUE(written.ok()) << written.status();
    auto version = b.registry->ReadVersion(*on_b, *written);
    ASSERT_TRUE(version.ok()) << version.status();  // not OUT_OF_RANGE
    EXPECT_EQ(*version, *written);
    // and the version comes, with the write in it
    ASSERT_TRUE(Eventually([&] { return on_b->version() >= *written; }));
    EXPECT_TRUE(on_b->snapshot()->Find("p" + std::to_string(k)).has_value());
  }
  ASSERT_TRUE(Eventually([&] { return on_b->version() == 21; }));
  // Beyond the store: the wait ends with OUT_OF_RANGE at the follower's next read.
  auto beyond = b.registry->ReadVersion(*on_b, 100);
  ASSERT_TRUE(beyond.ok());
  std::promise<absl::Status> ended;
  on_b->WhenRendered(*beyond, [&](absl::StatusOr<std::shared_ptr<const Frame>> f) {
    ended.set_value(f.status());
  });
  auto future = ended.get_future();
  ASSERT_EQ(future.wait_for(std::chrono::seconds(20)), std::future_status::ready);
  absl::Status s = future.get();
  EXPECT_EQ(s.code(), absl::StatusCode::kOutOfRange) << s;
  EXPECT_NE(std::string(s.message()).find("version 21"), std::string::npos) << s;
}

// A scene deleted on one server goes from the others; made again (with other settings), it
// is the new one everywhere, none of the old sites with it.
TEST(Replicas, DeletionsAndNewIncarnationsReachEveryServer) {
  auto replicas = Replicas(2);
  Replica& a = *replicas[0];
  Replica& b = *replicas[1];
  ASSERT_TRUE(a.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(a.registry->UpsertSites("s", {{"p", PointSite{{0.5, 0.5}}}}).ok());
  ASSERT_TRUE(Eventually([&] { return VersionOn(b, "s") == 2; }));
  // The same id made on the other server at once is refused by the database.
  EXPECT_EQ(b.registry->CreateScene(Settings("s")).status().code(),
            absl::StatusCode::kAlreadyExists);
  ASSERT_TRUE(a.registry->DeleteScene("s").ok());
  ASSERT_TRUE(Eventually([&] {
    return b.registry->Describe("s").status().code() == absl::StatusCode::kNotFound;
  }));
  ASSERT_TRUE(b.registry->CreateScene(Settings("s", 16)).ok());
  ASSERT_TRUE(Eventually([&] {
    auto scene = a.registry->Find("s");
    return scene.ok() && scene->settings().grid.width == 16;
  }));
  EXPECT_EQ(a.registry->Find("s")->site_count(), 0u);
  // Deleted and made again between two reads of the follower: the incarnation tells.
  ASSERT_TRUE(b.registry->UpsertSites("s", {{"q", PointSite{{0.5, 0.5}}}}).ok());
  ASSERT_TRUE(Eventually([&] { return VersionOn(a, "s") == 2; }));
  auto direct = b.store->CreateScene(Settings("s", 8), 1);
  EXPECT_EQ(direct.status().code(), absl::StatusCode::kAlreadyExists);
  ASSERT_TRUE(b.store->DeleteScene("s").ok());
  ASSERT_TRUE(b.store->CreateScene(Settings("s", 8), 1).ok());
  ASSERT_TRUE(Eventually([&] {
    auto scene = a.registry->Find("s");
    return scene.ok() && scene->settings().grid.width == 8 && scene->site_count() == 0;
  }));
}

// A server that has not yet seen a scene deleted and made again elsewhere (it does not
// follow here, as if the notification were late) writes to its old copy: the database
// refuses the write for the new scene, which keeps none of it, and the server, reading the
// store, finds the scene is another one now.
TEST(Replicas, AWriteToASceneMadeAgainElsewhereIsRefused) {
  static int databases = 0;
  ASSERT_EQ(SharedPostgres().error(), "");
  const std::string url = SharedPostgres().NewDatabase("incarnation" + std::to_string(++databases));
  Replica late(url, /*follow=*/false);
  Replica other(url);
  ASSERT_TRUE(late.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(late.registry->UpsertSites("s", {{"p", PointSite{{0.5, 0.5}}}}).ok());
  ASSERT_TRUE(Eventually([&] { return VersionOn(other, "s") == 2; }));
  // Deleted and made again, as a 3D scene, and brought to version 2 as well.
  ASSERT_TRUE(other.registry->DeleteScene("s").ok());
  SceneSettings three_d = Settings("s", 4);
  three_d.depth = 4;
  three_d.max_z = 1;
  ASSERT_TRUE(other.registry->CreateScene(three_d).ok());
  ASSERT_TRUE(other.registry->UpsertSites("s", std::vector<Site3>{{"q", PointSite3{{0.5, 0.5, 0.5}}}}).ok());
  // The late server's write follows version 2 of its own copy, which the store also has.
  auto written = late.registry->UpsertSites("s", {{"r", PointSite{{0.25, 0.25}}}});
  EXPECT_FALSE(written.ok());
  EXPECT_EQ(written.status().code(), absl::StatusCode::kFailedPrecondition) << written.status();
  auto stored = other.store->ReadChanges("s", 0);
  ASSERT_TRUE(stored.ok()) << stored.status();
  const auto* put = std::get_if<SharedSites<Site3>>(&stored->put);
  ASSERT_NE(put, nullptr);  // a 3D scene's sites
  ASSERT_EQ(put->size(), 1u);
  EXPECT_EQ((*put)[0]->id, "q");
  EXPECT_EQ(stored->version, 2u);
  auto held = late.registry->Find("s");
  ASSERT_TRUE(held.ok()) << held.status();
  EXPECT_TRUE(held->three_d());  // it now holds the new scene
}

// The sites `r` holds in scene `id`, by id.
std::map<std::string, Site> SitesOn(const Replica& r, const std::string& id) {
  std::map<std::string, Site> out;
  auto scene = r.registry->Find(id);
  if (!scene.ok()) return out;
  auto snapshot = (*As(*scene))->snapshot();
  snapshot->ids().ForEachAfter("", [&](const IdMap::Entry& e) {
    out.emplace(e.id, *snapshot->sites().get(e.slot));
    return true;
  });
  return out;
}

// Writes acknowledged by version, each putting one site: the oracle of what a store at a
// version holds, whatever history the store went through.
class History {
 public:
  // Puts a site through `r` and notes it at the version acknowledged.
  uint64_t Put(Replica& r, const std::string& id) {
    Site site{id, PointSite{{u_(rng_), u_(rng_)}}};
    auto version = r.registry->UpsertSites("s", {site});
    EXPECT_TRUE(version.ok()) << version.status();
    if (!version.ok()) return 0;
    EXPECT_FALSE(by_version_.count(*version)) << *version;
    by_version_[*version] = site;
    return *version;
  }
  // Forgets the writes after `version`: the store went back to it.
  void GoBackTo(uint64_t version) { by_version_.erase(by_version_.upper_bound(version), by_version_.end()); }
  // The sites the writes leave, applied in version order.
  std::map<std::string, Site> Sites() const {
    std::map<std::string, Site> out;
    for (const auto& [version, site] : by_version_) out.insert_or_assign(site.id, site);
    return out;
  }

 private:
  std::mt19937_64 rng_{43};
  std::uniform_real_distribution<double> u_{0, 1};
  std::map<uint64_t, Site> by_version_;
};

bool SameSites(const std::map<std::string, Site>& a, const std::map<std::string, Site>& b) {
  if (a.size() != b.size()) return false;
  for (const auto& [id, site] : a) {
    auto other = b.find(id);
    if (other == b.end() || !SameSite(site, other->second)) return false;
  }
  return true;
}

// The database goes back in time under two following servers: stopped, its data directory
// replaced by a copy taken ten versions earlier (a restore from a backup), started again.
// Both servers drop what the database lost, hold exactly what it holds, and take writes
// again at the versions after it.
TEST(StoreBackInTime, ReplicasFollowARestoredDatabaseAndWriteAgain) {
  testing::TempPostgres pg;
  ASSERT_EQ(pg.error(), "");
  Replica a(pg.url()), b(pg.url());
  ASSERT_TRUE(a.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(Eventually([&] { return b.registry->Find("s").ok(); }));
  History history;
  for (int k = 0; k < 10; ++k) history.Put(k % 2 ? a : b, "p" + std::to_string(k % 7));
  ASSERT_TRUE(Eventually([&] { return VersionOn(a, "s") == 11 && VersionOn(b, "s") == 11; }));
  pg.Stop();
  ASSERT_TRUE(pg.SaveData("backup"));
  ASSERT_TRUE(pg.Start());
  for (int k = 10; k < 20; ++k) history.Put(k % 2 ? a : b, "p" + std::to_string(k % 9));
  ASSERT_TRUE(Eventually([&] { return VersionOn(a, "s") == 21 && VersionOn(b, "s") == 21; }));
  auto held = *As(a.registry->Find("s"));
  pg.Stop();
  ASSERT_TRUE(pg.RestoreData("backup"));
  ASSERT_TRUE(pg.Start());
  history.GoBackTo(11);
  for (Replica* r : {&a, &b}) {
    EXPECT_TRUE(Eventually([&] { return VersionOn(*r, "s") == 11; })) << VersionOn(*r, "s");
    EXPECT_TRUE(SameSites(SitesOn(*r, "s"), history.Sites()));
  }
  // The scene held before is retired as reloaded: its watchers are told so.
  EXPECT_TRUE(held->deleted());
  EXPECT_TRUE(held->reloaded());
  EXPECT_EQ(history.Put(a, "after"), 12u);
  EXPECT_EQ(history.Put(b, "after2"), 13u);
  for (Replica* r : {&a, &b}) {
    EXPECT_TRUE(Eventually([&] { return VersionOn(*r, "s") == 13; })) << VersionOn(*r, "s");
    EXPECT_TRUE(SameSites(SitesOn(*r, "s"), history.Sites()));
  }
}

// A server that does not follow (as if it read the store late) writes versions 2 to 6 of
// scene "s", the database is copied, the server writes versions 7 to 11, and the copy is
// restored: the database is back at version 6 and the server still holds 11.
struct LateServer {
  testing::TempPostgres pg;
  std::unique_ptr<Replica> late;
  History history;
  void GoBackInTime() {
    ASSERT_EQ(pg.error(), "");
    late = std::make_unique<Replica>(pg.url(), /*follow=*/false);
    ASSERT_TRUE(late->registry->CreateScene(Settings("s")).ok());
    for (int k = 0; k < 5; ++k) history.Put(*late, "p" + std::to_string(k));
    pg.Stop();
    ASSERT_TRUE(pg.SaveData("backup"));
    ASSERT_TRUE(pg.Start());
    for (int k = 5; k < 10; ++k) history.Put(*late, "p" + std::to_string(k % 7));
    ASSERT_EQ(VersionOn(*late, "s"), 11u);
    pg.Stop();
    ASSERT_TRUE(pg.RestoreData("backup"));
    ASSERT_TRUE(pg.Start());
    history.GoBackTo(6);
  }
};

// The database goes back in time and another server writes it past the version a server
// still holds before that server reads it again (it follows late here): the versions it holds
// now name other changes, and it reads the scene again rather than what follows its version.
TEST(StoreBackInTime, AServerOvertakenByANewHistoryReadsTheSceneAgain) {
  LateServer db;
  ASSERT_NO_FATAL_FAILURE(db.GoBackInTime());
  Replica fresh(db.pg.url(), /*follow=*/false);
  for (int k = 0; k < 7; ++k) db.history.Put(fresh, "q" + std::to_string(k % 3));
  ASSERT_EQ(VersionOn(fresh, "s"), 13u);
  ASSERT_TRUE(db.late->registry->CatchUp().ok());
  EXPECT_EQ(VersionOn(*db.late, "s"), 13u);
  EXPECT_TRUE(SameSites(SitesOn(*db.late, "s"), db.history.Sites()));
}

// The same, found by a write: the late server's write follows its version, which the store
// has too, with other sites. The store refuses it, and the server reads the scene again and
// makes the write on what the store holds.
TEST(StoreBackInTime, AWriteOnAHistoryTheStoreLostIsMadeOnTheStoresOwn) {
  LateServer db;
  ASSERT_NO_FATAL_FAILURE(db.GoBackInTime());
  Replica fresh(db.pg.url(), /*follow=*/false);
  for (int k = 0; k < 5; ++k) db.history.Put(fresh, "q" + std::to_string(k));
  ASSERT_EQ(VersionOn(*db.late, "s"), 11u);
  ASSERT_EQ(VersionOn(fresh, "s"), 11u);
  EXPECT_EQ(db.history.Put(*db.late, "r"), 12u);
  EXPECT_TRUE(SameSites(SitesOn(*db.late, "s"), db.history.Sites()));
  ASSERT_TRUE(fresh.registry->CatchUp().ok());
  EXPECT_TRUE(SameSites(SitesOn(fresh, "s"), db.history.Sites()));
}

// Two servers on a primary and its streaming standby, as an operator runs PostgreSQL's own
// high availability: one multi-host URL that connects to whichever takes writes.
struct Failover {
  testing::TempPostgres primary;
  testing::TempPostgres standby;
  std::string url;
  explicit Failover(bool synchronous)
      : primary(), standby(primary, synchronous),
        url(absl::StrCat("postgresql://gvd@/gvd?host=", primary.dir(), ",", standby.dir(),
                         "&port=", primary.port(), ",", standby.port(),
                         "&target_session_attrs=read-write")) {}
  // The primary dies; the standby is promoted.
  bool Fail() {
    primary.Stop("immediate");
    return standby.Promote();
  }
};

// With a synchronous standby, a failover in the middle of writes on two servers loses no
// acknowledged write: each is in the new primary, and both servers hold what it holds.
TEST(StoreFailover, ASynchronousStandbyKeepsEveryAcknowledgedWrite) {
  Failover db(/*synchronous=*/true);
  ASSERT_EQ(db.primary.error(), "");
  ASSERT_EQ(db.standby.error(), "");
  Replica a(db.url), b(db.url);
  ASSERT_TRUE(a.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(Eventually([&] { return b.registry->Find("s").ok(); }));
  std::mutex mu;
  std::map<std::string, Site> acknowledged;
  std::atomic<bool> stop{false};
  std::atomic<int> written{0};
  std::vector<std::thread> writers;
  for (Replica* r : {&a, &b}) {
    writers.emplace_back([&, r] {
      std::mt19937_64 rng(reinterpret_cast<uintptr_t>(r));
      std::uniform_real_distribution<double> u(0, 1);
      for (int k = 0; !stop; ++k) {
        Site site{absl::StrCat(r == &a ? "a" : "b", k), PointSite{{u(rng), u(rng)}}};
        auto version = r->registry->UpsertSites("s", {site});
        if (!version.ok()) {
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
          continue;  // the database is failing over: the write may or may not be there
        }
        ++written;
        std::lock_guard<std::mutex> lock(mu);
        acknowledged.emplace(site.id, site);
      }
    });
  }
  ASSERT_TRUE(Eventually([&] { return written > 50; }));
  ASSERT_TRUE(db.Fail());
  const int before = written;
  EXPECT_TRUE(Eventually([&] { return written > before + 50; })) << "no writes after failover";
  stop = true;
  for (auto& t : writers) t.join();
  auto stored = PostgresStore::Open(absl::StrCat("postgresql://gvd@/gvd?host=", db.standby.dir(),
                                                 "&port=", db.standby.port()));
  ASSERT_TRUE(stored.ok()) << stored.status();
  auto loaded = (*stored)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  std::map<std::string, Site> held;
  for (const Site& site : testing::SitesOf((*loaded)[0])) held.emplace(site.id, site);
  for (const auto& [id, site] : acknowledged) {
    auto it = held.find(id);
    ASSERT_NE(it, held.end()) << id << " was acknowledged and lost";
    EXPECT_TRUE(SameSite(it->second, site)) << id;
  }
  for (Replica* r : {&a, &b}) {
    EXPECT_TRUE(Eventually([&] { return VersionOn(*r, "s") == (*loaded)[0].version; }));
    EXPECT_TRUE(SameSites(SitesOn(*r, "s"), held));
  }
}

// With an asynchronous standby that stopped receiving before the last writes, the failover
// loses them: both servers drop them, hold exactly what the new primary holds, and write
// again.
TEST(StoreFailover, AnAsynchronousStandbyThatMissedWritesIsFollowedBack) {
  Failover db(/*synchronous=*/false);
  ASSERT_EQ(db.primary.error(), "");
  ASSERT_EQ(db.standby.error(), "");
  Replica a(db.url), b(db.url);
  ASSERT_TRUE(a.registry->CreateScene(Settings("s")).ok());
  ASSERT_TRUE(Eventually([&] { return b.registry->Find("s").ok(); }));
  History history;
  for (int k = 0; k < 10; ++k) history.Put(k % 2 ? a : b, "p" + std::to_string(k % 7));
  // The standby has replayed version 11, then stops receiving.
  ASSERT_TRUE(Eventually([&] {
    return db.standby.Sql("SELECT version FROM gvd_scene WHERE id = 's'") == "11";
  }));
  db.standby.Sql("ALTER SYSTEM SET primary_conninfo = ''");
  db.standby.Sql("SELECT pg_reload_conf()");
  ASSERT_TRUE(Eventually([&] {
    return db.primary.Sql("SELECT count(*) FROM pg_stat_replication") == "0";
  }));
  for (int k = 10; k < 20; ++k) history.Put(k % 2 ? a : b, "p" + std::to_string(k % 9));
  ASSERT_TRUE(Eventually([&] { return VersionOn(a, "s") == 21 && VersionOn(b, "s") == 21; }));
  ASSERT_TRUE(db.Fail());
  history.GoBackTo(11);
  for (Replica* r : {&a, &b}) {
    EXPECT_TRUE(Eventually([&] { return VersionOn(*r, "s") == 11; })) << VersionOn(*r, "s");
    EXPECT_TRUE(SameSites(SitesOn(*r, "s"), history.Sites()));
  }
  EXPECT_EQ(history.Put(b, "after"), 12u);
  EXPECT_TRUE(Eventually([&] { return VersionOn(a, "s") == 12; }));
  EXPECT_TRUE(SameSites(SitesOn(a, "s"), history.Sites()));
}

}  // namespace
}  // namespace gvd
