// The application core with the GL render threads behind its render seam (llvmpipe without a
// GPU): reads at a version wait for their frames and answer as the oracle does, and the work
// that must not block a transport's thread runs on the CPU pool. (The other core tests,
// gvd_app_tests, link no GL.)
#include <gtest/gtest.h>
#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "render/gl/render_loop.h"
#include "server/app/jobs.h"
#include "server/app/registry.h"
#include "server/store/sqlite_store.h"
#include "tests/server/app/registry_support.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

// The render threads on the EGL device, as the server runs them (llvmpipe without a GPU),
// `lanes` of them resting `background_rest` times a render nobody waits for: null, after
// skipping, when no context can be made, unless GVD_REQUIRE_GL is set.
std::unique_ptr<RenderLoop> StartRenderer(int lanes = 1, double background_rest = kBackgroundRest) {
  auto renderer = std::make_unique<RenderLoop>(lanes, nullptr, background_rest);
  absl::Status s = renderer->Start(DevicePreference::kAuto);
  if (s.ok()) return renderer;
  const char* required = std::getenv("GVD_REQUIRE_GL");
  if (required != nullptr && *required != '\0' && std::string(required) != "0") {
    ADD_FAILURE() << "no EGL context, and GVD_REQUIRE_GL is set: " << s;
  } else {
    GTEST_LOG_(INFO) << "no EGL context: " << s;
  }
  return nullptr;
}

// Whether the scene's frame reaches `version` within a minute, found by polling the frame:
// nobody waits on a render (RenderWait), which would end the render threads' rests.
template <class S>
bool Drawn(const S& scene, uint64_t version) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (scene.frame()->version() < version) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

TEST(SceneRegistry, CreateWriteReadAtAVersionDelete) {
  auto renderer = StartRenderer();
  if (!renderer) GTEST_SKIP() << "no EGL context";
  auto store = SqliteStore::Open(":memory:");
  ASSERT_TRUE(store.ok());
  SceneRegistry registry(store->get(), {renderer.get()}, ServerLimits{});
  EXPECT_FALSE(registry.loaded());
  ASSERT_TRUE(registry.Load().ok());
  EXPECT_TRUE(registry.loaded());

  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ((*scene)->version(), 1u);
  EXPECT_EQ(registry.CreateScene(Settings("s")).status().code(),
            absl::StatusCode::kAlreadyExists);

  // Sites: 200 random points, then a move of one of them.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site> sites;
  for (int i = 0; i < 200; ++i) sites.push_back(Point("p" + std::to_string(i), u(rng), u(rng)));
  auto v2 = registry.UpsertSites("s", sites);
  ASSERT_TRUE(v2.ok()) << v2.status();
  EXPECT_EQ(*v2, 2u);
  sites[17] = Point("p17", 0.5, 0.5);
  auto v3 = registry.UpsertSites("s", {sites[17]});
  ASSERT_TRUE(v3.ok()) << v3.status();
  EXPECT_EQ(*v3, 3u);

  // A read at version 3 waits for its frame, then answers as the oracle does.
  std::vector<Vec2> points;
  for (int i = 0; i < 2000; ++i) points.push_back({u(rng), u(rng)});
  auto version = registry.ReadVersion(**scene, 3);
  ASSERT_TRUE(version.ok());
  auto job = NearestJob::Make(&registry, *scene, {points, false, false, true, *version}, nullptr);
  ASSERT_TRUE(RunJob(job).ok());
  EXPECT_GE(job->version(), 3u);
  ASSERT_EQ(job->rows().size(), points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const oracle::Best best = oracle::BestSite(points[i], sites);
    const AnswerRow& row = job->rows()[i];
    ASSERT_NE(row.site_id, nullptr);
    // The site answered is within the bound of the best, and its distance is exact.
    EXPECT_LE(row.distance - row.error_bound, best.value + oracle::Tolerance(points[i], best.value));
    const Site& answered = *std::find_if(sites.begin(), sites.end(),
                                         [&](const Site& s) { return s.id == *row.site_id; });
    EXPECT_NEAR(row.distance, oracle::Distance(points[i], answered.geometry),
                oracle::Tolerance(points[i], row.distance));
  }
  // A version not reached is OUT_OF_RANGE, naming it.
  auto ahead = registry.ReadVersion(**scene, 9);
  EXPECT_EQ(ahead.status().code(), absl::StatusCode::kOutOfRange);
  EXPECT_NE(ahead.status().message().find("min_version 9"), std::string::npos);

  // Deleting an unknown id changes nothing: NOT_FOUND, naming it.
  auto refused = registry.DeleteSites("s", {"p1", "nobody"});
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(refused.status().message().find("\"nobody\""), std::string::npos);
  EXPECT_EQ((*scene)->version(), 3u);
  EXPECT_EQ((*scene)->site_count(), 200u);

  ASSERT_TRUE(registry.DeleteScene("s").ok());
  EXPECT_EQ(registry.Find("s").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(registry.DeleteScene("s").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(registry.UpsertSites("s", {Point("a", 0, 0)}).status().code(),
            absl::StatusCode::kNotFound);
  renderer->Stop();
}

// After a render nobody waited for, the render thread rests (here 10^12 times the render's
// time, so that no machine's speed decides it): a change meanwhile stays undrawn, until a
// caller begins to wait for a frame, which has it at once, or a watched scene changes.
TEST(SceneRegistry, RendersNobodyWaitsForOrWatchesRest) {
  auto renderer = StartRenderer(1, 1e12);
  if (!renderer) GTEST_SKIP() << "no EGL context";
  auto store = SqliteStore::Open(":memory:");
  ASSERT_TRUE(store.ok());
  SceneRegistry registry(store->get(), {renderer.get()}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_TRUE(registry.UpsertSites("s", {Point("a", 0.2, 0.3), Point("b", 0.7, 0.6),
                                         Point("c", 0.4, 0.9)}).ok());  // version 2
  // Past kInlineExactPoints, so that a read at a version not drawn waits for its frame.
  std::vector<Vec2> points(NearestJob::kInlineExactPoints + 1, Vec2{0.65, 0.45});
  // A read at `version` (a caller waits), within a minute: far sooner than a rest, far later
  // than any render of three sites.
  auto read = [&](uint64_t version) {
    auto done = std::make_shared<std::promise<absl::Status>>();
    auto job = NearestJob::Make(&registry, *scene, {points, false, false, true, version}, nullptr);
    job->Start([done](const absl::Status& s) { done->set_value(s); });
    auto answered = done->get_future();
    if (answered.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
      return std::make_pair(absl::DeadlineExceededError("no frame within 60 s"), job);
    }
    return std::make_pair(answered.get(), job);
  };
  auto drawn = [&](uint64_t version) { return Drawn(**scene, version); };
  auto [first, first_job] = read(2);
  ASSERT_TRUE(first.ok()) << first;
  EXPECT_EQ(*first_job->rows()[0].site_id, "b");

  // A change after an awaited render is drawn though nobody waits (no rest yet); the next
  // one waits out the rest that follows that render.
  ASSERT_TRUE(registry.UpsertSites("s", {Point("b", 0.7, 0.65)}).ok());  // version 3
  ASSERT_TRUE(drawn(3));
  ASSERT_TRUE(registry.UpsertSites("s", {Point("b", 0.1, 0.1)}).ok());  // version 4
  std::this_thread::sleep_for(std::chrono::seconds(1));
  EXPECT_EQ((*scene)->frame()->version(), 3u);

  // A caller waits for version 4: the rest ends, and the frame shows the move.
  auto [second, second_job] = read(4);
  ASSERT_TRUE(second.ok()) << second;
  EXPECT_GE(second_job->version(), 4u);
  EXPECT_EQ(*second_job->rows()[0].site_id, "a");  // 0.47 from (0.65, 0.45); c 0.52, b 0.65

  // Rest again (a render nobody waited for), then a watched scene's change ends the rest.
  ASSERT_TRUE(registry.UpsertSites("s", {Point("b", 0.15, 0.1)}).ok());  // version 5
  ASSERT_TRUE(drawn(5));
  std::mutex mu;
  std::condition_variable seen;
  uint64_t watched = 0;  // the newest frame the listener heard of
  const uint64_t token = (*scene)->Watch([&](const std::shared_ptr<const Frame>& f) {
    std::lock_guard<std::mutex> lock(mu);
    if (f) watched = f->version();
    seen.notify_all();
  });
  ASSERT_TRUE(registry.UpsertSites("s", {Point("b", 0.2, 0.1)}).ok());  // version 6
  {
    std::unique_lock<std::mutex> lock(mu);
    EXPECT_TRUE(seen.wait_for(lock, std::chrono::seconds(60), [&] { return watched >= 6; }))
        << "no frame of version 6 within 60 s; the newest heard of: " << watched;
  }
  (*scene)->Unwatch(token);
  renderer->Stop();
}

// Voluntary context switches of each of this process's threads named `name`, by thread id.
std::map<std::string, long> SwitchesOf(const std::string& name) {
  std::map<std::string, long> out;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string got;
    if (!std::getline(comm, got) || got != name) continue;
    std::ifstream status(task.path() / "status");
    for (std::string line; std::getline(status, line);) {
      if (line.rfind("voluntary_ctxt_switches:", 0) == 0) {
        out[task.path().filename()] = std::stol(line.substr(line.find(':') + 1));
      }
    }
  }
  return out;
}

// A scene marked dirty wakes the one render thread that takes it: its own, while that
// thread sleeps. The other sleeps on through a hundred moves, each drawn before the next
// (each thread's voluntary context switches, as the kernel counts them).
TEST(SceneRegistry, AMoveWakesOnlyTheRenderThreadThatDrawsIt) {
  auto renderer = StartRenderer(2, /*background_rest=*/0);
  if (!renderer) GTEST_SKIP() << "no EGL context";
  auto store = SqliteStore::Open(":memory:");
  ASSERT_TRUE(store.ok());
  SceneRegistry registry(store->get(), {renderer.get()}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  auto scene = As(registry.CreateScene(Settings("s")));
  ASSERT_TRUE(scene.ok()) << scene.status();
  // Drawn polls the frame: a caller waiting on a render would wake every render thread.
  auto drawn = [&](uint64_t version) { return Drawn(**scene, version); };
  auto version = registry.UpsertSites("s", {Point("a", 0.2, 0.3), Point("b", 0.7, 0.6)});
  ASSERT_TRUE(version.ok()) << version.status();
  ASSERT_TRUE(drawn(*version));
  const auto before = SwitchesOf("gvd-render");
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  for (int move = 0; move < 100; ++move) {
    version = registry.UpsertSites("s", {Point("b", u(rng), u(rng))});
    ASSERT_TRUE(version.ok()) << version.status();
    ASSERT_TRUE(drawn(*version)) << "move " << move << " not drawn within 60 s";
  }
  const auto after = SwitchesOf("gvd-render");
  std::vector<long> woken;
  for (const auto& [tid, switches] : after) {
    if (before.count(tid)) woken.push_back(switches - before.at(tid));
  }
  std::sort(woken.begin(), woken.end(), std::greater<>());
  ASSERT_GE(woken.size(), 2u);  // the two lanes, and threads of the GL driver's named after them
  // The lane that drew the moves slept and woke for each; every other thread of the name
  // (the other lane, and the driver's, which sleep through renders) hardly ever woke, where
  // waking every lane for each move wakes the other lane twice a move.
  EXPECT_GT(woken.front(), 0);
  long others = 0;
  for (size_t i = 1; i < woken.size(); ++i) others += woken[i];
  EXPECT_LT(others, 25) << "the other render threads woke " << others << " times in 100 moves";
  renderer->Stop();
}

// The name of the thread that calls it.
std::string ThreadName() {
  char name[32] = {};
  pthread_getname_np(pthread_self(), name, sizeof name);
  return name;
}

// A `cancelled` predicate that notes the threads that poll it: the threads a job's work runs
// on (answers poll it as they go, an encode before it starts).
struct Poller {
  std::mutex mu;
  std::set<std::string> threads;
  std::function<bool()> Fn() {
    return [this] {
      std::lock_guard<std::mutex> lock(mu);
      threads.insert(ThreadName());
      return false;
    };
  }
};

TEST(SceneRegistry, LargeBatchesAndImagesRunOnTheCpuPool) {
  auto renderer = StartRenderer();
  if (!renderer) GTEST_SKIP() << "no EGL context";
  // This thread stands for a transport's: what runs here is what would block it.
  pthread_setname_np(pthread_self(), "transport");
  auto store = SqliteStore::Open(":memory:");
  ASSERT_TRUE(store.ok());
  SceneRegistry registry(store->get(), {renderer.get()}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  SceneSettings far = Settings("far");
  far.diagram = Diagram::kFarthest;
  auto near_scene = As(registry.CreateScene(Settings("near")));
  auto far_scene = As(registry.CreateScene(far));
  ASSERT_TRUE(near_scene.ok() && far_scene.ok());
  std::vector<Site> sites = {Point("a", 0.2, 0.3), Point("b", 0.7, 0.6), Point("c", 0.4, 0.9)};
  ASSERT_TRUE(registry.UpsertSites("near", sites).ok());
  ASSERT_TRUE(registry.UpsertSites("far", sites).ok());
  std::vector<Vec2> one = {{0.5, 0.5}};
  std::vector<Vec2> many(NearestJob::kInlinePoints + 1, Vec2{0.5, 0.5});
  // Wait for both frames, so that the raster answers below find them ready on this thread.
  for (const auto& scene : {*near_scene, *far_scene}) {
    ASSERT_TRUE(RunJob(NearestJob::Make(&registry, scene, {one, false, false, true, 2}, nullptr)).ok());
  }
  struct Case {
    const char* what;
    std::function<std::shared_ptr<FrameJob>(std::function<bool()>)> job;
    const char* thread;  // where its work must run
  };
  const Case cases[] = {
      {"a raster batch past kInlinePoints",
       [&](auto c) { return NearestJob::Make(&registry, *near_scene, {many, false, false, true, 2}, c); },
       "gvd-cpu"},
      {"an exact batch past kInlineExactPoints",
       [&](auto c) { return NearestJob::Make(&registry, *near_scene, {many, true, false, true, 2}, c); },
       "gvd-cpu"},
      {"one exact answer in a FARTHEST scene (every site scored)",
       [&](auto c) { return NearestJob::Make(&registry, *far_scene, {one, true, false, true, 2}, c); },
       "gvd-cpu"},
      {"an image",
       [&](auto c) {
         ImageOptions options;
         options.rect = (*near_scene)->settings().grid.all();
         return ImageJob::Make(&registry, *near_scene, 2, options, c);
       },
       "gvd-cpu"},
      {"one exact answer in a NEAREST scene of points (O(log n))",
       [&](auto c) { return NearestJob::Make(&registry, *near_scene, {one, true, false, true, 2}, c); },
       "transport"},
  };
  for (const Case& c : cases) {
    Poller poller;
    ASSERT_TRUE(RunJob(c.job(poller.Fn())).ok()) << c.what;
    EXPECT_EQ(poller.threads, std::set<std::string>{c.thread}) << c.what;
  }
  renderer->Stop();
}

}  // namespace
}  // namespace gvd
