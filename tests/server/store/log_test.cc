// The store as a log (server/store/store.h), on both engines: SQLite in a file, and a real
// PostgreSQL started for the test (tests/support/postgres.h). The oracle is a model kept
// here: each version's state of a scene, built from the change sets the store acknowledged.
// A follower at any version that applies what ReadChanges gives must hold the latest state.
#include <algorithm>
#include <atomic>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <openssl/sha.h>

#include "render/scene/codec.h"
#include "server/store/postgres_store.h"
#include "server/store/sqlite_store.h"
#include "tests/support/postgres.h"
#include "tests/support/stored_sites.h"

namespace gvd {
namespace {

using testing::RandomSite;
using testing::SameSite;
using testing::TempDir;
using testing::SitesOf;
using testing::PutOf;
using testing::SharedPostgres;

using State = std::map<std::string, Site>;

SceneSettings Settings(const std::string& id) {
  SceneSettings s;
  s.id = id;
  s.grid = Grid{{0, 0, 1, 1}, 32, 16};
  s.eps = 0.25;
  s.cone_triangles = 9;
  return s;
}


// Opens stores of one engine: several on one database stand for replicas.
class Engine {
 public:
  Engine(const std::string& kind, Retention retention) : kind_(kind), retention_(retention) {
    static int databases = 0;
    if (kind_ == "postgres") {
      EXPECT_EQ(SharedPostgres().error(), "");
      url_ = SharedPostgres().NewDatabase("log" + std::to_string(++databases));
      EXPECT_NE(url_, "");
    }
  }
  const std::string& url() const { return url_; }
  std::unique_ptr<SceneStore> Open() {
    if (kind_ == "postgres") {
      PostgresStore::Options o;
      o.retention = retention_;
      auto s = PostgresStore::Open(url_, o);
      EXPECT_TRUE(s.ok()) << s.status();
      return s.ok() ? std::move(*s) : nullptr;
    }
    auto s = SqliteStore::Open(dir_.path() + "/data");
    EXPECT_TRUE(s.ok()) << s.status();
    if (!s.ok()) return nullptr;
    (*s)->set_retention(retention_);
    if (kind_ == "sqlite_packs") {
      // Change sets of two puts or more as packs, folded two sites at a time as they come.
      SqliteStore::Packing packing;
      packing.min_sites = 2;
      packing.fold_after = std::chrono::milliseconds(0);
      packing.fold_chunk = 2;
      packing.fold_idle = std::chrono::milliseconds(0);
      (*s)->set_packing(packing);
    }
    return std::move(*s);
  }

 private:
  std::string kind_;
  Retention retention_;
  TempDir dir_;
  std::string url_;
};

class LogStore : public ::testing::TestWithParam<std::string> {};

State StateOf(const StoredScene& s) {
  State out;
  for (const Site& site : SitesOf(s)) out[site.id] = site;
  return out;
}

void ExpectSame(const State& got, const State& want) {
  ASSERT_EQ(got.size(), want.size());
  for (const auto& [id, site] : want) {
    auto it = got.find(id);
    ASSERT_NE(it, got.end()) << id;
    EXPECT_TRUE(SameSite(it->second, site)) << id;
  }
}

// What a follower at `state` holds after applying `c`.
State Applied(State state, const SceneChanges& c) {
  if (c.complete) state.clear();
  for (const std::string& id : c.removed) state.erase(id);
  for (const auto& site : PutOf(c)) state[site->id] = *site;
  return state;
}

TEST_P(LogStore, ACommitFollowsTheStoredVersionOrIsRefused) {
  Engine engine(GetParam(), Retention());
  auto store = engine.Open();
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->CreateScene(Settings("s"), 1).ok());
  auto p = std::make_shared<const Site>(Site{"p", PointSite{{0.25, 0.5}}});
  auto q = std::make_shared<const Site>(Site{"q", PointSite{{0.75, 0.5}}});
  std::vector<std::shared_ptr<const Site>> put_p = {p}, put_q = {q};
  ASSERT_TRUE(store->Commit({"s", 2, put_p, {}}).ok());
  // A second writer that read version 1 is refused whole, and says so.
  absl::Status stale = store->Commit({"s", 2, put_q, {}});
  EXPECT_EQ(stale.code(), absl::StatusCode::kAborted) << stale;
  EXPECT_NE(std::string(stale.message()).find("at version 2"), std::string::npos) << stale;
  // Nor may a change skip versions.
  EXPECT_EQ(store->Commit({"s", 5, put_q, {}}).code(), absl::StatusCode::kAborted);
  // Nor be made for another incarnation of the scene (one deleted and made again).
  ChangeSet other{"s", 3, put_q, {}};
  auto heads0 = store->Heads();
  ASSERT_TRUE(heads0.ok());
  other.incarnation = (*heads0)[0].incarnation + 1;
  absl::Status made_again = store->Commit(other);
  EXPECT_EQ(made_again.code(), absl::StatusCode::kAborted) << made_again;
  EXPECT_NE(std::string(made_again.message()).find("made again"), std::string::npos);
  EXPECT_EQ(store->Commit({"absent", 2, put_q, {}}).code(), absl::StatusCode::kNotFound);
  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].version, 2u);
  ExpectSame(StateOf((*loaded)[0]), {{"p", *p}});
  auto heads = store->Heads();
  ASSERT_TRUE(heads.ok()) << heads.status();
  ASSERT_EQ(heads->size(), 1u);
  EXPECT_EQ((*heads)[0].version, 2u);
  EXPECT_EQ((*heads)[0].incarnation, (*loaded)[0].incarnation);
  EXPECT_NE((*heads)[0].incarnation, 0u);
}

// Servers creating one scene id at once: the engine lets exactly one succeed.
TEST_P(LogStore, CreationIsUniqueInTheEngine) {
  Engine engine(GetParam(), Retention());
  constexpr int kServers = 6;
  std::vector<std::unique_ptr<SceneStore>> stores;
  for (int i = 0; i < kServers; ++i) stores.push_back(engine.Open());
  for (int round = 0; round < 5; ++round) {
    const std::string id = "race" + std::to_string(round);
    std::atomic<int> made{0}, exists{0}, other{0};
    std::vector<std::thread> threads;
    for (int i = 0; i < kServers; ++i) {
      threads.emplace_back([&, i] {
        auto s = stores[i]->CreateScene(Settings(id), 1);
        if (s.ok()) {
          ++made;
        } else if (s.status().code() == absl::StatusCode::kAlreadyExists) {
          ++exists;
        } else {
          ++other;
          ADD_FAILURE() << s.status();
        }
      });
    }
    for (auto& t : threads) t.join();
    EXPECT_EQ(made.load(), 1);
    EXPECT_EQ(exists.load(), kServers - 1);
  }
}

// Random change sets with a small history window: for every version a follower could be
// at, what ReadChanges gives brings it to the latest state, by the net change or (past the
// horizon) the whole state.
TEST_P(LogStore, AFollowerAtAnyVersionCatchesUp) {
  Retention retention;
  retention.versions = 12;
  retention.every = 4;
  Engine engine(GetParam(), retention);
  auto store = engine.Open();
  ASSERT_NE(store, nullptr);
  std::mt19937_64 rng(29);
  auto made = store->CreateScene(Settings("s"), 1);
  ASSERT_TRUE(made.ok()) << made.status();
  std::vector<State> states(2);  // states[v]: the scene at version v
  for (uint64_t v = 2; v <= 60; ++v) {
    State next = states.back();
    std::vector<std::shared_ptr<const Site>> put;
    std::vector<std::string> removed;
    std::map<std::string, bool> touched;
    for (int k = 0, n = 1 + rng() % 6; k < n; ++k) {
      std::string id = "id" + std::to_string(rng() % 12);
      if (touched.count(id)) continue;
      touched[id] = true;
      if (next.count(id) && rng() % 2 == 0) {
        removed.push_back(id);
        next.erase(id);
      } else {
        auto site = std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id));
        put.push_back(site);
        next[id] = *site;
      }
    }
    ASSERT_TRUE(store->Commit({"s", v, put, removed}).ok()) << v;
    states.push_back(std::move(next));
  }
  const uint64_t head = states.size() - 1;
  for (uint64_t after = 0; after <= head; ++after) {
    SCOPED_TRACE(after);
    auto c = store->ReadChanges("s", after);
    ASSERT_TRUE(c.ok()) << c.status();
    EXPECT_EQ(c->version, head);
    EXPECT_EQ(c->incarnation, *made);
    EXPECT_EQ(c->settings.id, "s");
    ExpectSame(Applied(after == 0 ? State() : states[after], *c), states[head]);
    // Recent followers get the net change, not the whole state: the old tombstones are
    // gone (the horizon moved), the recent ones kept.
    if (after + retention.versions + retention.every <= head) {
      EXPECT_TRUE(c->complete);
    }
    if (after != 0 && after + retention.versions > head) {
      EXPECT_FALSE(c->complete);
    }
  }
  EXPECT_EQ(store->ReadChanges("absent", 0).status().code(), absl::StatusCode::kNotFound);
}

// A scene deleted and made again is another incarnation, with none of the old rows.
TEST_P(LogStore, ASceneMadeAgainIsANewIncarnation) {
  Engine engine(GetParam(), Retention());
  auto store = engine.Open();
  ASSERT_NE(store, nullptr);
  auto first = store->CreateScene(Settings("s"), 1);
  ASSERT_TRUE(first.ok());
  auto p = std::make_shared<const Site>(Site{"p", PointSite{{0.25, 0.5}}});
  std::vector<std::shared_ptr<const Site>> put = {p};
  ASSERT_TRUE(store->Commit({"s", 2, put, {}}).ok());
  ASSERT_TRUE(store->DeleteScene("s").ok());
  EXPECT_EQ(store->ReadChanges("s", 0).status().code(), absl::StatusCode::kNotFound);
  auto second = store->CreateScene(Settings("s"), 1);
  ASSERT_TRUE(second.ok());
  EXPECT_NE(*first, *second);
  auto c = store->ReadChanges("s", 0);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->incarnation, *second);
  EXPECT_EQ(c->version, 1u);
  EXPECT_TRUE(PutOf(*c).empty());
}

// Writers on several servers race for one scene: every version is given once, in order, and
// the stored state is the acknowledged changes applied in version order, whether each was
// committed sync or relaxed.
TEST_P(LogStore, RacingWritersGetDistinctOrderedVersions) {
  Engine engine(GetParam(), Retention());
  constexpr int kServers = 3, kWrites = 40;
  std::vector<std::unique_ptr<SceneStore>> stores;
  for (int i = 0; i < kServers; ++i) stores.push_back(engine.Open());
  ASSERT_TRUE(stores[0]->CreateScene(Settings("s"), 1).ok());
  std::mutex mu;
  std::map<uint64_t, std::vector<std::shared_ptr<const Site>>> acknowledged;
  std::atomic<int> refused{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < kServers; ++i) {
    threads.emplace_back([&, i] {
      std::mt19937_64 rng(7 + i);
      for (int w = 0; w < kWrites; ++w) {
        auto head = stores[i]->ReadChanges("s", 1);
        ASSERT_TRUE(head.ok()) << head.status();
        std::vector<std::shared_ptr<const Site>> put = {std::make_shared<const Site>(
            RandomSite(rng, static_cast<int>(rng()), "id" + std::to_string(rng() % 8)))};
        ChangeSet change{"s", head->version + 1, put, {}};
        change.durability = rng() % 2 ? Durability::kRelaxed : Durability::kSync;
        absl::Status s = stores[i]->Commit(change);
        if (s.ok()) {
          std::lock_guard<std::mutex> lock(mu);
          EXPECT_TRUE(acknowledged.emplace(head->version + 1, put).second);
        } else {
          EXPECT_EQ(s.code(), absl::StatusCode::kAborted) << s;
          ++refused;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  State want;
  uint64_t expected = 2;
  for (const auto& [version, put] : acknowledged) {
    EXPECT_EQ(version, expected++);  // no gaps
    for (const auto& site : put) want[site->id] = *site;
  }
  auto loaded = stores[1]->Load();
  ASSERT_TRUE(loaded.ok());
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].version, expected - 1);
  ExpectSame(StateOf((*loaded)[0]), want);
  std::printf("%zu acknowledged, %d refused\n", acknowledged.size(), refused.load());
}

// The digest of a state's sites as digest.h defines it: the first eight bytes, big-endian,
// of each site's SHA-256 (OpenSSL's one-shot call), XORed.
uint64_t DigestOf(const State& state) {
  uint64_t digest = 0;
  for (const auto& [id, site] : state) {
    const std::string bytes = EncodeSite(site);
    unsigned char md[SHA256_DIGEST_LENGTH];
    SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), md);
    uint64_t d = 0;
    for (int i = 0; i < 8; ++i) d = d << 8 | md[i];
    digest ^= d;
  }
  return digest;
}

// One value of a query run in the database itself, as text ("" on failure).
std::string Query(const std::string& url, const std::string& sql) {
  PGconn* c = PQconnectdb(url.c_str());
  PGresult* r = PQexec(c, sql.c_str());
  std::string out;
  if (PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) == 1) out = PQgetvalue(r, 0, 0);
  if (PQresultStatus(r) != PGRES_TUPLES_OK && PQresultStatus(r) != PGRES_COMMAND_OK) {
    ADD_FAILURE() << sql << ": " << PQresultErrorMessage(r);
  }
  PQclear(r);
  PQfinish(c);
  return out;
}

// PostgreSQL keeps each scene's digest (server/store/digest.h) through random changes that
// put, replace and remove sites: the heads and the log say the digest of the rows the scene
// holds, as the database computes it from them and as the test computes it from its model.
// A change made on other sites than the scene's is refused whole.
TEST(PostgresDigest, FollowsTheRowsAndRefusesChangesMadeOnOtherSites) {
  Engine engine("postgres", Retention());
  auto store = engine.Open();
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->CreateScene(Settings("s"), 1).ok());
  std::mt19937_64 rng(91);
  State state;
  for (uint64_t version = 2; version < 60; ++version) {
    std::vector<std::shared_ptr<const Site>> put;
    std::vector<std::string> removed;
    std::set<std::string> named;
    for (int i = 0, n = 1 + rng() % 4; i < n; ++i) {
      const std::string id = "id" + std::to_string(rng() % 10);
      if (!named.insert(id).second) continue;
      if (rng() % 3 == 0 && state.count(id)) {
        removed.push_back(id);
      } else {
        put.push_back(std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id)));
      }
    }
    ChangeSet change{"s", version, put, removed};
    change.base_digest = DigestOf(state);
    if (version % 7 == 0) {
      ChangeSet wrong = change;
      wrong.base_digest = *change.base_digest ^ 1;
      absl::Status refused = store->Commit(wrong);
      EXPECT_EQ(refused.code(), absl::StatusCode::kAborted) << refused;
      EXPECT_NE(std::string(refused.message()).find("holds other sites"), std::string::npos)
          << refused;
    }
    ASSERT_TRUE(store->Commit(change).ok()) << version;
    for (const std::string& id : removed) state.erase(id);
    for (const auto& site : put) state[site->id] = *site;
    auto heads = store->Heads();
    ASSERT_TRUE(heads.ok()) << heads.status();
    ASSERT_TRUE((*heads)[0].digest.has_value());
    EXPECT_EQ(*(*heads)[0].digest, DigestOf(state)) << version;
    auto log = store->ReadChanges("s", version - 1);
    ASSERT_TRUE(log.ok()) << log.status();
    EXPECT_EQ(log->digest, DigestOf(state)) << version;
  }
  // And as PostgreSQL computes it from the rows the scene holds now.
  const std::string url = engine.url();
  EXPECT_EQ(Query(url, "SELECT digest::text FROM gvd_scene WHERE id = 's'"),
            Query(url, "SELECT coalesce(bit_xor(('x' || left(encode(sha256(site), 'hex'), 16))"
                       "::bit(64)::int8), 0)::text FROM gvd_site WHERE scene = 's' "
                       "AND site <> ''::bytea"));
}

// A database of schema version 1 (no digests) gains each scene's digest when a store of
// this release opens it.
TEST(PostgresDigest, AVersion1DatabaseGainsItsScenesDigests) {
  Engine engine("postgres", Retention());
  State state;
  {
    auto store = engine.Open();
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->CreateScene(Settings("s"), 1).ok());
    std::mt19937_64 rng(5);
    std::vector<std::shared_ptr<const Site>> put;
    for (int i = 0; i < 30; ++i) {
      put.push_back(std::make_shared<const Site>(
          RandomSite(rng, static_cast<int>(rng()), "id" + std::to_string(i))));
      state[put.back()->id] = *put.back();
    }
    ASSERT_TRUE(store->Commit({"s", 2, put, {}}).ok());
    std::vector<std::string> removed = {"id3", "id7"};
    ASSERT_TRUE(store->Commit({"s", 3, {}, removed}).ok());
    state.erase("id3");
    state.erase("id7");
  }
  Query(engine.url(), "ALTER TABLE gvd_scene DROP COLUMN digest");
  Query(engine.url(), "UPDATE gvd_schema SET version = 1");
  auto store = engine.Open();
  ASSERT_NE(store, nullptr);
  auto heads = store->Heads();
  ASSERT_TRUE(heads.ok()) << heads.status();
  ASSERT_EQ(heads->size(), 1u);
  EXPECT_EQ((*heads)[0].digest, DigestOf(state));
  EXPECT_EQ(Query(engine.url(), "SELECT max(version)::text FROM gvd_schema"), "2");
}

INSTANTIATE_TEST_SUITE_P(Engines, LogStore, ::testing::Values("sqlite", "sqlite_packs", "postgres"),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace gvd
