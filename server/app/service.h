// Every call of gvd.v1.VoronoiService as the application core serves it: plain functions that take
// the request message and fill the response message, whichever transport brought them. The
// gRPC transport (server/grpc/) and the HTTP transport (server/http/) only translate: they
// make a Call per request, hand the messages to these functions and turn the status into
// their own. So both have the same admission, tokens, limits, metrics and drain.
//
// Where each call's work runs. A call returns at once; its work runs on the caller's thread
// only when it needs neither a wait nor much work (a lookup, a page of sites, Pick, a small
// batch from a published frame) or is a small write while no other write is under way (Write
// below); other writes run on the registry's commit threads, everything heavier on its CPU
// pool (server/app/jobs.h says which part where). So a transport's thread never waits on a
// render, a large computation, or another call's commit.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "server/app/auth.h"
#include "server/app/call.h"
#include "server/app/registry.h"
#include "server/app/watch.h"
#include "server/metrics.h"

namespace gvd {

// Thread-safe. Each unary call takes its Call, the request and the response, which must stay
// valid until `done` is called (exactly once, on any thread, perhaps before the call
// returns); each server stream takes a StreamWriter, which must stay valid until the core
// calls its Finish. Refusals come as statuses: INVALID_ARGUMENT naming the field and value,
// NOT_FOUND, RESOURCE_EXHAUSTED naming the limit, UNAUTHENTICATED and PERMISSION_DENIED for
// tokens, UNAVAILABLE while loading or draining.
class Service {
 public:
  // `registry` must outlive the service; `auth` (tokens required when set) and `metrics` may
  // be null. Until the registry is loaded, every call is answered UNAVAILABLE.
  Service(SceneRegistry* registry, const TokenAuth* auth = nullptr, Metrics* metrics = nullptr);
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  // The largest UpsertSites or DeleteSites request (its protobuf size) that may run on the
  // caller's thread (Write, below): a few hundred points, or a polygon of a thousand vertices.
  static constexpr size_t kWriteHereBytes = 16 << 10;

  // Refuses new calls (UNAVAILABLE) from now on, ends the WatchScene streams (UNAVAILABLE),
  // and waits up to `grace` for the calls in flight to finish. Returns how many were still
  // in flight.
  int Drain(std::chrono::milliseconds grace);
  // Calls in flight: running, waiting for a render or a commit, streams writing.
  int in_flight() const { return calls_.in_flight; }
  // Whether calls need a bearer token: a transport need not read a call's authorization
  // otherwise.
  bool checks_tokens() const { return auth_ != nullptr; }

  // Scenes.
  void CreateScene(CallPtr call, const v1::CreateSceneRequest& request,
                   v1::CreateSceneResponse* response,
                   Done done);
  void GetScene(CallPtr call, const v1::GetSceneRequest& request, v1::GetSceneResponse* response,
                Done done);
  void ListScenes(CallPtr call, const v1::ListScenesRequest& request,
                  v1::ListScenesResponse* response, Done done);
  void DeleteScene(CallPtr call, const v1::DeleteSceneRequest& request,
                   v1::DeleteSceneResponse* response, Done done);
  void WatchScene(CallPtr call, const v1::WatchSceneRequest& request,
                  StreamWriter<v1::WatchSceneResponse>* stream);

  // Sites.
  void UpsertSites(CallPtr call, const v1::UpsertSitesRequest& request,
                   v1::UpsertSitesResponse* response, Done done);
  void DeleteSites(CallPtr call, const v1::DeleteSitesRequest& request,
                   v1::DeleteSitesResponse* response, Done done);
  void ListSites(CallPtr call, const v1::ListSitesRequest& request, v1::ListSitesResponse* response,
                 Done done);

  // Queries (server/app/queries.cc).
  void FindNearest(CallPtr call, const v1::FindNearestRequest& request,
                   v1::FindNearestResponse* response, Done done);
  void FindNearestStream(CallPtr call, const v1::FindNearestStreamRequest& request,
                         StreamWriter<v1::FindNearestStreamResponse>* stream);
  void RenderImage(CallPtr call, const v1::RenderImageRequest& request,
                   v1::RenderImageResponse* response, Done done);
  void Pick(CallPtr call, const v1::PickRequest& request, v1::PickResponse* response, Done done);

  // Structure and applications (server/app/analysis_calls.cc).
  void GetBoundaries(CallPtr call, const v1::GetBoundariesRequest& request,
                     v1::GetBoundariesResponse* response, Done done);
  void GetNeighbors(CallPtr call, const v1::GetNeighborsRequest& request,
                    v1::GetNeighborsResponse* response, Done done);
  void GetDelaunay(CallPtr call, const v1::GetDelaunayRequest& request,
                   v1::GetDelaunayResponse* response, Done done);
  void RenderWindow(CallPtr call, const v1::RenderWindowRequest& request,
                    v1::RenderWindowResponse* response, Done done);
  void GetClearanceField(CallPtr call, const v1::GetClearanceFieldRequest& request,
                         v1::GetClearanceFieldResponse* response, Done done);
  void PlanPath(CallPtr call, const v1::PlanPathRequest& request, v1::PlanPathResponse* response,
                Done done);
  void RenderMosaic(CallPtr call, const v1::RenderMosaicRequest& request,
                    v1::RenderMosaicResponse* response, Done done);

 private:
  enum class Access { kRead, kWrite };
  // How every call starts: it is counted (scope), admitted (loaded, not draining, its token;
  // kWrite for calls that change state), and a call on one scene (scene_id given) has its id
  // validated and its scene found. When status is not OK the call ends with it.
  struct Begun {
    std::shared_ptr<CallScope> scope;
    std::optional<SceneHandle> scene;
    absl::Status status;
  };
  Begun Begin(const Call& call, const char* method, Access access,
              const std::string* scene_id = nullptr);
  // `done` after the call's status is recorded in its scope.
  static Done Ending(std::shared_ptr<CallScope> scope, Done done);
  // Runs `work` on `lane` and ends with its status; RESOURCE_EXHAUSTED naming `limit` (the
  // flag that sets the queue's size) when the lane's queue is full.
  static void OnLane(CpuPool::Lane& lane, const char* limit, std::function<absl::Status()> work,
                     Done done);
  // A write whose request has `bytes`: on the calling thread when it is small (at most
  // kWriteHereBytes), the store is this server's own (SceneRegistry::local_store) and no other
  // write is under way (the commits lane is idle), so that it costs its commit and no
  // handoff; else on the commits lane, as OnLane. A transport's thread so waits on the store
  // for one small write at a time, its own, never through another's commit.
  void Write(size_t bytes, std::function<absl::Status()> work, Done done);

  // A structure call on a 2D scene's frame of at least `min_version`: `work` runs on the
  // analyses lane (AnalysisJob) once the frame is there.
  using FrameWork = std::function<absl::Status(const std::shared_ptr<const Frame>&, const Scene&)>;
  void StartAnalysis(CallPtr call, const std::shared_ptr<Scene>& scene, uint64_t min_version,
                     FrameWork work, Done done);
  // GetClearanceField of a 2D scene.
  void PlaneClearance(CallPtr call, const std::shared_ptr<Scene>& scene,
                      const v1::GetClearanceFieldRequest& request,
                      v1::GetClearanceFieldResponse* response, Done done);
  // RenderImage of a 2D scene's window at a resolution of its own.
  void RenderImageAt(CallPtr call, const std::shared_ptr<Scene>& scene,
                     const v1::RenderImageRequest& request, v1::RenderImageResponse* response,
                     Done done);

  SceneRegistry* const registry_;
  const ServerLimits& limits_;
  const TokenAuth* const auth_;
  std::atomic<bool> draining_{false};
  mutable CallCounter calls_;
  Watches watches_;  // the WatchScene streams open now
};

}  // namespace gvd
