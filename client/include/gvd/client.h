// The C++ client of gvd-server. One method per RPC, plus conveniences; every call returns
// the server's grpc::Status. Thread-safe: calls may be made from many threads at once.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/channel.h>
#include <grpcpp/support/status.h>

#include "gvd/v1/voronoi.grpc.pb.h"

namespace gvd {

struct ClientOptions {
  // Deadline of each call; a FindNearest with min_version waits at most this long.
  std::chrono::milliseconds timeout{30'000};
  int max_message_bytes = 256 << 20;
  // Sent as "authorization: Bearer TOKEN" when not empty.
  std::string token;
  // TLS when tls_ca is set: the CA (PEM) the server's certificate must chain to, and
  // optionally a client certificate chain and key (PEM) for servers that require one.
  std::string tls_ca, tls_cert, tls_key;
};

class Client {
 public:
  // A client of `target` (e.g. "127.0.0.1:50051"), over TLS when options.tls_ca is set.
  static std::unique_ptr<Client> Connect(const std::string& target, ClientOptions options = {});
  Client(std::shared_ptr<grpc::Channel> channel, ClientOptions options);

  // The scene made (CreateSceneResponse.scene).
  grpc::Status CreateScene(const v1::CreateSceneRequest& request, v1::Scene* scene);
  grpc::Status GetScene(const std::string& scene_id, v1::Scene* scene);
  // Every scene, following page tokens.
  grpc::Status ListScenes(std::vector<v1::Scene>* scenes);
  grpc::Status DeleteScene(const std::string& scene_id);
  // WatchScene: calls on_event with each event as it comes, until the stream ends, or
  // on_event returns false (then the call is cancelled and the result is OK). No deadline:
  // a watch lasts as long as the scene, the server or the caller.
  grpc::Status WatchScene(const v1::WatchSceneRequest& request,
                          const std::function<bool(const v1::WatchSceneResponse&)>& on_event);

  grpc::Status UpsertSites(const v1::UpsertSitesRequest& request, uint64_t* version);
  grpc::Status DeleteSites(const std::string& scene_id, const std::vector<std::string>& ids,
                           uint64_t* version,
                           v1::Durability durability = v1::DURABILITY_SYNC);
  grpc::Status ListSites(const v1::ListSitesRequest& request, v1::ListSitesResponse* response);
  // Every site of the scene, following page tokens.
  grpc::Status ListAllSites(const std::string& scene_id, std::vector<v1::Site>* sites);

  grpc::Status FindNearest(const v1::FindNearestRequest& request,
                           v1::FindNearestResponse* response);
  // FindNearestStream: every packed chunk, in order.
  grpc::Status FindNearestStream(const v1::FindNearestStreamRequest& request,
                                 std::vector<v1::FindNearestStreamResponse>* chunks);

  grpc::Status RenderImage(const v1::RenderImageRequest& request,
                           v1::RenderImageResponse* response);

  // Structure of the diagram (paper sec. 5, 6.2).
  grpc::Status GetBoundaries(const v1::GetBoundariesRequest& request,
                             v1::GetBoundariesResponse* response);
  grpc::Status GetNeighbors(const v1::GetNeighborsRequest& request,
                            v1::GetNeighborsResponse* response);
  grpc::Status GetDelaunay(const v1::GetDelaunayRequest& request,
                           v1::GetDelaunayResponse* response);
  grpc::Status RenderWindow(const v1::RenderWindowRequest& request,
                            v1::RenderWindowResponse* response);

  // Applications (paper sec. 7).
  grpc::Status GetClearanceField(const v1::GetClearanceFieldRequest& request,
                                 v1::GetClearanceFieldResponse* response);
  grpc::Status PlanPath(const v1::PlanPathRequest& request, v1::PlanPathResponse* response);
  grpc::Status Pick(const v1::PickRequest& request, v1::PickResponse* response);
  grpc::Status RenderMosaic(const v1::RenderMosaicRequest& request,
                            v1::RenderMosaicResponse* response);

  // Waits until the server answers or `timeout` passes; true when connected.
  bool WaitForConnected(std::chrono::milliseconds timeout);

 private:
  std::unique_ptr<grpc::ClientContext> Context() const;

  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::VoronoiService::Stub> stub_;
  ClientOptions options_;
};

}  // namespace gvd
