// The gRPC transport in process over the application core, on a real gRPC server on
// loopback: where the store calls of writes run. Creating and deleting scenes, large writes,
// writes while another is under way and writes to a store shared with replicas run on the
// core's commit threads ("gvd-commit"); a small write alone on a store of its own runs on
// the gRPC transport's one polling thread, "gvd-grpc" (Service::Write).
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <pthread.h>

#include <atomic>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "gvd/v1/voronoi.grpc.pb.h"
#include "server/app/registry.h"
#include "server/grpc/server.h"
#include "server/store/sqlite_store.h"

namespace gvd {
namespace {

// A store in memory that notes the threads its writes run on, says it is shared when told,
// and holds a commit of more than `hold_above` sites until `release` is set.
class RecordingStore final : public SceneStore {
 public:
  explicit RecordingStore(bool shared = false)
      : inner_(std::move(*SqliteStore::Open(":memory:"))), shared_(shared) {}
  bool shared() const override { return shared_; }
  absl::StatusOr<std::vector<StoredScene>> Load() override { return inner_->Load(); }
  absl::StatusOr<uint64_t> CreateScene(const SceneSettings& s, uint64_t v) override {
    Note();
    return inner_->CreateScene(s, v);
  }
  absl::Status Commit(const ChangeSet& c) override {
    Note();
    if (c.put_count() > hold_above.load()) {
      held.set_value();
      released.wait();
    }
    return inner_->Commit(c);
  }
  absl::Status DeleteScene(std::string_view id) override {
    Note();
    return inner_->DeleteScene(id);
  }
  std::string Describe() const override { return "recording"; }
  // The threads' names, in the order of the calls, and forgotten.
  std::vector<std::string> Take() {
    std::lock_guard<std::mutex> lock(mu_);
    return std::move(threads_);
  }

  // Atomic, and the promises' futures made here: the commit threads read them after the
  // test writes them, through gRPC's calls, which the thread sanitizer does not follow.
  std::atomic<size_t> hold_above{SIZE_MAX};
  std::promise<void> held, release;
  std::shared_future<void> released = release.get_future().share();

 private:
  void Note() {
    char name[32] = {};
    pthread_getname_np(pthread_self(), name, sizeof name);
    std::lock_guard<std::mutex> lock(mu_);
    threads_.push_back(name);
  }
  std::unique_ptr<SqliteStore> inner_;
  const bool shared_;
  std::mutex mu_;
  std::vector<std::string> threads_;
};

// A server of the core over `store` on loopback, and a stub to it.
struct Served {
  explicit Served(SceneStore* store) : registry(store, {}, ServerLimits{}), core(&registry) {
    EXPECT_TRUE(registry.Load().ok());
    server = std::move(*GrpcServer::Start(GrpcOptions{}, &core));
    stub = v1::VoronoiService::NewStub(grpc::CreateChannel(
        "127.0.0.1:" + std::to_string(server->port()), grpc::InsecureChannelCredentials()));
  }
  ~Served() { server->Shutdown(std::chrono::system_clock::now()); }

  void Create(const std::string& id) {
    v1::CreateSceneRequest create;
    create.set_scene_id(id);
    create.mutable_window()->set_max_x(1);
    create.mutable_window()->set_max_y(1);
    create.set_width_px(32);
    create.set_height_px(32);
    v1::CreateSceneResponse scene;
    grpc::ClientContext context;
    auto status = stub->CreateScene(&context, create, &scene);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }
  // Waits until the commit threads run no write: a write's answer may reach the client
  // before its commit thread is done with the job, and a write meanwhile would go to them.
  void Idle() {
    while (!registry.commits().RunHereIfIdle([] {})) std::this_thread::yield();
  }
  // Upserts `n` points named prefix0, prefix1, ...; the scene's new version.
  uint64_t Upsert(const std::string& id, const std::string& prefix, int n) {
    v1::UpsertSitesRequest upsert;
    upsert.set_scene_id(id);
    for (int k = 0; k < n; ++k) {
      auto* site = upsert.add_sites();
      site->set_id(prefix + std::to_string(k));
      site->mutable_point()->set_x((k % 97) / 97.0);
      site->mutable_point()->set_y((k % 89) / 89.0);
    }
    v1::UpsertSitesResponse upserted;
    grpc::ClientContext context;
    auto status = stub->UpsertSites(&context, upsert, &upserted);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return upserted.version();
  }

  SceneRegistry registry;
  Service core;
  std::unique_ptr<GrpcServer> server;
  std::unique_ptr<v1::VoronoiService::Stub> stub;
};

// More points than a request of Service::kWriteHereBytes holds.
constexpr int kLarge = Service::kWriteHereBytes / 16;

TEST(ServiceThreads, WritesCommitWhereTheirSizeAndTheStoreSay) {
  RecordingStore store;
  Served served(&store);
  const std::string commit = "gvd-commit";
  // Scene "s": made on a commit thread. Then two sites, alone: on gRPC's thread.
  served.Create("s");
  served.Idle();
  EXPECT_EQ(served.Upsert("s", "p", 2), 2u);
  auto threads = store.Take();
  ASSERT_EQ(threads.size(), 2u);
  EXPECT_EQ(threads[0], commit);
  EXPECT_EQ(threads[1], "gvd-grpc");
  // A request larger than a small write's: on a commit thread.
  EXPECT_EQ(served.Upsert("s", "q", kLarge), 3u);
  EXPECT_EQ(store.Take(), std::vector<std::string>{commit});
  // Deleting one site, alone: on gRPC's thread.
  served.Idle();
  v1::DeleteSitesRequest remove;
  remove.set_scene_id("s");
  remove.add_ids("p1");
  v1::DeleteSitesResponse removed;
  grpc::ClientContext c1;
  ASSERT_TRUE(served.stub->DeleteSites(&c1, remove, &removed).ok());
  EXPECT_EQ(removed.version(), 4u);
  threads = store.Take();
  ASSERT_EQ(threads.size(), 1u);
  EXPECT_EQ(threads[0], "gvd-grpc");

  // A small write while a large one waits on the store: on a commit thread, beside it.
  served.Create("t");
  store.Take();
  store.hold_above = kLarge - 1;
  auto large = std::async(std::launch::async,
                          [&] { return served.Upsert("s", "r", kLarge); });
  store.held.get_future().wait();
  // Done while the large one is held: it waited for no commit but its own.
  EXPECT_EQ(served.Upsert("t", "m", 1), 2u);
  store.release.set_value();
  EXPECT_EQ(large.get(), 5u);
  EXPECT_EQ(store.Take(), (std::vector<std::string>{commit, commit}));

  v1::DeleteSceneRequest drop;
  drop.set_scene_id("s");
  v1::DeleteSceneResponse dropped;
  grpc::ClientContext c2;
  ASSERT_TRUE(served.stub->DeleteScene(&c2, drop, &dropped).ok());
  EXPECT_EQ(store.Take(), std::vector<std::string>{commit});
}

TEST(ServiceThreads, WritesToASharedStoreCommitOnTheCommitThreads) {
  RecordingStore store(/*shared=*/true);
  Served served(&store);
  served.Create("s");
  EXPECT_EQ(served.Upsert("s", "p", 1), 2u);
  EXPECT_EQ(store.Take(), (std::vector<std::string>{"gvd-commit", "gvd-commit"}));
}

}  // namespace
}  // namespace gvd
