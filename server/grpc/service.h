// The gvd.v1.Voronoi service on gRPC's callback API. Handlers validate, mutate scenes and
// answer queries from published frames; they never touch GL and never wait for a render
// (a query that asks for a newer version parks until the render thread publishes it).
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "gvd/v1/voronoi.grpc.pb.h"
#include "server/grpc/auth.h"
#include "server/grpc/call_scope.h"
#include "server/app/limits.h"
#include "server/app/memory.h"
#include "server/metrics.h"
#include "render/gl/render_loop.h"
#include "server/grpc/watch.h"
#include "render/scene/cpu_pool.h"
#include "render/scene/scene.h"
#include "render/scene/store.h"

namespace gvd {

struct NearestQuery;

// Threads:
//  - gRPC's threads run the handlers: they admit, validate, write scenes (through Scene's
//    per-scene writer lock; the durable commit happens there, under no lock of this class)
//    and answer from published frames when no wait is needed;
//  - a query that waits for a version resumes on the answers_ lane of the CPU pool, and an
//    analysis runs on the analyses_ lane, never on the render thread;
//  - mu_ guards only the scene map and the ids being created, for lookups and publication.
class VoronoiService final : public v1::Voronoi::CallbackService {
 public:
  // `renderer` and `store` must outlive the service. Until Load() has run, every call is
  // answered UNAVAILABLE.
  VoronoiService(RenderLoop* renderer, SceneStore* store, ServerLimits limits,
                 const TokenAuth* auth = nullptr, Metrics* metrics = nullptr);

  // Per-scene figures for the metrics.
  std::vector<Metrics::SceneSample> SampleScenes() const;
  // What the scenes hold and reserve now, of limits.max_memory.
  uint64_t memory_used() const { return memory_.used(); }

  // Rebuilds every stored scene (and queues its render); then the service answers calls.
  absl::Status Load();

  // Refuses new calls (UNAVAILABLE) from now on, ends the WatchScene streams (UNAVAILABLE),
  // and waits up to `grace` for the calls in flight to finish. Returns how many were still
  // in flight.
  int Drain(std::chrono::milliseconds grace);
  // Calls in flight: handlers running, queries waiting for a render, streams writing.
  int in_flight() const { return calls_.in_flight; }

  grpc::ServerUnaryReactor* CreateScene(grpc::CallbackServerContext* ctx,
                                        const v1::CreateSceneRequest* request,
                                        v1::Scene* response) override;
  grpc::ServerUnaryReactor* GetScene(grpc::CallbackServerContext* ctx,
                                     const v1::GetSceneRequest* request,
                                     v1::Scene* response) override;
  grpc::ServerUnaryReactor* ListScenes(grpc::CallbackServerContext* ctx,
                                       const v1::ListScenesRequest* request,
                                       v1::ListScenesResponse* response) override;
  grpc::ServerUnaryReactor* DeleteScene(grpc::CallbackServerContext* ctx,
                                        const v1::DeleteSceneRequest* request,
                                        v1::DeleteSceneResponse* response) override;
  grpc::ServerWriteReactor<v1::SceneEvent>* WatchScene(
      grpc::CallbackServerContext* ctx, const v1::WatchSceneRequest* request) override;
  grpc::ServerUnaryReactor* UpsertSites(grpc::CallbackServerContext* ctx,
                                        const v1::UpsertSitesRequest* request,
                                        v1::UpsertSitesResponse* response) override;
  grpc::ServerUnaryReactor* DeleteSites(grpc::CallbackServerContext* ctx,
                                        const v1::DeleteSitesRequest* request,
                                        v1::DeleteSitesResponse* response) override;
  grpc::ServerUnaryReactor* ListSites(grpc::CallbackServerContext* ctx,
                                      const v1::ListSitesRequest* request,
                                      v1::ListSitesResponse* response) override;
  grpc::ServerUnaryReactor* FindNearest(grpc::CallbackServerContext* ctx,
                                        const v1::FindNearestRequest* request,
                                        v1::FindNearestResponse* response) override;
  grpc::ServerWriteReactor<v1::FindNearestResponse>* FindNearestStream(
      grpc::CallbackServerContext* ctx, const v1::FindNearestRequest* request) override;
  grpc::ServerUnaryReactor* RenderImage(grpc::CallbackServerContext* ctx,
                                        const v1::RenderImageRequest* request,
                                        v1::RenderImageResponse* response) override;

  // Structure and applications (server/analysis_service.cc).
  grpc::ServerUnaryReactor* GetBoundaries(grpc::CallbackServerContext* ctx,
                                          const v1::GetBoundariesRequest* request,
                                          v1::GetBoundariesResponse* response) override;
  grpc::ServerUnaryReactor* GetNeighbors(grpc::CallbackServerContext* ctx,
                                         const v1::GetNeighborsRequest* request,
                                         v1::GetNeighborsResponse* response) override;
  grpc::ServerUnaryReactor* GetDelaunay(grpc::CallbackServerContext* ctx,
                                        const v1::GetDelaunayRequest* request,
                                        v1::GetDelaunayResponse* response) override;
  grpc::ServerUnaryReactor* RenderWindow(grpc::CallbackServerContext* ctx,
                                         const v1::RenderWindowRequest* request,
                                         v1::RenderWindowResponse* response) override;
  grpc::ServerUnaryReactor* GetClearanceField(grpc::CallbackServerContext* ctx,
                                              const v1::GetClearanceFieldRequest* request,
                                              v1::GetClearanceFieldResponse* response) override;
  grpc::ServerUnaryReactor* PlanPath(grpc::CallbackServerContext* ctx,
                                     const v1::PlanPathRequest* request,
                                     v1::PlanPathResponse* response) override;
  grpc::ServerUnaryReactor* Pick(grpc::CallbackServerContext* ctx, const v1::PickRequest* request,
                                 v1::PickResponse* response) override;

 private:
  // Validates a FindNearest request on its scene (query->scene) and resolves its points and
  // mode.
  grpc::Status ParseNearest(const v1::FindNearestRequest& request, NearestQuery* query) const;

  // The scene, or NOT_FOUND naming it (after validating the id).
  grpc::Status Lookup(const std::string& scene_id, std::shared_ptr<Scene>* scene) const;

  // How every handler starts: the call is counted (scope) and admitted (ready, token;
  // kWrite for calls that change state), and a call on one scene (scene_id given) has its
  // id validated and its scene found. When status is not OK the handler finishes with it.
  enum class Access { kRead, kWrite };
  struct Call {
    std::shared_ptr<CallScope> scope;
    std::shared_ptr<Scene> scene;
    grpc::Status status;
    bool ok() const { return status.ok(); }
    // Finishes a unary call with `s` (by default, the preamble's refusal).
    grpc::ServerUnaryReactor* Finish(grpc::CallbackServerContext* ctx) const {
      return scope->Done(ctx, status);
    }
    grpc::ServerUnaryReactor* Finish(grpc::CallbackServerContext* ctx, const grpc::Status& s) const {
      return scope->Done(ctx, s);
    }
  };
  Call Begin(grpc::CallbackServerContext* ctx, const char* method, Access access,
             const std::string* scene_id = nullptr) const;

  // Sets the version a call waits for: `requested`, or the current one while the scene's
  // first render is under way. OUT_OF_RANGE when the scene has not reached `requested`.
  grpc::Status WaitFor(uint64_t requested, NearestQuery* query) const;

  // Starts an analysis call: validates and resolves its scene (into query), waits for the
  // frame, then runs `work` on a worker thread (RESOURCE_EXHAUSTED when too many wait). The
  // work may render zoom windows through renderer_.
  grpc::ServerUnaryReactor* StartAnalysis(
      const char* method, grpc::CallbackServerContext* ctx, const std::string& scene_id,
      uint64_t min_version, std::function<grpc::Status(NearestQuery*)> validate,
      std::function<grpc::Status(const std::shared_ptr<const Frame>&, const Scene&)> work);

  // UNAVAILABLE until Load() has run (and once draining); then the token check, if any.
  grpc::Status Admit(grpc::CallbackServerContext* ctx, bool write) const;
  grpc::Status Ready() const;
  // Resumes a scene's frame waiters on answers_.
  Executor executor();

  RenderLoop* const renderer_;
  SceneStore* const store_;
  const ServerLimits limits_;
  const TokenAuth* const auth_;
  Metrics* const metrics_;
  // Runs one store call, timing it for the metrics.
  template <class StoreCall>
  absl::Status Durably(StoreCall store_call) const;
  std::atomic<bool> ready_{false};
  std::atomic<bool> draining_{false};
  mutable CallCounter calls_;
  // Guards scenes_, creating_ and unloaded_, and is never held across a store call: a durable commit
  // blocks no other scene's lookup.
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Scene>> scenes_;
  // Ids of scenes being created (reserved, not yet committed): they count against
  // --max-scenes and refuse a second create, but are not found until committed.
  std::set<std::string> creating_;
  // Stored scenes that did not fit --max-memory at start (Load): kept in the store, reported
  // by GetScene and ListScenes, removable by DeleteScene; any other call on one is
  // FAILED_PRECONDITION with the reason.
  struct Unloaded {
    SceneSettings settings;
    uint64_t version = 0;
    size_t sites = 0;
    uint64_t bytes = 0;
    std::string reason;
  };
  std::map<std::string, Unloaded> unloaded_;
  static void Describe(const Unloaded& scene, v1::Scene* out);
  // --max-memory over the scenes' own figures (ScenesMemory). Its lock is taken before mu_.
  MemoryBudget memory_;
  uint64_t ScenesMemory() const;
  // The WatchScene streams open now.
  Watches watches_;
  // The process's CPU pool does the work that must not run on gRPC's threads nor on the
  // render thread, on two lanes: answers to queries that waited for a frame (and image
  // encoding) first, then analyses, of which at most --analysis-threads run at once and
  // --max-queued-analyses wait. Declared last: answers_ goes first, finishing what is queued
  // (which may still queue analyses), then analyses_.
  CpuPool::Lane analyses_;
  CpuPool::Lane answers_;
};

}  // namespace gvd
