#include "server/grpc/server.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <pthread.h>

#include <algorithm>
#include <climits>
#include <functional>
#include <optional>
#include <set>
#include <string_view>
#include <utility>
#include <vector>

#include <boost/asio/post.hpp>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "grpc/health/v1/health.pb.h"
#include "grpc/reflection/v1alpha/reflection.pb.h"
#include "server/app/methods.h"

namespace gvd {
namespace {

using google::protobuf::Message;
using HealthRequest = grpc::health::v1::HealthCheckRequest;
using HealthResponse = grpc::health::v1::HealthCheckResponse;
namespace reflection = grpc::reflection::v1alpha;

const char* const kHealthService = "grpc.health.v1.Health";
const char* const kReflectionService = "grpc.reflection.v1alpha.ServerReflection";
// Calls awaited at once: gRPC queues a call that comes while none is.
constexpr int kAwaited = 4;

// The paths of the calls served ("/package.Service/Method"), made once: a call's method is
// one of these.
struct Paths {
  std::string core = absl::StrCat("/", kServiceName, "/");  // a prefix: the method follows
  std::string health_check = absl::StrCat("/", kHealthService, "/Check");
  std::string health_watch = absl::StrCat("/", kHealthService, "/Watch");
  std::string reflection = absl::StrCat("/", kReflectionService, "/ServerReflectionInfo");
};
const Paths& CallPaths() {
  static const Paths paths;
  return paths;
}

grpc::Status ToGrpc(const absl::Status& s) {
  if (s.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(s.code()), std::string(s.message()));
}

grpc::ByteBuffer Serialize(const Message& message) {
  grpc::ByteBuffer out;
  bool own = false;
  (void)grpc::SerializationTraits<Message>::Serialize(message, &out, &own);
  return out;
}

bool Parse(grpc::ByteBuffer* in, Message* message) {
  return grpc::SerializationTraits<Message>::Deserialize(in, message).ok();
}

// An answer of grpc.reflection.v1alpha from the descriptors this program is built with.
reflection::ServerReflectionResponse Reflect(const reflection::ServerReflectionRequest& request) {
  using google::protobuf::FileDescriptor;
  const auto* pool = google::protobuf::DescriptorPool::generated_pool();
  reflection::ServerReflectionResponse response;
  response.set_valid_host(request.host());
  *response.mutable_original_request() = request;
  auto error = [&response](grpc::StatusCode code, std::string message) {
    response.mutable_error_response()->set_error_code(code);
    response.mutable_error_response()->set_error_message(std::move(message));
  };
  // The file and every file it imports, directly or not, each once.
  auto files = [&response](const FileDescriptor* file) {
    auto* out = response.mutable_file_descriptor_response();
    std::set<const FileDescriptor*> seen;
    std::vector<const FileDescriptor*> next{file};
    while (!next.empty()) {
      const FileDescriptor* f = next.back();
      next.pop_back();
      if (!seen.insert(f).second) continue;
      google::protobuf::FileDescriptorProto proto;
      f->CopyTo(&proto);
      out->add_file_descriptor_proto(proto.SerializeAsString());
      for (int i = 0; i < f->dependency_count(); ++i) next.push_back(f->dependency(i));
    }
  };
  // `file`'s answer, or NOT_FOUND naming `what` was asked for.
  auto found = [&](const FileDescriptor* file, const std::string& what) {
    if (file == nullptr) return error(grpc::StatusCode::NOT_FOUND, absl::StrCat("no ", what));
    files(file);
  };
  switch (request.message_request_case()) {
    case reflection::ServerReflectionRequest::kFileByFilename:
      found(pool->FindFileByName(request.file_by_filename()),
            absl::StrCat("file named \"", request.file_by_filename(), "\""));
      break;
    case reflection::ServerReflectionRequest::kFileContainingSymbol:
      found(pool->FindFileContainingSymbol(request.file_containing_symbol()),
            absl::StrCat("symbol \"", request.file_containing_symbol(), "\""));
      break;
    case reflection::ServerReflectionRequest::kFileContainingExtension: {
      const auto& asked = request.file_containing_extension();
      const auto* type = pool->FindMessageTypeByName(asked.containing_type());
      const auto* extension =
          type == nullptr ? nullptr : pool->FindExtensionByNumber(type, asked.extension_number());
      found(extension == nullptr ? nullptr : extension->file(),
            absl::StrCat("extension ", asked.extension_number(), " of \"",
                         asked.containing_type(), "\""));
      break;
    }
    case reflection::ServerReflectionRequest::kAllExtensionNumbersOfType: {
      const auto* type = pool->FindMessageTypeByName(request.all_extension_numbers_of_type());
      if (type == nullptr) {
        error(grpc::StatusCode::NOT_FOUND,
              absl::StrCat("no message type \"", request.all_extension_numbers_of_type(), "\""));
        break;
      }
      std::vector<const google::protobuf::FieldDescriptor*> extensions;
      pool->FindAllExtensions(type, &extensions);
      auto* out = response.mutable_all_extension_numbers_response();
      out->set_base_type_name(type->full_name());
      for (const auto* e : extensions) out->add_extension_number(e->number());
      break;
    }
    case reflection::ServerReflectionRequest::kListServices:
      for (const char* name : {kServiceName, kHealthService, kReflectionService}) {
        response.mutable_list_services_response()->add_service()->set_name(name);
      }
      break;
    case reflection::ServerReflectionRequest::MESSAGE_REQUEST_NOT_SET:
      error(grpc::StatusCode::INVALID_ARGUMENT, "the request asks for nothing");
      break;
  }
  return response;
}

}  // namespace

// One call, from the time it is awaited until gRPC and the core are done with it. It lives
// while anything holds it: each operation started on its stream until its tag comes back,
// the core from the call's start until its answer (a stream's end), a conversion, a health
// watch until the caller goes. Each tag comes back on the polling thread.
class GrpcServer::Exchange {
 public:
  enum class Op { kRequest, kRead, kWrite, kFinish, kDone };
  struct Tag {
    Exchange* exchange;
    Op op;
  };

  explicit Exchange(GrpcServer* server) : server_(server) {
    ctx_.AsyncNotifyWhenDone(&done_tag_);
    server_->generic_.RequestCall(&ctx_, &stream_, server_->cq_.get(), server_->cq_.get(),
                                  &request_tag_);
  }

  void On(Op op, bool ok) {
    switch (op) {
      case Op::kRequest: Requested(ok); break;
      case Op::kRead: Read(ok); break;
      case Op::kWrite: Wrote(ok); break;
      case Op::kFinish: break;
      case Op::kDone: Done(); break;
    }
    Release();
  }

  // A health watch's status changed (called under the server's lock).
  void Notify(int status) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      latest_ = status;
    }
    SendHealth();
  }
  const std::string& watched() const { return health_service_; }

 private:
  enum class Kind { kUnknown, kUnary, kStream, kHealthCheck, kHealthWatch, kReflection };

  // The core's view of a server stream.
  class Out final : public StreamOut {
   public:
    explicit Out(Exchange* e) : e_(e) {}
    void Message(const google::protobuf::Message& message,
                 std::function<void(bool)> written) override {
      e_->StreamWrite(message, std::move(written));
    }
    void End(const absl::Status& status) override { e_->StreamEnd(ToGrpc(status)); }

   private:
    Exchange* const e_;
  };

  void Hold() {
    std::lock_guard<std::mutex> lock(mu_);
    ++holds_;
  }
  void Release() {
    bool last;
    {
      std::lock_guard<std::mutex> lock(mu_);
      last = --holds_ == 0;
    }
    if (!last) return;
    GrpcServer* server = server_;
    delete this;
    server->Ended();
  }

  void Requested(bool ok) {
    if (!ok) {  // the server stopped before a call came: no done tag follows
      Release();
      return;
    }
    server_->Request();
    std::string authorization;
    if (server_->core_->checks_tokens()) {
      const auto& md = ctx_.client_metadata();
      auto it = md.find("authorization");
      if (it != md.end()) authorization.assign(it->second.data(), it->second.size());
    }
    call_ = std::make_shared<Call>(std::move(authorization));
    const std::string& name = ctx_.method();
    const Paths& paths = CallPaths();
    if (absl::StartsWith(name, paths.core)) {
      method_ = FindMethod(std::string_view(name).substr(paths.core.size()));
      if (method_ != nullptr) kind_ = method_->unary ? Kind::kUnary : Kind::kStream;
    } else if (name == paths.health_check) {
      kind_ = Kind::kHealthCheck;
    } else if (name == paths.health_watch) {
      kind_ = Kind::kHealthWatch;
    } else if (name == paths.reflection) {
      kind_ = Kind::kReflection;
    }
    if (kind_ == Kind::kUnknown) {
      return Finish(grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                                 absl::StrCat("this server has no method \"", name, "\"")));
    }
    StartRead();
  }

  void StartRead() {
    Hold();
    stream_.Read(&in_, &read_tag_);
  }

  void Read(bool ok) {
    if (kind_ == Kind::kReflection) return ReflectionRequest(ok);
    if (!ok) {  // the caller went, or half-closed with no message
      return Finish(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "the call carried no request"));
    }
    switch (kind_) {
      case Kind::kUnary:
      case Kind::kStream:
        if (in_.Length() <= kConvertHereBytes) return Begin();
        Hold();  // the conversion's
        boost::asio::post(server_->converter_, [this] {
          HoldConversions(server_->stopping_);
          Begin();
          Release();
        });
        return;
      case Kind::kHealthCheck: {
        HealthRequest request;
        if (!Parse(&in_, &request)) return NotParsed("grpc.health.v1.HealthCheckRequest");
        const int status = server_->HealthStatus(request.service());
        if (status == HealthResponse::SERVICE_UNKNOWN) {
          return Finish(grpc::Status(grpc::StatusCode::NOT_FOUND,
                                     absl::StrCat("unknown service \"", request.service(), "\"")));
        }
        HealthResponse response;
        response.set_status(static_cast<HealthResponse::ServingStatus>(status));
        return Answer(response);
      }
      case Kind::kHealthWatch: {
        HealthRequest request;
        if (!Parse(&in_, &request)) return NotParsed("grpc.health.v1.HealthCheckRequest");
        health_service_ = request.service();
        {
          std::lock_guard<std::mutex> lock(mu_);
          if (over_) return;
          watching_ = true;
          ++holds_;  // the watch's, until the caller goes (Done)
        }
        server_->Watch(this, true);
        return;
      }
      default:
        return;
    }
  }

  void NotParsed(const std::string& type) {
    Finish(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat("the request is not a ", type)));
  }

  // A call of the service, its request read: parsed and handed to the core.
  void Begin() {
    const auto* descriptor = method_->descriptor;
    request_ = NewMessage(descriptor->input_type());
    if (!Parse(&in_, request_.get())) return NotParsed(descriptor->input_type()->full_name());
    Hold();  // the core's, until its answer or the stream's end
    if (kind_ == Kind::kStream) {
      method_->streaming(server_->core_, call_, *request_, std::make_shared<Out>(this));
      return;
    }
    response_ = NewMessage(descriptor->output_type());
    method_->unary(server_->core_, call_, *request_, response_.get(),
                   [this](const absl::Status& s) {
                     if (s.ok()) {
                       Answer(*response_);
                     } else {
                       Finish(ToGrpc(s));
                     }
                     Release();
                   });
  }

  // A unary call's answer, refused past the message limit as the HTTP transport refuses it.
  void Answer(const Message& response) {
    const size_t bytes = response.ByteSizeLong();
    const size_t limit = server_->options_.max_message_bytes;
    if (bytes > limit) {
      return Finish(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                 absl::StrCat("the answer is ", bytes, " bytes, over the limit of ",
                                              limit, " (--max-message-bytes)")));
    }
    out_ = Serialize(response);
    Hold();
    stream_.WriteAndFinish(out_, grpc::WriteOptions(), grpc::Status::OK, &finish_tag_);
  }

  void Finish(const grpc::Status& status) {
    Hold();
    stream_.Finish(status, &finish_tag_);
  }

  void StreamWrite(const Message& message, std::function<void(bool)> written) {
    grpc::ByteBuffer bytes = Serialize(message);
    {
      std::lock_guard<std::mutex> lock(mu_);
      out_ = std::move(bytes);
      written_ = std::move(written);
      writing_ = true;
      ++holds_;
    }
    stream_.Write(out_, &write_tag_);
  }

  // The core's end of a stream: after the write under way, if one is.
  void StreamEnd(const grpc::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (writing_) {
        end_ = status;
        return;
      }
    }
    Finish(status);
    Release();  // the core's
  }

  void Wrote(bool ok) {
    if (kind_ == Kind::kReflection) {
      if (ok) StartRead();
      return;
    }
    if (kind_ == Kind::kHealthWatch) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        writing_ = false;
      }
      if (ok) SendHealth();
      return;
    }
    std::function<void(bool)> written;
    {
      std::lock_guard<std::mutex> lock(mu_);
      writing_ = false;
      written = std::move(written_);
    }
    written(ok);
    std::optional<grpc::Status> end;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (!writing_ && end_) {
        end = std::move(end_);
        end_.reset();
      }
    }
    if (end) {
      Finish(*end);
      Release();  // the core's
    }
  }

  // The call is over: finished, or the caller went, or its deadline passed.
  void Done() {
    if (ctx_.IsCancelled()) call_->Cancel();
    bool watching;
    {
      std::lock_guard<std::mutex> lock(mu_);
      over_ = true;
      watching = watching_;
      watching_ = false;
    }
    if (watching) {
      server_->Watch(this, false);
      Release();  // the watch's
    }
  }

  void SendHealth() {
    HealthResponse response;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (writing_ || over_ || latest_ == sent_) return;
      writing_ = true;
      sent_ = latest_;
      ++holds_;
      response.set_status(static_cast<HealthResponse::ServingStatus>(latest_));
      out_ = Serialize(response);
    }
    stream_.Write(out_, &write_tag_);
  }

  void ReflectionRequest(bool ok) {
    if (!ok) return Finish(grpc::Status::OK);  // the caller has asked all it had
    reflection::ServerReflectionRequest request;
    if (!Parse(&in_, &request)) return NotParsed("grpc.reflection.v1alpha.ServerReflectionRequest");
    out_ = Serialize(Reflect(request));
    Hold();
    stream_.Write(out_, &write_tag_);
  }

  friend class GrpcServer;

  GrpcServer* const server_;
  grpc::GenericServerContext ctx_;
  grpc::GenericServerAsyncReaderWriter stream_{&ctx_};
  Tag request_tag_{this, Op::kRequest};
  Tag read_tag_{this, Op::kRead};
  Tag write_tag_{this, Op::kWrite};
  Tag finish_tag_{this, Op::kFinish};
  Tag done_tag_{this, Op::kDone};
  grpc::ByteBuffer in_;
  Kind kind_ = Kind::kUnknown;
  const Method* method_ = nullptr;
  CallPtr call_;
  std::unique_ptr<Message> request_, response_;
  std::string health_service_;

  std::mutex mu_;  // guards what follows
  int holds_ = 2;  // the request's tag and the done tag (which comes once a call has come)
  grpc::ByteBuffer out_;
  bool writing_ = false;
  std::function<void(bool)> written_;
  std::optional<grpc::Status> end_;
  bool over_ = false;      // the done tag came
  bool watching_ = false;  // a health watch, in the server's watches_
  int latest_ = -1, sent_ = -1;  // a health watch's status now and the one sent last
};

GrpcServer::GrpcServer(GrpcOptions options, Service* core)
    : options_(std::move(options)), core_(core) {}

absl::StatusOr<std::unique_ptr<GrpcServer>> GrpcServer::Start(GrpcOptions options,
                                                              Service* core) {
  std::unique_ptr<GrpcServer> server(new GrpcServer(std::move(options), core));
  const int limit = static_cast<int>(std::min<size_t>(server->options_.max_message_bytes, INT_MAX));
  grpc::ServerBuilder builder;
  builder.AddListeningPort(server->options_.listen,
                           server->options_.credentials ? server->options_.credentials
                                                        : grpc::InsecureServerCredentials(),
                           &server->port_);
  builder.SetMaxReceiveMessageSize(limit);
  builder.SetMaxSendMessageSize(limit);
  builder.RegisterAsyncGenericService(&server->generic_);
  server->cq_ = builder.AddCompletionQueue();
  server->server_ = builder.BuildAndStart();
  if (!server->server_ || server->port_ == 0) {
    server->stopped_ = true;
    server->converter_.stop();
    server->converter_.join();
    return absl::UnavailableError(
        absl::StrCat("gRPC cannot listen on \"", server->options_.listen, "\""));
  }
  server->serving_[""] = false;
  // The first calls are awaited before the polling thread starts, so that it sees them made
  // (the thread's start orders them before it; every later one it makes itself).
  for (int i = 0; i < kAwaited; ++i) server->Request();
  server->poller_ = std::thread([s = server.get()] { s->Poll(); });
  return server;
}

GrpcServer::~GrpcServer() { Shutdown(std::chrono::system_clock::now()); }

void GrpcServer::Poll() {
  pthread_setname_np(pthread_self(), "gvd-grpc");
  void* tag = nullptr;
  bool ok = false;
  while (cq_->Next(&tag, &ok)) {
    auto* t = static_cast<Exchange::Tag*>(tag);
    t->exchange->On(t->op, ok);
  }
}

void GrpcServer::Request() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_) return;
    ++calls_;
  }
  new Exchange(this);
}

void GrpcServer::Ended() {
  std::lock_guard<std::mutex> lock(mu_);
  if (--calls_ == 0) ended_.notify_all();
}

void GrpcServer::Shutdown(std::chrono::system_clock::time_point deadline) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopped_) return;
    stopped_ = true;
    stopping_ = true;
  }
  server_->Shutdown(deadline);
  {
    std::unique_lock<std::mutex> lock(mu_);
    ended_.wait(lock, [this] { return calls_ == 0; });
  }
  cq_->Shutdown();
  poller_.join();
  converter_.stop();
  converter_.join();
}

int GrpcServer::HealthStatus(const std::string& service) {
  std::lock_guard<std::mutex> lock(mu_);
  return HealthStatusLocked(service);
}

int GrpcServer::HealthStatusLocked(const std::string& service) const {
  auto it = serving_.find(service);
  if (it == serving_.end()) return HealthResponse::SERVICE_UNKNOWN;
  return it->second ? HealthResponse::SERVING : HealthResponse::NOT_SERVING;
}

void GrpcServer::NotifyWatchesLocked() {
  // A watch told its status unchanged sends nothing (Exchange::SendHealth).
  for (Exchange* e : watches_) e->Notify(HealthStatusLocked(e->watched()));
}

void GrpcServer::Watch(Exchange* exchange, bool watching) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!watching) {
    watches_.erase(exchange);
    return;
  }
  watches_.insert(exchange);
  exchange->Notify(HealthStatusLocked(exchange->watched()));
}

void GrpcServer::SetServing(const std::string& service, bool serving) {
  std::lock_guard<std::mutex> lock(mu_);
  serving_[service] = serving;
  NotifyWatchesLocked();
}

void GrpcServer::SetServing(bool serving) {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto& [service, now] : serving_) now = serving;
  NotifyWatchesLocked();
}

}  // namespace gvd
