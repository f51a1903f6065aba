// The gvd.v1.VoronoiService on gRPC's callback API: a transport that only translates. Each
// handler makes a Call (the caller's "authorization" metadata; cancelled when gRPC cancels
// the RPC, its deadline included), hands the messages to the application core
// (server/app/service.h) and finishes with the core's status as the same gRPC code.
#pragma once

#include "gvd/v1/voronoi.grpc.pb.h"
#include "server/app/service.h"

namespace gvd {

// Threads: gRPC's threads run the handlers, which return at once; the core says where each
// call's work runs.
class GrpcService final : public v1::VoronoiService::CallbackService {
 public:
  // `core` must outlive the service. (Within this class, Service alone names gRPC's base.)
  explicit GrpcService(gvd::Service* core) : core_(core) {}

  grpc::ServerUnaryReactor* CreateScene(grpc::CallbackServerContext* ctx,
                                        const v1::CreateSceneRequest* request,
                                        v1::CreateSceneResponse* response) override;
  grpc::ServerUnaryReactor* GetScene(grpc::CallbackServerContext* ctx,
                                     const v1::GetSceneRequest* request,
                                     v1::GetSceneResponse* response) override;
  grpc::ServerUnaryReactor* ListScenes(grpc::CallbackServerContext* ctx,
                                       const v1::ListScenesRequest* request,
                                       v1::ListScenesResponse* response) override;
  grpc::ServerUnaryReactor* DeleteScene(grpc::CallbackServerContext* ctx,
                                        const v1::DeleteSceneRequest* request,
                                        v1::DeleteSceneResponse* response) override;
  grpc::ServerWriteReactor<v1::WatchSceneResponse>* WatchScene(
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
  grpc::ServerWriteReactor<v1::FindNearestStreamResponse>* FindNearestStream(
      grpc::CallbackServerContext* ctx, const v1::FindNearestStreamRequest* request) override;
  grpc::ServerUnaryReactor* RenderImage(grpc::CallbackServerContext* ctx,
                                        const v1::RenderImageRequest* request,
                                        v1::RenderImageResponse* response) override;
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
  grpc::ServerUnaryReactor* RenderMosaic(grpc::CallbackServerContext* ctx,
                                         const v1::RenderMosaicRequest* request,
                                         v1::RenderMosaicResponse* response) override;

 private:
  gvd::Service* const core_;
};

}  // namespace gvd
