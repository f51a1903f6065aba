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

}  // namespace
}  // namespace gvd
