#include "server/grpc/service.h"

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace gvd {
namespace {

grpc::Status ToGrpc(const absl::Status& s) {
  if (s.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(s.code()), std::string(s.message()));
}

// The request's authorization metadata, where the core checks tokens (reading the metadata
// builds a map of it, two allocations a call).
std::string Authorization(const Service& core, const grpc::CallbackServerContext& ctx) {
  if (!core.checks_tokens()) return std::string();
  const auto& md = ctx.client_metadata();
  auto it = md.find("authorization");
  return it == md.end() ? std::string() : std::string(it->second.data(), it->second.size());
}

// The core's Call of an RPC.
CallPtr MakeCall(const Service& core, const grpc::CallbackServerContext& ctx) {
  return std::make_shared<Call>(Authorization(core, ctx));
}

// A unary RPC the core ends after it returned: finished with the core's status; a cancelled
// RPC cancels its Call.
class Unary final : public grpc::ServerUnaryReactor {
 public:
  explicit Unary(CallPtr call) : call_(std::move(call)) {}
  void OnCancel() override { call_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  CallPtr call_;
};

// A unary RPC's Call, and how it ends: the core's status, before its method returned or
// after. One allocation for both.
struct Ending {
  explicit Ending(std::string authorization) : call(std::move(authorization)) {}
  Call call;
  std::mutex mu;
  bool returned = false;              // the core's method has returned
  std::optional<absl::Status> early;  // the status it ended with before that
  Unary* reactor = nullptr;           // once it returned without a status
};

// Hands a unary RPC to the core's `method`. A call the core ends before its method returns
// (a lookup, Pick, a small batch from a frame) finishes on the context's default reactor,
// whose end gRPC runs inline; one that ends later, on a reactor of its own, which hears of
// the caller going.
template <class Request, class Response>
grpc::ServerUnaryReactor* Serve(Service* core, grpc::CallbackServerContext* ctx,
                                const Request* request, Response* response,
                                void (Service::*method)(CallPtr, const Request&, Response*, Done)) {
  auto owner = std::make_shared<Ending>(Authorization(*core, *ctx));
  CallPtr call(owner, &owner->call);
  // The Call keeps the Ending: this function's until the core's method returns, then the
  // reactor's until gRPC is done with it, after Finish. So `done` holds it by a plain pointer
  // (which std::function keeps without an allocation of its own).
  Ending* ending = owner.get();
  (core->*method)(call, *request, response, [ending](const absl::Status& s) {
    Unary* reactor;
    {
      std::lock_guard<std::mutex> lock(ending->mu);
      if (!ending->returned) {
        ending->early = s;
        return;
      }
      reactor = ending->reactor;
    }
    reactor->Finish(ToGrpc(s));
  });
  std::lock_guard<std::mutex> lock(ending->mu);
  ending->returned = true;
  if (ending->early) {
    grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
    reactor->Finish(ToGrpc(*ending->early));
    return reactor;
  }
  ending->reactor = new Unary(std::move(call));
  return ending->reactor;
}

// A server-streaming RPC as the core's StreamWriter.
template <class M>
class Stream final : public grpc::ServerWriteReactor<M>, public StreamWriter<M> {
 public:
  explicit Stream(CallPtr call) : call_(std::move(call)) {}
  const CallPtr& call() const { return call_; }

  void Write(const M* message, std::function<void(bool)> written) override {
    written_ = std::move(written);
    this->StartWrite(message);
  }
  void Finish(const absl::Status& status) override {
    grpc::ServerWriteReactor<M>::Finish(ToGrpc(status));
  }
  void OnWriteDone(bool ok) override {
    auto written = std::move(written_);
    written(ok);
  }
  void OnCancel() override { call_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  CallPtr call_;
  std::function<void(bool)> written_;
};

}  // namespace

#define GVD_UNARY(Method, Request, Response)                                                     \
  grpc::ServerUnaryReactor* GrpcService::Method(grpc::CallbackServerContext* ctx,             \
                                                   const Request* request, Response* response) { \
    return Serve(core_, ctx, request, response, &gvd::Service::Method);                          \
  }

GVD_UNARY(CreateScene, v1::CreateSceneRequest, v1::CreateSceneResponse)
GVD_UNARY(GetScene, v1::GetSceneRequest, v1::GetSceneResponse)
GVD_UNARY(ListScenes, v1::ListScenesRequest, v1::ListScenesResponse)
GVD_UNARY(DeleteScene, v1::DeleteSceneRequest, v1::DeleteSceneResponse)
GVD_UNARY(UpsertSites, v1::UpsertSitesRequest, v1::UpsertSitesResponse)
GVD_UNARY(DeleteSites, v1::DeleteSitesRequest, v1::DeleteSitesResponse)
GVD_UNARY(ListSites, v1::ListSitesRequest, v1::ListSitesResponse)
GVD_UNARY(FindNearest, v1::FindNearestRequest, v1::FindNearestResponse)
GVD_UNARY(RenderImage, v1::RenderImageRequest, v1::RenderImageResponse)
GVD_UNARY(GetBoundaries, v1::GetBoundariesRequest, v1::GetBoundariesResponse)
GVD_UNARY(GetNeighbors, v1::GetNeighborsRequest, v1::GetNeighborsResponse)
GVD_UNARY(GetDelaunay, v1::GetDelaunayRequest, v1::GetDelaunayResponse)
GVD_UNARY(RenderWindow, v1::RenderWindowRequest, v1::RenderWindowResponse)
GVD_UNARY(GetClearanceField, v1::GetClearanceFieldRequest, v1::GetClearanceFieldResponse)
GVD_UNARY(PlanPath, v1::PlanPathRequest, v1::PlanPathResponse)
GVD_UNARY(Pick, v1::PickRequest, v1::PickResponse)
GVD_UNARY(RenderMosaic, v1::RenderMosaicRequest, v1::RenderMosaicResponse)
#undef GVD_UNARY

grpc::ServerWriteReactor<v1::WatchSceneResponse>* GrpcService::WatchScene(
    grpc::CallbackServerContext* ctx, const v1::WatchSceneRequest* request) {
  auto* stream = new Stream<v1::WatchSceneResponse>(MakeCall(*core_, *ctx));
  core_->WatchScene(stream->call(), *request, stream);
  return stream;
}

grpc::ServerWriteReactor<v1::FindNearestStreamResponse>* GrpcService::FindNearestStream(
    grpc::CallbackServerContext* ctx, const v1::FindNearestStreamRequest* request) {
  auto* stream = new Stream<v1::FindNearestStreamResponse>(MakeCall(*core_, *ctx));
  core_->FindNearestStream(stream->call(), *request, stream);
  return stream;
}

}  // namespace gvd
