#include "server/app/methods.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <thread>
#include <string>

#include "gvd/v1/voronoi.pb.h"

namespace gvd {
namespace {

using google::protobuf::Message;

const google::protobuf::MethodDescriptor* Descriptor(const char* name) {
  return v1::FindNearestRequest::descriptor()->file()->FindServiceByName("VoronoiService")
      ->FindMethodByName(name);
}

template <class Request, class Response>
Method UnaryMethod(const char* name,
                   void (Service::*method)(CallPtr, const Request&, Response*, Done)) {
  return {Descriptor(name),
          [method](Service* core, CallPtr call, const Message& request, Message* response,
                   Done done) {
            (core->*method)(std::move(call), static_cast<const Request&>(request),
                            static_cast<Response*>(response), std::move(done));
          },
          nullptr};
}

// A server stream's writer of M over a transport's StreamOut; it lives until the core
// finishes it.
template <class M>
class StreamOf final : public StreamWriter<M> {
 public:
  explicit StreamOf(std::shared_ptr<StreamOut> out) : out_(std::move(out)) {}
  void Write(const M* message, std::function<void(bool)> written) override {
    out_->Message(*message, std::move(written));
  }
  void Finish(const absl::Status& status) override {
    out_->End(status);
    delete this;
  }

 private:
  std::shared_ptr<StreamOut> out_;
};

template <class Request, class M>
Method StreamingMethod(const char* name,
                       void (Service::*method)(CallPtr, const Request&, StreamWriter<M>*)) {
  return {Descriptor(name), nullptr,
          [method](Service* core, CallPtr call, const Message& request,
                   std::shared_ptr<StreamOut> out) {
            (core->*method)(std::move(call), static_cast<const Request&>(request),
                            new StreamOf<M>(std::move(out)));
          }};
}

}  // namespace

const char* const kServiceName = "gvd.v1.VoronoiService";

const Method* FindMethod(std::string_view name) {
  static const auto* methods = new std::map<std::string, Method, std::less<>>{
      {"CreateScene", UnaryMethod("CreateScene", &Service::CreateScene)},
      {"GetScene", UnaryMethod("GetScene", &Service::GetScene)},
      {"ListScenes", UnaryMethod("ListScenes", &Service::ListScenes)},
      {"DeleteScene", UnaryMethod("DeleteScene", &Service::DeleteScene)},
      {"WatchScene", StreamingMethod("WatchScene", &Service::WatchScene)},
      {"UpsertSites", UnaryMethod("UpsertSites", &Service::UpsertSites)},
      {"DeleteSites", UnaryMethod("DeleteSites", &Service::DeleteSites)},
      {"ListSites", UnaryMethod("ListSites", &Service::ListSites)},
      {"FindNearest", UnaryMethod("FindNearest", &Service::FindNearest)},
      {"FindNearestStream", StreamingMethod("FindNearestStream", &Service::FindNearestStream)},
      {"RenderImage", UnaryMethod("RenderImage", &Service::RenderImage)},
      {"GetBoundaries", UnaryMethod("GetBoundaries", &Service::GetBoundaries)},
      {"GetNeighbors", UnaryMethod("GetNeighbors", &Service::GetNeighbors)},
      {"GetDelaunay", UnaryMethod("GetDelaunay", &Service::GetDelaunay)},
      {"RenderWindow", UnaryMethod("RenderWindow", &Service::RenderWindow)},
      {"GetClearanceField", UnaryMethod("GetClearanceField", &Service::GetClearanceField)},
      {"PlanPath", UnaryMethod("PlanPath", &Service::PlanPath)},
      {"Pick", UnaryMethod("Pick", &Service::Pick)},
      {"RenderMosaic", UnaryMethod("RenderMosaic", &Service::RenderMosaic)},
  };
  auto it = methods->find(name);
  return it == methods->end() ? nullptr : &it->second;
}

void HoldConversions(const std::atomic<bool>& stopping) {
  static const char* const path = std::getenv(kHoldConversionsVariable);
  if (path == nullptr || access(path, F_OK) != 0) return;
  const std::string waiting = std::string(path) + ".waiting";
  if (FILE* f = std::fopen(waiting.c_str(), "w")) std::fclose(f);
  while (!stopping && access(path, F_OK) == 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::remove(waiting.c_str());
}

std::unique_ptr<google::protobuf::Message> NewMessage(const google::protobuf::Descriptor* type) {
  return std::unique_ptr<Message>(
      google::protobuf::MessageFactory::generated_factory()->GetPrototype(type)->New());
}

}  // namespace gvd
