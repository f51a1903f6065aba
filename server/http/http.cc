#include "server/http/http.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/generic/generic_stub.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/ssl.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <charconv>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include <zlib.h>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "server/log.h"

namespace gvd {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using google::protobuf::Message;
using google::protobuf::MethodDescriptor;

const char* const kService = "gvd.v1.Voronoi";

// The Connect protocol's name and HTTP status for each gRPC code.
struct ConnectCode {
  const char* name;
  http::status status;
};
ConnectCode ToConnect(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::CANCELLED: return {"canceled", static_cast<http::status>(499)};
    case grpc::StatusCode::INVALID_ARGUMENT: return {"invalid_argument", http::status::bad_request};
    case grpc::StatusCode::DEADLINE_EXCEEDED: return {"deadline_exceeded", http::status::gateway_timeout};
    case grpc::StatusCode::NOT_FOUND: return {"not_found", http::status::not_found};
    case grpc::StatusCode::ALREADY_EXISTS: return {"already_exists", http::status::conflict};
    case grpc::StatusCode::PERMISSION_DENIED: return {"permission_denied", http::status::forbidden};
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return {"resource_exhausted", http::status::too_many_requests};
    case grpc::StatusCode::FAILED_PRECONDITION: return {"failed_precondition", http::status::bad_request};
    case grpc::StatusCode::ABORTED: return {"aborted", http::status::conflict};
    case grpc::StatusCode::OUT_OF_RANGE: return {"out_of_range", http::status::bad_request};
    case grpc::StatusCode::UNIMPLEMENTED: return {"unimplemented", http::status::not_implemented};
    case grpc::StatusCode::INTERNAL: return {"internal", http::status::internal_server_error};
    case grpc::StatusCode::UNAVAILABLE: return {"unavailable", http::status::service_unavailable};
    case grpc::StatusCode::DATA_LOSS: return {"data_loss", http::status::internal_server_error};
    case grpc::StatusCode::UNAUTHENTICATED: return {"unauthenticated", http::status::unauthorized};
    default: return {"unknown", http::status::internal_server_error};
  }
}

// {"code": ..., "message": ...}, the message escaped by protobuf's JSON printer.
std::string JsonString(const std::string& text);
std::string ErrorJson(const char* code, const std::string& message) {
  return absl::StrCat("{\"code\":\"", code, "\",\"message\":", JsonString(message), "}");
}

std::string Bytes(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  (void)buffer.Dump(&slices);
  std::string out;
  for (const auto& s : slices) out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

grpc::ByteBuffer Buffer(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

// A 5-byte Connect envelope (flags, big-endian length) and its payload.
std::string Envelope(uint8_t flags, const std::string& payload) {
  std::string out(5, '\0');
  out[0] = static_cast<char>(flags);
  const uint32_t n = static_cast<uint32_t>(payload.size());
  for (int i = 0; i < 4; ++i) out[1 + i] = static_cast<char>((n >> (24 - 8 * i)) & 0xff);
  return out + payload;
}

// One HTTP/1.1 connection: requests one at a time; each RPC forwarded over the generic stub.
class SessionBase : public std::enable_shared_from_this<SessionBase> {
 public:
  virtual ~SessionBase() = default;
  // Closes the connection when it is idle now or after its current request (the drain).
  virtual void CloseWhenIdle() = 0;
};

}  // namespace

namespace {

// A gzip body inflated, refused past `limit` bytes (a small body can inflate to any size).
absl::StatusOr<std::string> Gunzip(const std::string& in, size_t limit) {
  z_stream z{};
  if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK) return absl::InternalError("zlib failed");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  std::string out;
  char buf[1 << 16];
  int r = Z_OK;
  while (r != Z_STREAM_END) {
    z.next_out = reinterpret_cast<Bytef*>(buf);
    z.avail_out = sizeof buf;
    r = inflate(&z, Z_NO_FLUSH);
    if (r != Z_OK && r != Z_STREAM_END) break;
    out.append(buf, sizeof buf - z.avail_out);
    if (out.size() > limit) {
      inflateEnd(&z);
      return absl::ResourceExhaustedError(absl::StrCat(
          "the request body inflates past ", limit, " bytes (--max-message-bytes)"));
    }
    if (r == Z_OK && z.avail_in == 0 && z.avail_out != 0) break;  // cut short
  }
  inflateEnd(&z);
  if (r != Z_STREAM_END) return absl::InvalidArgumentError("the body is not whole gzip");
  return out;
}

// A JSON string of `text`, escaped by protobuf's JSON printer.
std::string JsonString(const std::string& text) {
  google::protobuf::Value value;
  value.set_string_value(text);
  std::string quoted;
  (void)google::protobuf::util::MessageToJsonString(value, &quoted);
  return quoted;
}

// Whether a request header is the call's metadata (as Connect servers pass them on): not the
// HTTP connection's, the body's or the protocol's own, nor the browser's (cookies included).
// Names gRPC would refuse (any but lower-case letters, digits, '-', '_' and '.') are not.
bool IsMetadata(const std::string& name) {
  static const std::set<std::string> kNot = {
      "host", "connection", "keep-alive", "proxy-connection", "transfer-encoding", "upgrade",
      "te", "trailer", "content-type", "content-length", "content-encoding", "accept",
      "accept-encoding", "accept-language", "user-agent", "origin", "referer", "cookie",
      "authorization", "expect", "cache-control", "pragma", "priority", "dnt"};
  if (name.empty() || kNot.count(name) > 0) return false;
  for (const char* prefix : {"connect-", "grpc-", "access-control-", "sec-", "proxy-"}) {
    if (absl::StartsWith(name, prefix)) return false;
  }
  for (char c : name) {
    if (!absl::ascii_islower(c) && !absl::ascii_isdigit(c) && c != '-' && c != '_' && c != '.') {
      return false;
    }
  }
  return true;
}

// A gRPC metadata value as an HTTP header's: binary ("-bin") in base64.
std::string HeaderValue(const grpc::string_ref& key, const grpc::string_ref& value) {
  std::string v(value.data(), value.size());
  return absl::EndsWith(absl::string_view(key.data(), key.size()), "-bin") ? absl::Base64Escape(v)
                                                                             : v;
}

using Metadata = std::vector<std::pair<std::string, std::string>>;

// The service's metadata that an answer carries: not gRPC's own.
Metadata AnswerMetadata(const std::multimap<grpc::string_ref, grpc::string_ref>& md) {
  Metadata out;
  for (const auto& [k, v] : md) {
    absl::string_view key(k.data(), k.size());
    if (absl::StartsWith(key, "grpc-") || absl::StartsWith(key, ":")) continue;
    out.emplace_back(std::string(key), HeaderValue(k, v));
  }
  return out;
}

// `in` gzip-compressed, fast (zlib's level 1: an answer is compressed on the request's path).
std::string Gzip(const std::string& in) {
  z_stream z{};
  if (deflateInit2(&z, Z_BEST_SPEED, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    return {};
  }
  std::string out(deflateBound(&z, in.size()), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int r = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return r == Z_STREAM_END ? out : std::string();
}

// Whether an Accept-Encoding header takes gzip (listed, and not with q=0).
bool AcceptsGzip(absl::string_view header) {
  for (absl::string_view item : absl::StrSplit(header, ',')) {
    std::vector<absl::string_view> parts = absl::StrSplit(item, ';');
    if (!absl::EqualsIgnoreCase(absl::StripAsciiWhitespace(parts[0]), "gzip")) continue;
    for (size_t k = 1; k < parts.size(); ++k) {
      absl::string_view q = absl::StripAsciiWhitespace(parts[k]);
      double value = 1;
      if (absl::ConsumePrefix(&q, "q=") && absl::SimpleAtod(q, &value) && value <= 0) {
        return false;
      }
    }
    return true;
  }
  return false;
}

}  // namespace

ConnectCall DecodeConnectCall(const std::string& name, bool post, const std::string& content_type,
                              std::string body, const std::string& timeout_ms,
                              const std::string& encoding, size_t max_bytes) {
  ConnectCall call;
  auto refuse = [&call](grpc::StatusCode code, std::string message, int http_status = 0) {
    call.method = nullptr;
    call.code = code;
    call.message = std::move(message);
    call.http_status = http_status;
    return std::move(call);
  };
  const MethodDescriptor* method =
      google::protobuf::DescriptorPool::generated_pool()->FindMethodByName(
          absl::StrCat(kService, ".", name));
  if (method == nullptr) {
    return refuse(grpc::StatusCode::UNIMPLEMENTED,
                  absl::StrCat(kService, " has no method \"", name, "\""),
                  static_cast<int>(http::status::not_found));
  }
  if (!post) {
    return refuse(grpc::StatusCode::UNIMPLEMENTED,
                  absl::StrCat("call ", kService, "/", name, " with POST"),
                  static_cast<int>(http::status::method_not_allowed));
  }
  std::string type = absl::AsciiStrToLower(content_type);
  type = std::string(absl::StripAsciiWhitespace(type.substr(0, type.find(';'))));
  const bool streaming = method->server_streaming();
  const std::string want_json = streaming ? "application/connect+json" : "application/json";
  const std::string want_proto = streaming ? "application/connect+proto" : "application/proto";
  if (type != want_json && type != want_proto) {
    return refuse(grpc::StatusCode::UNIMPLEMENTED,
                  absl::StrCat("Content-Type \"", type, "\" is not supported by ", name,
                               ": send ", want_json, " (or ", want_proto, ")"),
                  static_cast<int>(http::status::unsupported_media_type));
  }
  call.json = type == want_json;
  call.content_type = call.json ? want_json : want_proto;
  const std::string coding = absl::AsciiStrToLower(absl::StripAsciiWhitespace(encoding));
  if (!coding.empty() && coding != "identity" && coding != "gzip") {
    return refuse(grpc::StatusCode::UNIMPLEMENTED,
                  absl::StrCat(streaming ? "Connect-Content-Encoding" : "Content-Encoding", " \"",
                               coding, "\" is not supported: send gzip or identity"));
  }
  // Inflates `bytes` in place; a refusal on failure.
  auto inflate = [&](std::string& bytes) -> std::optional<ConnectCall> {
    auto inflated = Gunzip(bytes, max_bytes);
    if (!inflated.ok()) {
      return refuse(static_cast<grpc::StatusCode>(inflated.status().code()),
                    std::string(inflated.status().message()),
                    0);
    }
    bytes = std::move(*inflated);
    return std::nullopt;
  };
  if (!streaming && coding == "gzip") {
    if (auto refused = inflate(body)) return std::move(*refused);
  }
  if (streaming) {
    // One enveloped message, compressed (flag 1) only as Connect-Content-Encoding says.
    if (body.size() < 5) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    "a streaming request's body must be one Connect envelope");
    }
    const bool compressed = (static_cast<uint8_t>(body[0]) & 0x01) != 0;
    if (compressed && coding != "gzip") {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    "the request's envelope is compressed, and Connect-Content-Encoding names "
                    "no compression");
    }
    const uint32_t n = (uint32_t(uint8_t(body[1])) << 24) | (uint32_t(uint8_t(body[2])) << 16) |
                       (uint32_t(uint8_t(body[3])) << 8) | uint32_t(uint8_t(body[4]));
    if (n != body.size() - 5) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    absl::StrCat("the request's envelope says ", n, " bytes; ", body.size() - 5,
                                 " follow it"));
    }
    body = body.substr(5);
    if (compressed) {
      if (auto refused = inflate(body)) return std::move(*refused);
    }
  }
  auto* prototype =
      google::protobuf::MessageFactory::generated_factory()->GetPrototype(method->input_type());
  if (call.json) {
    std::unique_ptr<Message> message(prototype->New());
    google::protobuf::util::JsonParseOptions parse;
    // A newer client's fields are ignored, as protobuf's JSON mapping and Connect's servers
    // do, so that it can talk to an older server.
    parse.ignore_unknown_fields = true;
    if (auto s = google::protobuf::util::JsonStringToMessage(body.empty() ? "{}" : body,
                                                               message.get(), parse);
        !s.ok()) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    absl::StrCat("the body is not a ", method->input_type()->name(), " in JSON: ",
                                 s.message().ToString()));
    }
    call.request = message->SerializeAsString();
  } else {
    std::unique_ptr<Message> message(prototype->New());
    if (!message->ParseFromString(body)) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    absl::StrCat("the body is not a ", method->input_type()->name(),
                                 " in binary protobuf"));
    }
    call.request = std::move(body);
  }
  if (!timeout_ms.empty()) {
    int64_t ms = 0;
    if (!absl::SimpleAtoi(timeout_ms, &ms) || ms <= 0) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    absl::StrCat("Connect-Timeout-Ms must be a positive number, not \"",
                                 timeout_ms, "\""));
    }
    call.timeout = std::chrono::milliseconds(ms);
  }
  call.method = method;
  return call;
}

class HttpServer::Impl {
 public:
  Impl(HttpOptions options, std::shared_ptr<grpc::Channel> channel)
      : options_(std::move(options)), channel_(std::move(channel)), stub_(channel_),
        acceptor_(net::make_strand(ioc_)) {}

  absl::Status Start();
  void Shutdown(std::chrono::milliseconds grace);
  int port() const { return port_; }

  // What sessions need.
  const HttpOptions& options() const { return options_; }
  grpc::GenericStub& stub() { return stub_; }
  bool Allowed(const std::string& origin) const {
    for (const auto& o : options_.cors_origins) {
      if (o == "*" || o == origin) return true;
    }
    return false;
  }
  void Register(const std::shared_ptr<SessionBase>& s) {
    {
      std::lock_guard<std::mutex> lock(sessions_mu_);
      sessions_.emplace(s.get(), s);
    }
    if (stopping_) s->CloseWhenIdle();
  }
  void Unregister(SessionBase* s) {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    sessions_.erase(s);
  }
  bool stopping() const { return stopping_; }

 private:
  void Accept();

  HttpOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  grpc::GenericStub stub_;
  net::io_context ioc_;
  std::optional<ssl::context> tls_;
  tcp::acceptor acceptor_;  // on a strand of its own: its handler and Shutdown's close
  std::vector<std::thread> threads_;
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work_;
  int port_ = 0;
  std::atomic<bool> stopping_{false};
  std::mutex sessions_mu_;
  std::map<SessionBase*, std::weak_ptr<SessionBase>> sessions_;
};

namespace {

template <class StreamType>
class Session final : public SessionBase {
 public:
  Session(HttpServer::Impl* server, StreamType stream)
      : server_(server), stream_(std::move(stream)) {}
  ~Session() override { server_->Unregister(this); }

  void Run() {
    if constexpr (std::is_same_v<StreamType, beast::tcp_stream>) {
      Read();
    } else {
      beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(30));
      stream_.async_handshake(ssl::stream_base::server,
                              [self = Self()](beast::error_code ec) {
                                if (ec) return;  // a failed handshake: nothing to answer
                                self->Read();
                              });
    }
  }

  void CloseWhenIdle() override {
    net::post(stream_.get_executor(), [self = Self()] {
      self->closing_ = true;
      if (self->idle_) self->Close();
    });
  }

 private:
  std::shared_ptr<Session> Self() {
    return std::static_pointer_cast<Session>(shared_from_this());
  }

  // The header first: a body declared past --max-message-bytes is drained, not read.
  void Read() {
    if (closing_) return Close();
    idle_ = true;
    header_parser_.emplace();
    header_parser_->header_limit(64 << 10);
    // Beast checks a declared length against the body limit with the header: not yet.
    header_parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(120));
    http::async_read_header(stream_, buffer_, *header_parser_,
                            [self = Self()](beast::error_code ec, size_t) { self->OnHeader(ec); });
  }

  void OnHeader(beast::error_code ec) {
    idle_ = false;
    if (ec) return Close();  // the peer went, timed out, or spoke no HTTP
    // What an answer follows of the request, whichever path answers it (a refusal of its
    // body included): its HTTP version, keep-alive and origin.
    {
      const auto& req = header_parser_->get();
      version_ = req.version();
      keep_alive_ = req.keep_alive() && !server_->stopping();
      origin_ = std::string(req[http::field::origin]);
      // A Connect streaming call is answered 200 even when refused, its error in the
      // end-of-stream message: streaming clients read no error from an HTTP status.
      stream_type_.clear();
      const auto target = req.target();
      const auto field = req[http::field::content_type];
      std::string type = absl::AsciiStrToLower(std::string(field.data(), field.size()));
      type = std::string(absl::StripAsciiWhitespace(type.substr(0, type.find(';'))));
      if (req.method() == http::verb::post &&
          absl::StartsWith(absl::string_view(target.data(), target.size()),
                           absl::StrCat("/", kService, "/")) &&
          (type == "application/connect+json" || type == "application/connect+proto")) {
        stream_type_ = type;
      }
    }
    const uint64_t limit = server_->options().max_body_bytes;
    if (auto length = header_parser_->content_length(); length && *length > limit) {
      return Drain(*length);
    }
    const bool chunked = header_parser_->chunked();
    parser_.emplace(std::move(*header_parser_));
    header_parser_.reset();
    parser_->body_limit(limit);
    chunked_body_.clear();
    chunked_over_ = false;
    if (chunked) {
      // A chunked body (a streaming client's) declares no length: its chunks are kept while
      // within the limit, then read through and dropped (up to kDrainBytes), to be answered
      // as a declared one is.
      parser_->body_limit(kDrainBytes);
      on_chunk_ = [this, limit](uint64_t, beast::string_view body, beast::error_code&) {
        if (!chunked_over_ && chunked_body_.size() + body.size() <= limit) {
          chunked_body_.append(body.data(), body.size());
        } else if (!chunked_over_) {
          chunked_over_ = true;
          std::string().swap(chunked_body_);
        }
        return body.size();
      };
      parser_->on_chunk_body(on_chunk_);
    }
    http::async_read(stream_, buffer_, *parser_,
                     [self = Self()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec == http::error::body_limit) {  // a chunked body past kDrainBytes: answered, closed
      keep_alive_ = false;
      return Error(grpc::StatusCode::RESOURCE_EXHAUSTED, TooLarge("the request body"));
    }
    if (ec) return Close();  // the peer went, timed out, or spoke no HTTP
    if (chunked_over_) {
      std::string().swap(chunked_body_);
      return Error(grpc::StatusCode::RESOURCE_EXHAUSTED, TooLarge("the request body"));
    }
    auto req = parser_->release();
    if (req.chunked()) req.body() = std::move(chunked_body_);
    Handle(std::move(req));
  }

  std::string TooLarge(const std::string& what) const {
    return absl::StrCat(what, " exceeds ", server_->options().max_body_bytes,
                        " bytes (--max-message-bytes)");
  }

  // A body declared past --max-message-bytes is read and dropped (up to kDrainBytes), then
  // answered RESOURCE_EXHAUSTED (429) on a connection that stays open: a client still
  // sending it would otherwise meet a closed socket, not the answer. Beyond kDrainBytes the
  // answer comes at once and the connection closes.
  static constexpr uint64_t kDrainBytes = 256ull << 20;
  void Drain(uint64_t length) {
    drain_message_ = TooLarge(absl::StrCat("the request body of ", length, " bytes"));
    if (length > kDrainBytes) {
      keep_alive_ = false;
      header_parser_.reset();
      return Error(grpc::StatusCode::RESOURCE_EXHAUSTED, drain_message_);
    }
    drain_parser_.emplace(std::move(*header_parser_));
    header_parser_.reset();
    drain_parser_->body_limit(length);
    if (!scratch_) scratch_ = std::make_unique<char[]>(kScratch);
    DrainSome();
  }
  static constexpr size_t kScratch = 64 << 10;
  void DrainSome() {
    drain_parser_->get().body().data = scratch_.get();
    drain_parser_->get().body().size = kScratch;
    http::async_read(stream_, buffer_, *drain_parser_,
                     [self = Self()](beast::error_code ec, size_t) {
                       if (ec == http::error::need_buffer) ec = {};
                       if (ec) return self->Close();
                       if (!self->drain_parser_->is_done()) return self->DrainSome();
                       self->drain_parser_.reset();
                       self->Error(grpc::StatusCode::RESOURCE_EXHAUSTED, self->drain_message_);
                     });
  }

  void Handle(http::request<http::string_body> req) {
    version_ = req.version();
    keep_alive_ = req.keep_alive() && !server_->stopping();
    origin_ = std::string(req[http::field::origin]);
    {
      const auto accept = req[http::field::accept_encoding];
      gzip_answer_ = AcceptsGzip(absl::string_view(accept.data(), accept.size()));
    }
    std::string target(req.target().data(), req.target().size());
    target = target.substr(0, target.find('?'));
    const std::string prefix = absl::StrCat("/", kService, "/");
    if (req.method() != http::verb::post || !absl::StartsWith(target, prefix)) {
      stream_type_.clear();  // not a call of the service's
    }
    if (req.method() == http::verb::options) return Preflight();
    if (!absl::StartsWith(target, prefix)) {
      if (req.method() == http::verb::get || req.method() == http::verb::head) {
        return StaticFile(target, req.method() == http::verb::head);
      }
      // As a Connect server answers a service it does not have: 404, unimplemented.
      return Error(grpc::StatusCode::UNIMPLEMENTED,
                   absl::StrCat("no such service or path: ", target, " (this server has ",
                                kService, ")"),
                   http::status::not_found);
    }
    const std::string name = target.substr(prefix.size());
    auto header = [&req](const auto& field) {
      const auto v = req[field];
      return std::string(v.data(), v.size());
    };
    const std::string type = header(http::field::content_type);
    const bool streaming_type = absl::StrContains(absl::AsciiStrToLower(type), "connect+");
    ConnectCall call = DecodeConnectCall(
        name, req.method() == http::verb::post, type, std::move(req.body()),
        header("Connect-Timeout-Ms"),
        header(streaming_type ? "Connect-Content-Encoding" : "Content-Encoding"),
        server_->options().max_body_bytes);
    if (call.method == nullptr) {
      return Error(call.code, call.message,
                   call.http_status ? std::optional(static_cast<http::status>(call.http_status))
                                    : std::nullopt);
    }
    json_ = call.json;
    content_type_ = call.content_type;
    output_ = call.method->output_type();
    // What the gRPC call carries of the request: its token, its deadline and the headers
    // that are metadata (a "-bin" one's value in base64, as Connect sends binary values).
    metadata_.clear();
    for (const auto& field : req) {
      std::string name = absl::AsciiStrToLower(
          absl::string_view(field.name_string().data(), field.name_string().size()));
      if (!IsMetadata(name)) continue;
      std::string value(field.value().data(), field.value().size());
      if (absl::EndsWith(name, "-bin")) {
        std::string raw;
        if (!absl::Base64Unescape(value, &raw) && !absl::WebSafeBase64Unescape(value, &raw)) {
          return Error(grpc::StatusCode::INVALID_ARGUMENT,
                       absl::StrCat("header ", name, " is binary metadata (\"-bin\"): its value "
                                    "must be base64"));
        }
        value = std::move(raw);
      } else if (!std::all_of(value.begin(), value.end(),
                              [](char c) { return c >= 0x20 && c <= 0x7e; })) {
        return Error(grpc::StatusCode::INVALID_ARGUMENT,
                     absl::StrCat("header ", name, " holds a character metadata may not: only "
                                  "printable ASCII, or base64 in a \"-bin\" header"));
      }
      metadata_.emplace_back(std::move(name), std::move(value));
    }
    authorization_ = std::string(req[http::field::authorization]);
    deadline_.reset();
    if (call.timeout) deadline_ = std::chrono::system_clock::now() + *call.timeout;
    const std::string request = std::move(call.request);
    const std::string path = absl::StrCat("/", kService, "/", name);
    if (call.method->server_streaming()) return Stream(path, request);
    Unary(path, request);
  }

  void Prepare(grpc::ClientContext* ctx) const {
    if (!authorization_.empty()) ctx->AddMetadata("authorization", authorization_);
    for (const auto& [name, value] : metadata_) ctx->AddMetadata(name, value);
    if (deadline_) ctx->set_deadline(*deadline_);
  }

  // A unary call: the gRPC call, then one response.
  void Unary(const std::string& path, const std::string& request) {
    struct Call {
      grpc::ClientContext ctx;
      grpc::ByteBuffer request, response;
    };
    auto call = std::make_shared<Call>();
    Prepare(&call->ctx);
    call->request = Buffer(request);
    server_->stub().UnaryCall(
        &call->ctx, path, grpc::StubOptions(), &call->request, &call->response,
        [self = Self(), call](grpc::Status s) {
          net::post(self->stream_.get_executor(), [self, call, s] {
            // The service's headers as headers, its trailers as "Trailer-" ones (Connect's
            // unary form), on the answer or the error alike.
            self->answer_headers_ = AnswerMetadata(call->ctx.GetServerInitialMetadata());
            for (auto& [name, value] : AnswerMetadata(call->ctx.GetServerTrailingMetadata())) {
              self->answer_headers_.emplace_back("trailer-" + name, std::move(value));
            }
            if (!s.ok()) return self->Error(s.error_code(), s.error_message());
            std::string body = Bytes(call->response);
            if (self->json_) {
              auto json = self->ToJson(body);
              if (!json) return;  // answered
              body = std::move(*json);
            }
            self->Send(http::status::ok, self->content_type_, std::move(body));
          });
        });
  }

  // The response message in JSON; nullopt (having answered INTERNAL) when it does not parse.
  std::optional<std::string> ToJson(const std::string& bytes) {
    auto* prototype = google::protobuf::MessageFactory::generated_factory()->GetPrototype(output_);
    std::unique_ptr<Message> message(prototype->New());
    std::string json;
    if (!message->ParseFromString(bytes) ||
        !google::protobuf::util::MessageToJsonString(*message, &json).ok()) {
      Error(grpc::StatusCode::INTERNAL, "the service's answer could not be written as JSON");
      return std::nullopt;
    }
    return json;
  }

  // A server-streaming call: a 200 response with chunked transfer, one envelope per message
  // as the service sends it (the next is read when the last is written: the HTTP reader's
  // pace is the stream's), then the end-of-stream envelope with the status. One write at a
  // time: the call can end (OnDone) while its last message, or the header, is still being
  // written, and the end then waits for that write.
  class StreamCall;
  // What the connection's strand and the call's gRPC threads share: the call, until its
  // OnDone (after which it is gone).
  struct CallHandle {
    std::mutex mu;
    StreamCall* call = nullptr;  // null once done
  };
  class StreamCall final : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
   public:
    StreamCall(std::shared_ptr<Session> session, std::shared_ptr<CallHandle> handle)
        : session_(std::move(session)), handle_(std::move(handle)) {}
    grpc::ClientContext ctx;
    grpc::ByteBuffer request, message;

    // The call is held (AddHold) from its start: gRPC ends it (freeing the stream, then
    // OnDone) only once the session starts no more reads, so NextRead can never start one on
    // a freed stream. Released when a read finds the end, or when the connection broke.
    void Release() {
      if (!released_.exchange(true)) RemoveHold();
    }
    void OnReadDone(bool ok) override {
      if (!ok) return Release();  // the stream ends: OnDone follows
      std::string bytes = Bytes(message);
      auto session = session_;
      net::post(session->stream_.get_executor(), [session, bytes = std::move(bytes)]() mutable {
        session->StreamMessage(std::move(bytes));
      });
    }
    void OnDone(const grpc::Status& s) override {
      {
        std::lock_guard<std::mutex> lock(handle_->mu);
        handle_->call = nullptr;
      }
      auto session = std::move(session_);
      // The service's headers and trailers both: the answer's own headers went before the
      // call began.
      Metadata trailers = AnswerMetadata(ctx.GetServerInitialMetadata());
      for (auto& kv : AnswerMetadata(ctx.GetServerTrailingMetadata())) trailers.push_back(kv);
      net::post(session->stream_.get_executor(), [session, s, trailers = std::move(trailers)] {
        session->stream_trailers_ = trailers;
        session->StreamEnd(s);
      });
      delete this;
    }

   private:
    std::shared_ptr<Session> session_;
    std::shared_ptr<CallHandle> handle_;
    std::atomic<bool> released_{false};
  };

  void Stream(const std::string& path, const std::string& request) {
    call_ = std::make_shared<CallHandle>();
    auto* call = new StreamCall(Self(), call_);
    call_->call = call;
    Prepare(&call->ctx);
    call->request = Buffer(request);
    // The response header first; messages follow as they come.
    response_header_.emplace(http::status::ok, version_);
    response_header_->set(http::field::content_type, content_type_);
    response_header_->set("Connect-Accept-Encoding", "gzip");
    Cors(*response_header_);
    response_header_->chunked(true);
    response_header_->keep_alive(keep_alive_);
    serializer_.emplace(*response_header_);
    beast::get_lowest_layer(stream_).expires_never();
    server_->stub().PrepareBidiStreamingCall(&call->ctx, path, grpc::StubOptions(), call);
    call->StartWrite(&call->request);
    call->StartWritesDone();
    call->AddHold();
    call->StartCall();
    writing_ = true;
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(120));
    http::async_write_header(stream_, *serializer_, [self = Self()](beast::error_code ec, size_t) {
      self->StreamWritten(ec);
    });
  }

  // A write of the stream's is done: the end, if it came meanwhile, goes now; else the next
  // message is asked for.
  void StreamWritten(beast::error_code ec) {
    writing_ = false;
    // A reader that stops reading fails the write after 120 s; between messages (a watch
    // waits for frames) there is no deadline.
    beast::get_lowest_layer(stream_).expires_never();
    if (ec) StreamBroken();
    if (pending_end_) {
      const grpc::Status s = *pending_end_;
      pending_end_.reset();
      return StreamEnd(s);
    }
    if (!ec) NextRead();
  }

  // Asks the call for its next message, unless it is done.
  void NextRead() {
    if (!call_) return;
    std::lock_guard<std::mutex> lock(call_->mu);
    if (call_->call != nullptr) call_->call->StartRead(&call_->call->message);
  }

  void StreamMessage(std::string bytes) {
    if (broken_) return;
    std::string payload = std::move(bytes);
    if (json_) {
      auto* prototype = google::protobuf::MessageFactory::generated_factory()->GetPrototype(output_);
      std::unique_ptr<Message> message(prototype->New());
      std::string json;
      if (message->ParseFromString(payload) &&
          google::protobuf::util::MessageToJsonString(*message, &json).ok()) {
        payload = std::move(json);
      }
    }
    auto chunk = std::make_shared<std::string>(Envelope(0, payload));
    writing_ = true;
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(120));
    net::async_write(stream_, http::make_chunk(net::buffer(*chunk)),
                     [self = Self(), chunk](beast::error_code ec, size_t) {
                       self->StreamWritten(ec);
                     });
  }

  void StreamEnd(const grpc::Status& s) {
    if (writing_) {
      pending_end_ = s;
      return;
    }
    call_.reset();
    if (broken_) return Close();
    std::vector<std::string> parts;
    if (!s.ok()) {
      const ConnectCode c = ToConnect(s.error_code());
      parts.push_back(absl::StrCat("\"error\":", ErrorJson(c.name, s.error_message())));
    }
    if (!stream_trailers_.empty()) {
      std::map<std::string, std::vector<std::string>> grouped;
      for (const auto& [name, value] : stream_trailers_) grouped[name].push_back(JsonString(value));
      std::vector<std::string> fields;
      for (const auto& [name, values] : grouped) {
        fields.push_back(absl::StrCat(JsonString(name), ":[", absl::StrJoin(values, ","), "]"));
      }
      parts.push_back(absl::StrCat("\"metadata\":{", absl::StrJoin(fields, ","), "}"));
      stream_trailers_.clear();
    }
    const std::string end = absl::StrCat("{", absl::StrJoin(parts, ","), "}");
    auto chunk = std::make_shared<std::string>(Envelope(0x02, end));
    net::async_write(stream_, http::make_chunk(net::buffer(*chunk)),
                     [self = Self(), chunk](beast::error_code ec, size_t) {
                       if (ec) return self->Close();
                       net::async_write(self->stream_, http::make_chunk_last(),
                                        [self](beast::error_code ec2, size_t) {
                                          if (ec2 || !self->keep_alive_) return self->Close();
                                          self->Read();
                                        });
                     });
  }

  // The connection failed under a stream: cancel the call; its end then closes.
  void StreamBroken() {
    broken_ = true;
    if (!call_) return Close();
    std::lock_guard<std::mutex> lock(call_->mu);
    if (call_->call != nullptr) {
      call_->call->ctx.TryCancel();
      call_->call->Release();  // no read is outstanding: a write was, and it failed
    }
  }

  void Preflight() {
    if (origin_.empty() || !server_->Allowed(origin_)) {
      return Error(grpc::StatusCode::PERMISSION_DENIED,
                   absl::StrCat("origin \"", origin_, "\" is not allowed (--http-cors-origins)"),
                   http::status::forbidden);
    }
    auto res = std::make_shared<http::response<http::string_body>>(http::status::no_content, version_);
    Cors(*res);
    res->set(http::field::access_control_allow_methods, "POST, GET, OPTIONS");
    res->set(http::field::access_control_allow_headers,
             "Content-Type, Authorization, Connect-Protocol-Version, Connect-Timeout-Ms, "
             "Content-Encoding, Connect-Content-Encoding, Connect-Accept-Encoding");
    res->set(http::field::access_control_max_age, "7200");
    Write(res);
  }

  void StaticFile(const std::string& path, bool head) {
    const auto& files = server_->options().files;
    auto it = files.find(path.empty() ? "/" : path);
    if (it == files.end()) {
      return Error(grpc::StatusCode::NOT_FOUND, absl::StrCat("no such path: ", path));
    }
    auto res = std::make_shared<http::response<http::string_body>>(http::status::ok, version_);
    res->set(http::field::content_type, it->second.first);
    res->set(http::field::cache_control, "no-cache");
    res->body() = head ? std::string() : it->second.second;
    if (head) res->content_length(it->second.second.size());
    Cors(*res);
    Write(res, /*prepared=*/head);
  }

  template <class Response>
  void Cors(Response& res) {
    if (!origin_.empty() && server_->Allowed(origin_)) {
      res.set(http::field::access_control_allow_origin, origin_);
      // Beside what the answer already varies with (Accept-Encoding).
      const auto vary = res[http::field::vary];
      res.set(http::field::vary,
              vary.empty() ? std::string("Origin")
                           : absl::StrCat(std::string(vary.data(), vary.size()), ", Origin"));
    }
  }

  // `status`, where given, is the HTTP status even for a streaming request (an unknown
  // method's 404, an unsupported content type's 415).
  void Error(grpc::StatusCode code, const std::string& message,
             std::optional<http::status> status = std::nullopt) {
    const ConnectCode c = ToConnect(code);
    if (!stream_type_.empty() && !status) {
      return Send(http::status::ok, stream_type_,
                  Envelope(0x02, absl::StrCat("{\"error\":", ErrorJson(c.name, message), "}")));
    }
    Send(status.value_or(c.status), "application/json", ErrorJson(c.name, message));
  }

  // A unary answer (or a refused stream's end) whole; gzip-compressed where the request
  // accepts it and the body is worth it (not a stream's: its envelopes say their own).
  static constexpr size_t kGzipFrom = 1024;
  void Send(http::status status, const std::string& type, std::string body) {
    auto res = std::make_shared<http::response<http::string_body>>(status, version_);
    res->set(http::field::content_type, type);
    res->set(http::field::accept_encoding, "gzip");  // what request bodies may be
    if (stream_type_.empty()) res->set(http::field::vary, "Accept-Encoding");
    if (gzip_answer_ && stream_type_.empty() && body.size() >= kGzipFrom) {
      std::string packed = Gzip(body);
      if (!packed.empty() && packed.size() < body.size()) {
        body = std::move(packed);
        res->set(http::field::content_encoding, "gzip");
      }
    }
    res->body() = std::move(body);
    for (const auto& [name, value] : answer_headers_) res->insert(name, value);
    answer_headers_.clear();
    Cors(*res);
    Write(res);
  }

  void Write(const std::shared_ptr<http::response<http::string_body>>& res, bool prepared = false) {
    res->keep_alive(keep_alive_ && !closing_);
    if (!prepared) res->prepare_payload();
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(120));
    http::async_write(stream_, *res, [self = Self(), res](beast::error_code ec, size_t) {
      if (ec || !res->keep_alive()) return self->Close();
      self->Read();
    });
  }

  void Close() {
    if (closed_) return;
    closed_ = true;
    beast::error_code ec;
    if constexpr (std::is_same_v<StreamType, beast::tcp_stream>) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
      stream_.close();
    } else {
      beast::get_lowest_layer(stream_).close();
    }
  }

  HttpServer::Impl* const server_;
  StreamType stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::empty_body>> header_parser_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::optional<http::request_parser<http::buffer_body>> drain_parser_;
  // A chunked body, gathered by on_chunk_ (the parser keeps a reference to it).
  std::function<size_t(uint64_t, beast::string_view, beast::error_code&)> on_chunk_;
  std::string chunked_body_;
  bool chunked_over_ = false;  // past --max-message-bytes: read through, not kept
  std::unique_ptr<char[]> scratch_;
  std::string drain_message_;
  unsigned version_ = 11;
  bool keep_alive_ = false, idle_ = false, closing_ = false, closed_ = false;
  bool json_ = true, broken_ = false, writing_ = false;
  std::optional<grpc::Status> pending_end_;  // the stream's end, waiting for a write
  std::string origin_, content_type_, authorization_;
  std::string stream_type_;  // the request's Content-Type where it is a Connect stream's
  bool gzip_answer_ = false;  // the request's Accept-Encoding takes gzip
  Metadata metadata_;         // the request's headers that are metadata
  Metadata answer_headers_;   // the service's, for the next answer Send writes
  Metadata stream_trailers_;  // the service's, for a stream's end
  std::optional<std::chrono::system_clock::time_point> deadline_;
  const google::protobuf::Descriptor* output_ = nullptr;
  std::shared_ptr<CallHandle> call_;
  std::optional<http::response<http::empty_body>> response_header_;
  std::optional<http::response_serializer<http::empty_body>> serializer_;
};

}  // namespace

absl::Status HttpServer::Impl::Start() {
  const auto colon = options_.listen.rfind(':');
  if (colon == std::string::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("--http-listen needs HOST:PORT, not \"", options_.listen, "\""));
  }
  std::string host = options_.listen.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  int port = 0;
  if (!absl::SimpleAtoi(options_.listen.substr(colon + 1), &port) || port < 0 || port > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat("--http-listen needs HOST:PORT, not \"", options_.listen, "\""));
  }
  beast::error_code ec;
  const auto address = net::ip::make_address(host == "localhost" ? "127.0.0.1" : host, ec);
  if (ec) {
    return absl::InvalidArgumentError(
        absl::StrCat("--http-listen: \"", host, "\" is not an IP address"));
  }
  if (!options_.tls_cert.empty()) {
    tls_.emplace(ssl::context::tls_server);
    tls_->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 |
                      ssl::context::no_sslv3 | ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1);
    tls_->use_certificate_chain(net::buffer(options_.tls_cert), ec);
    if (!ec) tls_->use_private_key(net::buffer(options_.tls_key), ssl::context::pem, ec);
    if (!ec && !options_.tls_client_ca.empty()) {
      tls_->add_certificate_authority(net::buffer(options_.tls_client_ca), ec);
      tls_->set_verify_mode(ssl::verify_peer | ssl::verify_fail_if_no_peer_cert);
    }
    if (ec) return absl::InvalidArgumentError(absl::StrCat("HTTP TLS: ", ec.message()));
  }
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(port));
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    return absl::UnavailableError(
        absl::StrCat("cannot listen on ", options_.listen, " for HTTP: ", ec.message()));
  }
  port_ = acceptor_.local_endpoint().port();
  Accept();
  work_.emplace(net::make_work_guard(ioc_));
  for (int i = 0; i < std::max(1, options_.threads); ++i) {
    threads_.emplace_back([this] { ioc_.run(); });
  }
  return absl::OkStatus();
}

void HttpServer::Impl::Accept() {
  acceptor_.async_accept(net::make_strand(ioc_), [this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (!stopping_ && ec != net::error::operation_aborted) Accept();
      return;
    }
    if (tls_) {
      auto s = std::make_shared<Session<beast::ssl_stream<beast::tcp_stream>>>(
          this, beast::ssl_stream<beast::tcp_stream>(std::move(socket), *tls_));
      Register(s);
      s->Run();
    } else {
      auto s = std::make_shared<Session<beast::tcp_stream>>(this, beast::tcp_stream(std::move(socket)));
      Register(s);
      s->Run();
    }
    Accept();
  });
}

void HttpServer::Impl::Shutdown(std::chrono::milliseconds grace) {
  stopping_ = true;
  // On the acceptor's strand, where its accept handler runs, not beside it.
  net::post(acceptor_.get_executor(), [this] {
    beast::error_code ec;
    acceptor_.close(ec);
  });
  std::vector<std::shared_ptr<SessionBase>> open;
  {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    for (auto& [raw, weak] : sessions_) {
      if (auto s = weak.lock()) open.push_back(std::move(s));
    }
  }
  for (auto& s : open) s->CloseWhenIdle();
  open.clear();  // outside the lock: a session's destructor takes it
  const auto deadline = std::chrono::steady_clock::now() + grace;
  while (std::chrono::steady_clock::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(sessions_mu_);
      if (sessions_.empty()) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  work_.reset();
  ioc_.stop();
  for (auto& t : threads_) t.join();
  threads_.clear();
}

absl::StatusOr<std::unique_ptr<HttpServer>> HttpServer::Start(
    HttpOptions options, std::shared_ptr<grpc::Channel> channel) {
  auto impl = std::make_unique<Impl>(std::move(options), std::move(channel));
  if (auto s = impl->Start(); !s.ok()) return s;
  return std::unique_ptr<HttpServer>(new HttpServer(std::move(impl)));
}

HttpServer::HttpServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

HttpServer::~HttpServer() {
  if (impl_) impl_->Shutdown(std::chrono::milliseconds(0));
}

int HttpServer::port() const { return impl_->port(); }

void HttpServer::Shutdown(std::chrono::milliseconds grace) { impl_->Shutdown(grace); }

}  // namespace gvd
