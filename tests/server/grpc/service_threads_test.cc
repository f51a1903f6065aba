// The gRPC transport in process over the application core, on a real gRPC server on
// loopback: its handlers never wait on the store. Every store call a write makes runs on the core's commit threads
// ("gvd-commit"), whatever thread gRPC ran the handler on.
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <pthread.h>

#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "server/app/registry.h"
#include "server/grpc/service.h"
#include "server/store/sqlite_store.h"

namespace gvd {
namespace {

// A store in memory that notes the threads its writes run on.
class RecordingStore final : public SceneStore {
 public:
  RecordingStore() : inner_(std::move(*SqliteStore::Open(":memory:"))) {}
  absl::StatusOr<std::vector<StoredScene>> Load() override { return inner_->Load(); }
  absl::StatusOr<uint64_t> CreateScene(const SceneSettings& s, uint64_t v) override {
    Note();
    return inner_->CreateScene(s, v);
  }
  absl::Status Commit(const ChangeSet& c) override {
    Note();
    return inner_->Commit(c);
  }
  absl::Status DeleteScene(std::string_view id) override {
    Note();
    return inner_->DeleteScene(id);
  }
  std::string Describe() const override { return "recording"; }
  std::multiset<std::string> threads() {
    std::lock_guard<std::mutex> lock(mu_);
    return threads_;
  }

 private:
  void Note() {
    char name[32] = {};
    pthread_getname_np(pthread_self(), name, sizeof name);
    std::lock_guard<std::mutex> lock(mu_);
    threads_.insert(name);
  }
  std::unique_ptr<SqliteStore> inner_;
  std::mutex mu_;
  std::multiset<std::string> threads_;
};

TEST(ServiceThreads, WritesCommitOnTheCommitThreads) {
  RecordingStore store;
  SceneRegistry registry(&store, {}, ServerLimits{});
  ASSERT_TRUE(registry.Load().ok());
  Service core(&registry);
  GrpcService service(&core);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  auto server = builder.BuildAndStart();
  ASSERT_NE(port, 0);
  auto stub = v1::VoronoiService::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));
  auto call = [](auto status) { EXPECT_TRUE(status.ok()) << status.error_message(); };

  // Scene "s", sites a and b, then b deleted, then the scene.
  v1::CreateSceneRequest create;
  create.set_scene_id("s");
  create.mutable_window()->set_max_x(1);
  create.mutable_window()->set_max_y(1);
  create.set_width_px(32);
  create.set_height_px(32);
  v1::CreateSceneResponse scene;
  grpc::ClientContext c1;
  call(stub->CreateScene(&c1, create, &scene));
  v1::UpsertSitesRequest upsert;
  upsert.set_scene_id("s");
  for (const char* id : {"a", "b"}) {
    auto* site = upsert.add_sites();
    site->set_id(id);
    site->mutable_point()->set_x(0.25);
    site->mutable_point()->set_y(id[0] == 'a' ? 0.25 : 0.75);
  }
  v1::UpsertSitesResponse upserted;
  grpc::ClientContext c2;
  call(stub->UpsertSites(&c2, upsert, &upserted));
  EXPECT_EQ(upserted.version(), 2u);
  v1::DeleteSitesRequest remove;
  remove.set_scene_id("s");
  remove.add_ids("b");
  v1::DeleteSitesResponse removed;
  grpc::ClientContext c3;
  call(stub->DeleteSites(&c3, remove, &removed));
  EXPECT_EQ(removed.version(), 3u);
  v1::DeleteSceneRequest drop;
  drop.set_scene_id("s");
  v1::DeleteSceneResponse dropped;
  grpc::ClientContext c4;
  call(stub->DeleteScene(&c4, drop, &dropped));

  const std::multiset<std::string> expected = {"gvd-commit", "gvd-commit", "gvd-commit",
                                               "gvd-commit"};
  EXPECT_EQ(store.threads(), expected);
  server->Shutdown();
}

}  // namespace
}  // namespace gvd
