#include "gvd/client.h"

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

namespace gvd {

std::unique_ptr<Client> Client::Connect(const std::string& target, ClientOptions options) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (!options.tls_ca.empty()) {
    grpc::SslCredentialsOptions tls;
    tls.pem_root_certs = options.tls_ca;
    tls.pem_private_key = options.tls_key;
    tls.pem_cert_chain = options.tls_cert;
    credentials = grpc::SslCredentials(tls);
  }
  auto channel = grpc::CreateCustomChannel(target, credentials, args);
  return std::make_unique<Client>(std::move(channel), options);
}

Client::Client(std::shared_ptr<grpc::Channel> channel, ClientOptions options)
    : channel_(std::move(channel)), stub_(v1::VoronoiService::NewStub(channel_)), options_(options) {}

std::unique_ptr<grpc::ClientContext> Client::Context() const {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + options_.timeout);
  if (!options_.token.empty()) ctx->AddMetadata("authorization", "Bearer " + options_.token);
  return ctx;
}

grpc::Status Client::CreateScene(const v1::CreateSceneRequest& request, v1::Scene* scene) {
  v1::CreateSceneResponse response;
  grpc::Status s = stub_->CreateScene(Context().get(), request, &response);
  if (s.ok()) *scene = std::move(*response.mutable_scene());
  return s;
}

grpc::Status Client::GetScene(const std::string& scene_id, v1::Scene* scene) {
  v1::GetSceneRequest request;
  request.set_scene_id(scene_id);
  v1::GetSceneResponse response;
  grpc::Status s = stub_->GetScene(Context().get(), request, &response);
  if (s.ok()) *scene = std::move(*response.mutable_scene());
  return s;
}

grpc::Status Client::ListScenes(std::vector<v1::Scene>* scenes) {
  scenes->clear();
  v1::ListScenesRequest request;
  while (true) {
    v1::ListScenesResponse page;
    grpc::Status s = stub_->ListScenes(Context().get(), request, &page);
    if (!s.ok()) return s;
    scenes->insert(scenes->end(), page.scenes().begin(), page.scenes().end());
    if (page.next_page_token().empty()) return s;
    request.set_page_token(page.next_page_token());
  }
}

grpc::Status Client::DeleteScene(const std::string& scene_id) {
  v1::DeleteSceneRequest request;
  request.set_scene_id(scene_id);
  v1::DeleteSceneResponse response;
  return stub_->DeleteScene(Context().get(), request, &response);
}

grpc::Status Client::WatchScene(const v1::WatchSceneRequest& request,
                                const std::function<bool(const v1::WatchSceneResponse&)>& on_event) {
  grpc::ClientContext ctx;
  if (!options_.token.empty()) ctx.AddMetadata("authorization", "Bearer " + options_.token);
  auto reader = stub_->WatchScene(&ctx, request);
  v1::WatchSceneResponse event;
  while (reader->Read(&event)) {
    if (!on_event(event)) {
      ctx.TryCancel();
      while (reader->Read(&event)) {
      }
      reader->Finish();
      return grpc::Status::OK;
    }
  }
  return reader->Finish();
}

grpc::Status Client::UpsertSites(const v1::UpsertSitesRequest& request, uint64_t* version) {
  v1::UpsertSitesResponse response;
  grpc::Status s = stub_->UpsertSites(Context().get(), request, &response);
  if (s.ok() && version) *version = response.version();
  return s;
}

grpc::Status Client::DeleteSites(const std::string& scene_id, const std::vector<std::string>& ids,
                                 uint64_t* version, v1::Durability durability) {
  v1::DeleteSitesRequest request;
  request.set_scene_id(scene_id);
  request.set_durability(durability);
  for (const auto& id : ids) request.add_ids(id);
  v1::DeleteSitesResponse response;
  grpc::Status s = stub_->DeleteSites(Context().get(), request, &response);
  if (s.ok() && version) *version = response.version();
  return s;
}

grpc::Status Client::ListSites(const v1::ListSitesRequest& request,
                               v1::ListSitesResponse* response) {
  return stub_->ListSites(Context().get(), request, response);
}

grpc::Status Client::ListAllSites(const std::string& scene_id, std::vector<v1::Site>* sites) {
  sites->clear();
  v1::ListSitesRequest request;
  request.set_scene_id(scene_id);
  request.set_page_size(10'000);
  while (true) {
    v1::ListSitesResponse page;
    grpc::Status s = ListSites(request, &page);
    if (!s.ok()) return s;
    sites->insert(sites->end(), page.sites().begin(), page.sites().end());
    if (page.next_page_token().empty()) return s;
    request.set_page_token(page.next_page_token());
  }
}

grpc::Status Client::FindNearest(const v1::FindNearestRequest& request,
                                 v1::FindNearestResponse* response) {
  return stub_->FindNearest(Context().get(), request, response);
}

grpc::Status Client::FindNearestStream(const v1::FindNearestStreamRequest& request,
                                       std::vector<v1::FindNearestStreamResponse>* chunks) {
  chunks->clear();
  auto ctx = Context();
  auto reader = stub_->FindNearestStream(ctx.get(), request);
  v1::FindNearestStreamResponse chunk;
  while (reader->Read(&chunk)) chunks->push_back(std::move(chunk));
  return reader->Finish();
}

grpc::Status Client::RenderImage(const v1::RenderImageRequest& request,
                                 v1::RenderImageResponse* response) {
  return stub_->RenderImage(Context().get(), request, response);
}

grpc::Status Client::GetBoundaries(const v1::GetBoundariesRequest& request, v1::GetBoundariesResponse* response) {
  return stub_->GetBoundaries(Context().get(), request, response);
}

grpc::Status Client::GetNeighbors(const v1::GetNeighborsRequest& request, v1::GetNeighborsResponse* response) {
  return stub_->GetNeighbors(Context().get(), request, response);
}

grpc::Status Client::GetDelaunay(const v1::GetDelaunayRequest& request, v1::GetDelaunayResponse* response) {
  return stub_->GetDelaunay(Context().get(), request, response);
}

grpc::Status Client::RenderWindow(const v1::RenderWindowRequest& request, v1::RenderWindowResponse* response) {
  return stub_->RenderWindow(Context().get(), request, response);
}

grpc::Status Client::GetClearanceField(const v1::GetClearanceFieldRequest& request, v1::GetClearanceFieldResponse* response) {
  return stub_->GetClearanceField(Context().get(), request, response);
}

grpc::Status Client::PlanPath(const v1::PlanPathRequest& request, v1::PlanPathResponse* response) {
  return stub_->PlanPath(Context().get(), request, response);
}

grpc::Status Client::Pick(const v1::PickRequest& request, v1::PickResponse* response) {
  return stub_->Pick(Context().get(), request, response);
}

grpc::Status Client::RenderMosaic(const v1::RenderMosaicRequest& request,
                                  v1::RenderMosaicResponse* response) {
  return stub_->RenderMosaic(Context().get(), request, response);
}

bool Client::WaitForConnected(std::chrono::milliseconds timeout) {
  return channel_->WaitForConnected(std::chrono::system_clock::now() + timeout);
}

}  // namespace gvd
