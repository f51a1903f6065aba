// The gvd.v1.Voronoi service on gRPC's callback API: the transport of the application core
// (server/app/registry.h). Handlers admit, validate and translate requests into core calls
// and their statuses into codes; they never touch GL, never wait for a render, a commit or a
// large computation (server/grpc/reactors.h says where that work runs).
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <string>

#include "gvd/v1/voronoi.grpc.pb.h"
#include "render/image/image.h"
#include "server/app/limits.h"
#include "server/app/registry.h"
#include "server/grpc/auth.h"
#include "server/grpc/call_scope.h"
#include "server/grpc/watch.h"
#include "server/metrics.h"

namespace gvd {

template <class P>
struct BasicNearestQuery;
using NearestQuery = BasicNearestQuery<Vec2>;

// Threads: gRPC's threads run the handlers, which admit, validate and answer what needs
// neither a wait nor much work (a lookup, a small batch from a published frame, a page of
// sites); writes run on the core's commit threads, everything heavier on its CPU pool.
class VoronoiService final : public v1::Voronoi::CallbackService {
 public:
  // `registry` must outlive the service. Until the registry is loaded, every call is
  // answered UNAVAILABLE.
  VoronoiService(SceneRegistry* registry, const TokenAuth* auth = nullptr,
                 Metrics* metrics = nullptr);

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

  // Structure and applications (server/grpc/analysis_service.cc).
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
  // Validates a FindNearest request on its scene and resolves its points and mode, and the
  // packed columns it asks for (bit f for v1::FindNearestRequest::Field f).
  // `packed`: whether the answers go out packed (a request with `xy`, and every stream).
  // A template on the scene (Scene or Scene3), whose points the query takes.
  template <class S>
  grpc::Status ParseNearest(const v1::FindNearestRequest& request, const S& scene, bool packed,
                            BasicNearestQuery<typename S::Point>* query, uint32_t* fields) const;
  // FindNearest on a scene of either dimension, parsed and started.
  template <class S>
  grpc::ServerUnaryReactor* StartNearest(grpc::CallbackServerContext* ctx,
                                         const std::shared_ptr<CallScope>& scope,
                                         const std::shared_ptr<S>& scene,
                                         const v1::FindNearestRequest* request,
                                         v1::FindNearestResponse* response);
  template <class S>
  grpc::ServerWriteReactor<v1::FindNearestResponse>* StartNearestStream(
      grpc::CallbackServerContext* ctx, const std::shared_ptr<CallScope>& scope,
      const std::shared_ptr<S>& scene, const v1::FindNearestRequest* request);

  // How every handler starts: the call is counted (scope) and admitted (ready, token;
  // kWrite for calls that change state), and a call on one scene (scene_id given) has its
  // id validated and its scene found: a 2D one in `scene`, or, for the calls that take them
  // (three_d), a 3D one in `scene3`. When status is not OK the handler finishes with it.
  enum class Access { kRead, kWrite };
  struct Call {
    std::shared_ptr<CallScope> scope;
    std::shared_ptr<Scene> scene;
    std::shared_ptr<Scene3> scene3;
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
             const std::string* scene_id = nullptr, bool three_d = false) const;

  // Starts an analysis call: validates and resolves its scene, waits for the frame, then
  // runs `work` on the analyses lane (server/app/jobs.h's AnalysisJob).
  using Validate = std::function<grpc::Status(const Scene&)>;
  using Work = std::function<absl::Status(const std::shared_ptr<const Frame>&, const Scene&)>;
  grpc::ServerUnaryReactor* StartAnalysis(const char* method, grpc::CallbackServerContext* ctx,
                                          const std::string& scene_id, uint64_t min_version,
                                          Validate validate, Work work);
  // RenderImage's job on a 2D scene's frame or a 3D scene's slice.
  template <class S>
  grpc::ServerUnaryReactor* StartImage(const std::shared_ptr<CallScope>& scope,
                                       grpc::CallbackServerContext* ctx,
                                       const std::shared_ptr<S>& scene, ImageOptions options,
                                       uint64_t min_version, v1::RenderImageResponse* response);
  // RenderImage of a window rendered at a resolution of its own (a 2D scene's, begun).
  grpc::ServerUnaryReactor* RenderImageAt(const Call& call, grpc::CallbackServerContext* ctx,
                                          const v1::RenderImageRequest* request,
                                          v1::RenderImageResponse* response);
  // GetClearanceField of a 3D scene.
  grpc::ServerUnaryReactor* ClearanceField3(const Call& call, grpc::CallbackServerContext* ctx,
                                            const v1::GetClearanceFieldRequest* request,
                                            v1::GetClearanceFieldResponse* response);
  // The same for a call already begun on a 2D scene.
  grpc::ServerUnaryReactor* StartAnalysis(const Call& call, grpc::CallbackServerContext* ctx,
                                          uint64_t min_version, Validate validate, Work work);

  // UNAVAILABLE until the registry is loaded (and once draining); then the token check.
  grpc::Status Admit(grpc::CallbackServerContext* ctx, bool write) const;

  SceneRegistry* const registry_;
  const ServerLimits& limits_;
  const TokenAuth* const auth_;
  std::atomic<bool> draining_{false};
  mutable CallCounter calls_;
  // The WatchScene streams open now.
  Watches watches_;
};

}  // namespace gvd
