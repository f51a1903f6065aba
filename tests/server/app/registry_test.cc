// The application core in process, with no transport (this binary links no gRPC and no GL:
// ctest's app_links_no_grpc and app_links_no_gl check): scenes created, written, read at a version, deleted; the write
// path's refusals (budget, limits, a failing store) leave nothing half applied; the store
// keeps what was acknowledged; a change committed elsewhere enters through Apply. Answers
// are judged by the tests' own oracle (tests/support/oracle.h).
#include <gtest/gtest.h>
#include <pthread.h>

#include <cstdlib>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "server/app/jobs.h"
#include "render/plan/volume_renderer.h"
#include "server/app/registry.h"
#include "server/store/sqlite_store.h"
#include "tests/server/app/registry_support.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle.h"
#include "tests/support/oracle3.h"
#include "tests/support/stored_sites.h"

namespace gvd {
namespace {

using testing::TempDir;

// A store that refuses every commit after the first `allowed`, and counts what it took.
class FlakyStore final : public SceneStore {
 public:
  explicit FlakyStore(int allowed) : allowed_(allowed) {}
  absl::StatusOr<std::vector<StoredScene>> Load() override { return std::vector<StoredScene>(); }
  absl::StatusOr<uint64_t> CreateScene(const SceneSettings&, uint64_t) override {
    if (auto s = Take(); !s.ok()) return s;
    return 1;
  }
  absl::Status Commit(const ChangeSet&) override { return Take(); }
  absl::Status DeleteScene(std::string_view) override { return Take(); }
  std::string Describe() const override { return "flaky"; }
  int committed() const { return committed_; }

 private:
  absl::Status Take() {
    if (committed_ >= allowed_) return absl::UnavailableError("the disk is gone");
    ++committed_;
    return absl::OkStatus();
  }
  const int allowed_;
  int committed_ = 0;
};

// A registry on a store in memory with no renderer: no frame ever comes.
struct InMemory {
  std::unique_ptr<SqliteStore> store = std::move(*SqliteStore::Open(":memory:"));
  SceneRegistry registry{store.get(), {}, ServerLimits{}};
  InMemory() { EXPECT_TRUE(registry.Load().ok()); }
};

TEST(SceneRegistry, AWaitingReadFailsWhenItsSceneIsDeleted) {
  // No renderer: no frame ever comes, so the read waits until the scene goes.
  InMemory in_memory;
  SceneRegistry& registry = in_memory.registry;
  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok());
  // Weighted: the index does not answer in place of the frame.
  Site a = Point("a", 0.2, 0.2);
  a.additive = 0.1;
  ASSERT_TRUE(registry.UpsertSites("s", {a}).ok());
  auto job = NearestJob::Make(&registry, *scene, {{{0.5, 0.5}}, false, false, true, 2}, nullptr);
  std::promise<absl::Status> done;
  job->Start([&](const absl::Status& s) { done.set_value(s); });
  auto pending = done.get_future();
  EXPECT_EQ(pending.wait_for(std::chrono::milliseconds(50)), std::future_status::timeout);
  ASSERT_TRUE(registry.DeleteScene("s").ok());
  ASSERT_EQ(pending.wait_for(std::chrono::seconds(60)), std::future_status::ready);
  const absl::Status s = pending.get();
  EXPECT_EQ(s.code(), absl::StatusCode::kNotFound) << s;
}

// The policy for a raster read of a version committed but never rendered (no renderer here,
// so no frame ever comes): up to 64 points in a NEAREST scene of plain sites are answered
// through the index, exactly, at the latest version; 65 points, a weighted site or a FARTHEST
// scene wait for the frame.
TEST(SceneRegistry, CommittedVersionsAreAnsweredThroughTheIndexWhereThatIsCheap) {
  InMemory in_memory;
  SceneRegistry& registry = in_memory.registry;
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site> sites;
  for (int i = 0; i < 500; ++i) {
    sites.push_back(i % 2 ? Point("p" + std::to_string(i), u(rng), u(rng))
                          : Site{"s" + std::to_string(i),
                                 SegmentSite{{u(rng), u(rng)}, {u(rng), u(rng)}}});
  }
  auto starts = [&](const std::string& id, Diagram diagram, const std::vector<Site>& put,
                    size_t points) {
    SceneSettings settings = Settings(id);
    settings.diagram = diagram;
    auto scene = As(registry.CreateScene(settings));
    EXPECT_TRUE(scene.ok());
    auto v = registry.UpsertSites(id, put);
    EXPECT_TRUE(v.ok());
    std::vector<Vec2> q;
    for (size_t i = 0; i < points; ++i) q.push_back({u(rng), u(rng)});
    auto job = NearestJob::Make(&registry, *scene, {q, false, false, true, *v}, nullptr);
    auto done = std::make_shared<std::promise<absl::Status>>();
    job->Start([done](const absl::Status& s) { done->set_value(s); });
    auto answered = done->get_future();
    const bool now = answered.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
    if (now) {
      EXPECT_TRUE(answered.get().ok());
      EXPECT_EQ(job->version(), *v);
      for (size_t i = 0; i < q.size(); ++i) {
        const AnswerRow& row = job->rows()[i];
        const oracle::Best best = oracle::BestSite(q[i], put);
        EXPECT_TRUE(row.exact);
        EXPECT_EQ(*row.site_id, put[best.index].id);
        EXPECT_NEAR(row.distance, best.value, oracle::Tolerance(q[i], best.value));
      }
    }
    EXPECT_TRUE(registry.DeleteScene(id).ok());
    return now;
  };
  EXPECT_TRUE(starts("plain", Diagram::kNearest, sites, 64));
  EXPECT_FALSE(starts("many", Diagram::kNearest, sites, 65));
  EXPECT_FALSE(starts("far", Diagram::kFarthest, sites, 1));
  sites[7].additive = 0.01;
  EXPECT_FALSE(starts("weighted", Diagram::kNearest, sites, 1));
}

TEST(SceneRegistry, ExactAnswersNeedNoFrame) {
  // Sites of several kinds, weighted, in a FARTHEST scene too; no renderer at all.
  InMemory in_memory;
  SceneRegistry& registry = in_memory.registry;
  for (Diagram diagram : {Diagram::kNearest, Diagram::kFarthest}) {
    SceneSettings settings = Settings(diagram == Diagram::kNearest ? "near" : "far");
    settings.diagram = diagram;
    auto scene = As(registry.CreateScene(settings));
    ASSERT_TRUE(scene.ok());
    std::vector<Site> sites = {Point("a", 0.1, 0.1), Point("b", 0.9, 0.2),
                               {"seg", SegmentSite{{0.2, 0.8}, {0.7, 0.9}}, 0.05, 1.5},
                               {"poly", PolygonSite{{{0.4, 0.4}, {0.6, 0.4}, {0.5, 0.6}}}}};
    ASSERT_TRUE(registry.UpsertSites(settings.id, sites).ok());
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-0.2, 1.2);
    std::vector<Vec2> points;
    for (int i = 0; i < 3000; ++i) points.push_back({u(rng), u(rng)});  // past the batch cut
    auto job = NearestJob::Make(&registry, *scene, {points, true, false, true, 0}, nullptr);
    ASSERT_TRUE(RunJob(job).ok());
    for (size_t i = 0; i < points.size(); ++i) {
      const oracle::Best best = oracle::BestSite(points[i], sites, diagram);
      const AnswerRow& row = job->rows()[i];
      ASSERT_NE(row.site_id, nullptr);
      EXPECT_TRUE(row.exact);
      EXPECT_NEAR(row.distance, best.value, oracle::Tolerance(points[i], best.value, 1.5))
          << settings.id << " at (" << points[i].x << ", " << points[i].y << ")";
    }
  }
}

TEST(SceneRegistry, BudgetAndLimitsRefuseBeforeAnythingIsStored) {
  TempDir dir;
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok());
  ServerLimits limits;
  limits.max_scenes = 2;
  limits.max_sites_per_scene = 3;
  // Two 64x64 rasters and a few sites fit; a 512x512 raster does not.
  limits.max_memory = 2 * Scene::RasterBytes(Settings("x")) + 8000;
  SceneRegistry registry(store->get(), {}, limits);
  ASSERT_TRUE(registry.Load().ok());

  auto big = registry.CreateScene(Settings("big", 512));
  EXPECT_EQ(big.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(big.status().message().find("--max-memory"), std::string::npos) << big.status();
  ASSERT_TRUE(registry.CreateScene(Settings("a")).ok());
  ASSERT_TRUE(registry.CreateScene(Settings("b")).ok());
  auto third = registry.CreateScene(Settings("c", 8));
  EXPECT_EQ(third.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(third.status().message().find("--max-scenes"), std::string::npos) << third.status();

  ASSERT_TRUE(registry.UpsertSites("a", {Point("p", 0.5, 0.5)}).ok());
  const uint64_t used = registry.memory_used();
  // Past the budget: 100 sites with long ids.
  std::vector<Site> many;
  for (int i = 0; i < 100; ++i) many.push_back(Point(std::string(200, 'x') + std::to_string(i), 0, 0));
  auto over = registry.UpsertSites("b", many);
  EXPECT_EQ(over.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(over.status().message().find("--max-memory"), std::string::npos) << over.status();
  // Past --max-sites-per-scene.
  auto crowded = registry.UpsertSites("a", {Point("q", 0, 0), Point("r", 0, 1), Point("s", 1, 0)});
  EXPECT_EQ(crowded.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(crowded.status().message().find("--max-sites-per-scene"), std::string::npos);
  EXPECT_EQ(registry.memory_used(), used);  // every reservation was given back

  // What the store holds: the two scenes, "a" at version 2 with its one site, "b" empty.
  auto stored = (*store)->Load();
  ASSERT_TRUE(stored.ok()) << stored.status();
  ASSERT_EQ(stored->size(), 2u);
  EXPECT_EQ((*stored)[0].settings.id, "a");
  EXPECT_EQ((*stored)[0].version, 2u);
  const std::vector<Site> sites = testing::SitesOf((*stored)[0]);
  ASSERT_EQ(sites.size(), 1u);
  EXPECT_EQ(sites[0].id, "p");
  EXPECT_EQ((*stored)[1].version, 1u);
  EXPECT_EQ((*stored)[1].site_count(), 0u);
}

TEST(SceneRegistry, AFailedCommitChangesNothing) {
  FlakyStore store(/*allowed=*/2);  // the scene and one write
  SceneRegistry registry(&store, {}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok());
  ASSERT_TRUE(registry.UpsertSites("s", {Point("a", 0.1, 0.1)}).ok());
  const uint64_t used = registry.memory_used();
  auto failed = registry.UpsertSites("s", {Point("b", 0.2, 0.2), Point("a", 0.9, 0.9)});
  EXPECT_EQ(failed.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ((*scene)->version(), 2u);
  EXPECT_EQ((*scene)->site_count(), 1u);
  EXPECT_EQ(std::get<PointSite>((*scene)->snapshot()->sites().get(0)->geometry).p.x, 0.1);
  EXPECT_EQ(registry.memory_used(), used);
  EXPECT_EQ(registry.DeleteScene("s").code(), absl::StatusCode::kUnavailable);
  EXPECT_TRUE(registry.Find("s").ok());  // still there
  auto refused = registry.CreateScene(Settings("t"));
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(registry.Find("t").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store.committed(), 2);
}

TEST(SceneRegistry, LoadsWhatFitsAndKeepsTheRestStored) {
  TempDir dir;
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok());
    SceneRegistry registry(store->get(), {}, ServerLimits{});
    ASSERT_TRUE(registry.Load().ok());
    ASSERT_TRUE(registry.CreateScene(Settings("a")).ok());
    ASSERT_TRUE(registry.CreateScene(Settings("b")).ok());
    ASSERT_TRUE(registry.UpsertSites("b", {Point("p", 0.3, 0.3), Point("q", 0.6, 0.6)}).ok());
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok());
  ServerLimits limits;
  limits.max_memory = Scene::RasterBytes(Settings("x")) + 100;  // one empty scene fits
  SceneRegistry registry(store->get(), {}, limits);
  ASSERT_TRUE(registry.Load().ok()) << registry.Load();
  EXPECT_TRUE(registry.Find("a").ok());
  auto b = registry.Find("b");
  EXPECT_EQ(b.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(b.status().message().find("--max-memory"), std::string::npos) << b.status();
  auto listed = registry.List();
  ASSERT_EQ(listed.size(), 2u);
  EXPECT_EQ(listed[0].id(), "a");
  ASSERT_TRUE(listed[1].unloaded.has_value());
  EXPECT_EQ(listed[1].unloaded->version, 2u);
  EXPECT_EQ(listed[1].unloaded->sites, 2u);
  ASSERT_TRUE(registry.DeleteScene("b").ok());
  EXPECT_EQ(registry.Describe("b").status().code(), absl::StatusCode::kNotFound);
  auto stored = (*store)->Load();
  ASSERT_TRUE(stored.ok()) << stored.status();
  EXPECT_EQ(stored->size(), 1u);
}

TEST(SceneRegistry, AChangeCommittedElsewhereEntersThroughApply) {
  InMemory in_memory;
  SceneRegistry& registry = in_memory.registry;
  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok());
  ASSERT_TRUE(registry.UpsertSites("s", {Point("a", 0.1, 0.1), Point("b", 0.2, 0.2)}).ok());
  // Version 3, as another server would have committed it: b moved, a removed.
  const std::vector<std::shared_ptr<const Site>> put = {
      std::make_shared<const Site>(Point("b", 0.8, 0.8))};
  const std::vector<std::string> removed = {"a"};
  // Committed by the other server (a store's commit is a conditional append: the next local
  // write follows version 3 there too).
  ASSERT_TRUE(in_memory.store->Commit({"s", 3, put, removed}).ok());
  auto applied = registry.Apply({"s", 3, put, removed});
  ASSERT_TRUE(applied.ok()) << applied.status();
  EXPECT_EQ(*applied, 3u);
  auto snapshot = (*scene)->snapshot();
  EXPECT_EQ(snapshot->size(), 1u);
  EXPECT_FALSE(snapshot->Find("a").has_value());
  ASSERT_TRUE(snapshot->Find("b").has_value());
  EXPECT_EQ(std::get<PointSite>(snapshot->sites().get(*snapshot->Find("b"))->geometry).p.x, 0.8);
  // Out of order, or removing what is not there: refused, nothing changes.
  auto early = registry.Apply({"s", 5, put, {}});
  EXPECT_EQ(early.status().code(), absl::StatusCode::kFailedPrecondition);
  auto unknown = registry.Apply({"s", 4, {}, removed});
  EXPECT_EQ(unknown.status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ((*scene)->version(), 3u);
  EXPECT_EQ((*scene)->snapshot(), snapshot);
  // The local write path goes on from there.
  auto next = registry.UpsertSites("s", {Point("c", 0.5, 0.5)});
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(*next, 4u);
}

// ---- 3D scenes ----

SceneSettings Settings3(const std::string& id) {
  SceneSettings s = Settings(id, 12);
  s.grid.window = {0, 0, 3, 3};
  s.depth = 10;
  s.min_z = 0;
  s.max_z = 2.5;
  return s;
}

template <class J>
absl::Status Run3(const std::shared_ptr<J>& job) {
  std::promise<absl::Status> done;
  job->Start([&](const absl::Status& s) { done.set_value(s); });
  return done.get_future().get();
}

// A 3D scene through the application core: created, written, read at a version (raster
// answers within their bounds, exact ones equal to the oracle, with closest points), kept
// by the store and rendered again after a reload; 2D calls on it, and 3D calls on a 2D
// scene, are refused by name.
TEST(SceneRegistry, A3DSceneFromCreateToReload) {
  TempDir dir;
  std::vector<Site3> sites = {{"p", PointSite3{{0.5, 0.5, 0.5}}},
                              {"s", SegmentSite3{{2, 0, 0}, {2, 3, 2.5}}},
                              {"ball", Placed(Icosphere(2), {1.5, 2, 1.5}, 0.6)}};
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-0.5, 3.5);
  std::vector<Vec3> points;
  for (int i = 0; i < 1000; ++i) points.push_back({u(rng), u(rng), u(rng) * 0.75});
  auto oracle = [&](Vec3 q) {
    oracle3::Real best = INFINITY;
    for (const Site3& s : sites) best = std::min(best, oracle3::ToGeometry(q, s.geometry));
    return double(best);
  };
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok());
    VolumeRenderer volumes;
    SceneRegistry registry(store->get(), {nullptr, &volumes}, ServerLimits{});
    ASSERT_TRUE(registry.Load().ok());
    ASSERT_TRUE(registry.CreateScene(Settings("flat")).ok());
    auto scene = As<Scene3>(registry.CreateScene(Settings3("space")));
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ(registry.CreateScene(Settings("space")).status().code(), absl::StatusCode::kAlreadyExists);
    EXPECT_EQ(As<Scene>(registry.Find("space")).status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_EQ(As<Scene3>(registry.Find("flat")).status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_EQ(registry.UpsertSites("flat", sites).status().code(), absl::StatusCode::kFailedPrecondition);
    auto version = registry.UpsertSites("space", sites);
    ASSERT_TRUE(version.ok()) << version.status();

    auto job = BasicNearestJob<Scene3>::Make(&registry, *scene, {points, false, false, true, *version, true}, nullptr);
    ASSERT_TRUE(Run3(job).ok());
    ASSERT_EQ(job->rows().size(), points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      const AnswerRow& r = job->rows()[i];
      ASSERT_NE(r.site_id, nullptr);
      const double best = oracle(points[i]);
      EXPECT_LE(r.distance - best, r.error_bound + 1e-9) << i;
      EXPECT_GE(r.distance, best - 1e-9);
      EXPECT_NEAR(Distance(job->closest()[i], points[i]), r.distance, 1e-9);
    }
    auto exact = BasicNearestJob<Scene3>::Make(&registry, *scene, {points, true, false, true, 0}, nullptr);
    ASSERT_TRUE(Run3(exact).ok());
    for (size_t i = 0; i < points.size(); ++i) {
      EXPECT_NEAR(exact->rows()[i].distance, oracle(points[i]), 1e-9);
      EXPECT_TRUE(exact->rows()[i].exact);
    }
    // A committed change of the other dimension's sites is refused whole.
    const std::vector<std::shared_ptr<const Site>> flat = {std::make_shared<const Site>(Point("q", 1, 1))};
    const std::vector<std::string> gone = {"p"};
    ChangeSet wrong{"space", *version + 1, flat, gone};
    EXPECT_EQ(registry.Apply(wrong).status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_EQ((*scene)->version(), *version);
    EXPECT_TRUE((*scene)->snapshot()->Find("p").has_value());
    ASSERT_TRUE(registry.DeleteSites("space", {"p"}).ok());
    sites.erase(sites.begin());
    EXPECT_EQ(registry.List().size(), 2u);
  }
  // Reloaded: the scene and its sites are back, and render again.
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok());
  VolumeRenderer volumes;
  SceneRegistry registry(store->get(), {nullptr, &volumes}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  auto scene = As<Scene3>(registry.Find("space"));
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ((*scene)->version(), 3u);
  EXPECT_EQ((*scene)->settings().depth, 10u);
  auto read = registry.ReadVersion(**scene, 0);
  ASSERT_TRUE(read.ok());
  auto job = BasicNearestJob<Scene3>::Make(&registry, *scene, {points, false, false, true, *read}, nullptr);
  ASSERT_TRUE(Run3(job).ok());
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_LE(job->rows()[i].distance - oracle(points[i]), job->rows()[i].error_bound + 1e-9);
  }
  ASSERT_TRUE(registry.DeleteScene("space").ok());
  EXPECT_EQ(registry.Find("space").status().code(), absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace gvd
