#include "server/http/http.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/ssl.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include <pthread.h>
#include <unistd.h>
#include <zlib.h>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "gvd/v1/voronoi.pb.h"
#include "server/app/methods.h"
#include "server/http/json.h"
#include "server/log.h"

namespace gvd {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
// A session's streams and timer run on its strand, named by its concrete type: held as
// Asio's type-erased any_io_executor (Beast's tcp_stream), a strand goes to the heap at
// each copy, and Beast copies its executor some twenty times a call.
using Strand = net::strand<net::io_context::executor_type>;
using StrandSocket = tcp::socket::rebind_executor<Strand>::other;
using TcpStream = beast::basic_stream<tcp, Strand>;
using StrandTimer = net::steady_timer::rebind_executor<Strand>::other;
using google::protobuf::Message;
using google::protobuf::MethodDescriptor;

const char* const kService = kServiceName;

// The largest request body (as sent) or answer (its protobuf size) converted on an I/O
// thread: a one-point query's is some 100 bytes, a 100,000-point batch's megabytes, which
// take that thread tens of milliseconds (5.3 MB of JSON in, 11.6 MB out: 70 ms).
constexpr size_t kConvertHereBytes = 64 << 10;

// The Connect protocol's name and HTTP status for each code.
struct ConnectCode {
  const char* name;
  http::status status;
};
ConnectCode ToConnect(absl::StatusCode code) {
  switch (code) {
    case absl::StatusCode::kCancelled: return {"canceled", static_cast<http::status>(499)};
    case absl::StatusCode::kInvalidArgument: return {"invalid_argument", http::status::bad_request};
    case absl::StatusCode::kDeadlineExceeded: return {"deadline_exceeded", http::status::gateway_timeout};
    case absl::StatusCode::kNotFound: return {"not_found", http::status::not_found};
    case absl::StatusCode::kAlreadyExists: return {"already_exists", http::status::conflict};
    case absl::StatusCode::kPermissionDenied: return {"permission_denied", http::status::forbidden};
    case absl::StatusCode::kResourceExhausted: return {"resource_exhausted", http::status::too_many_requests};
    case absl::StatusCode::kFailedPrecondition: return {"failed_precondition", http::status::bad_request};
    case absl::StatusCode::kAborted: return {"aborted", http::status::conflict};
    case absl::StatusCode::kOutOfRange: return {"out_of_range", http::status::bad_request};
    case absl::StatusCode::kUnimplemented: return {"unimplemented", http::status::not_implemented};
    case absl::StatusCode::kInternal: return {"internal", http::status::internal_server_error};
    case absl::StatusCode::kUnavailable: return {"unavailable", http::status::service_unavailable};
    case absl::StatusCode::kDataLoss: return {"data_loss", http::status::internal_server_error};
    case absl::StatusCode::kUnauthenticated: return {"unauthenticated", http::status::unauthorized};
    default: return {"unknown", http::status::internal_server_error};
  }
}

// {"code": ..., "message": ...}.
std::string ErrorJson(const char* code, const std::string& message) {
  return absl::StrCat("{\"code\":\"", code, "\",\"message\":", JsonQuote(message), "}");
}

// A 5-byte Connect envelope (flags, big-endian length) and its payload.
std::string Envelope(uint8_t flags, const std::string& payload) {
  std::string out(5, '\0');
  out[0] = static_cast<char>(flags);
  const uint32_t n = static_cast<uint32_t>(payload.size());
  for (int i = 0; i < 4; ++i) out[1 + i] = static_cast<char>((n >> (24 - 8 * i)) & 0xff);
  return out + payload;
}

// A response's head as it goes on the wire: the status line, the fields, the blank line.
// Written here rather than by Beast's serializer, which walks a response's fields as a
// sequence of buffer views: a one-point FindNearest over HTTP/JSON costs the server 57.4 k
// instructions this way against 71.1 k (tests/bench/transports.sh http-instructions), and in
// a load of them the serializer had taken 7% of the I/O thread's time (`perf record`).
class Head {
 public:
  Head(http::status status, unsigned version) : status_(status) {
    const beast::string_view reason = http::obsolete_reason(status);
    absl::StrAppend(&text_, "HTTP/", version / 10, ".", version % 10, " ",
                    static_cast<unsigned>(status), " ",
                    absl::string_view(reason.data(), reason.size()), "\r\n");
  }
  Head& Field(absl::string_view name, absl::string_view value) {
    absl::StrAppend(&text_, name, ": ", value, "\r\n");
    return *this;
  }
  // The Connection field as Beast's keep_alive() writes it: HTTP/1.1 keeps the connection
  // unless told "close", HTTP/1.0 closes it unless told "keep-alive".
  Head& KeepAlive(unsigned version, bool keep) {
    if (version >= 11 && !keep) return Field("Connection", "close");
    if (version < 11 && keep) return Field("Connection", "keep-alive");
    return *this;
  }
  std::string End() && {
    text_ += "\r\n";
    return std::move(text_);
  }
  http::status status() const { return status_; }

 private:
  http::status status_;
  std::string text_;
};

// One HTTP/1.1 connection: requests one at a time; each call handed to the core.
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
  auto refuse = [&call](absl::StatusCode code, std::string message, int http_status = 0) {
    call.method = nullptr;
    call.request.reset();
    call.code = code;
    call.message = std::move(message);
    call.http_status = http_status;
    return std::move(call);
  };
  const MethodDescriptor* method =
      google::protobuf::DescriptorPool::generated_pool()->FindMethodByName(
          absl::StrCat(kService, ".", name));
  if (method == nullptr) {
    return refuse(absl::StatusCode::kUnimplemented,
                  absl::StrCat(kService, " has no method \"", name, "\""),
                  static_cast<int>(http::status::not_found));
  }
  if (!post) {
    return refuse(absl::StatusCode::kUnimplemented,
                  absl::StrCat("call ", kService, "/", name, " with POST"),
                  static_cast<int>(http::status::method_not_allowed));
  }
  std::string type = absl::AsciiStrToLower(content_type);
  type = std::string(absl::StripAsciiWhitespace(type.substr(0, type.find(';'))));
  const bool streaming = method->server_streaming();
  const std::string want_json = streaming ? "application/connect+json" : "application/json";
  const std::string want_proto = streaming ? "application/connect+proto" : "application/proto";
  if (type != want_json && type != want_proto) {
    return refuse(absl::StatusCode::kUnimplemented,
                  absl::StrCat("Content-Type \"", type, "\" is not supported by ", name,
                               ": send ", want_json, " (or ", want_proto, ")"),
                  static_cast<int>(http::status::unsupported_media_type));
  }
  call.json = type == want_json;
  call.content_type = call.json ? want_json : want_proto;
  const std::string coding = absl::AsciiStrToLower(absl::StripAsciiWhitespace(encoding));
  if (!coding.empty() && coding != "identity" && coding != "gzip") {
    return refuse(absl::StatusCode::kUnimplemented,
                  absl::StrCat(streaming ? "Connect-Content-Encoding" : "Content-Encoding", " \"",
                               coding, "\" is not supported: send gzip or identity"));
  }
  // Inflates `bytes` in place; a refusal on failure.
  auto inflate = [&](std::string& bytes) -> std::optional<ConnectCall> {
    auto inflated = Gunzip(bytes, max_bytes);
    if (!inflated.ok()) {
      return refuse(inflated.status().code(),
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
      return refuse(absl::StatusCode::kInvalidArgument,
                    "a streaming request's body must be one Connect envelope");
    }
    const bool compressed = (static_cast<uint8_t>(body[0]) & 0x01) != 0;
    if (compressed && coding != "gzip") {
      return refuse(absl::StatusCode::kInvalidArgument,
                    "the request's envelope is compressed, and Connect-Content-Encoding names "
                    "no compression");
    }
    const uint32_t n = (uint32_t(uint8_t(body[1])) << 24) | (uint32_t(uint8_t(body[2])) << 16) |
                       (uint32_t(uint8_t(body[3])) << 8) | uint32_t(uint8_t(body[4]));
    if (n != body.size() - 5) {
      return refuse(absl::StatusCode::kInvalidArgument,
                    absl::StrCat("the request's envelope says ", n, " bytes; ", body.size() - 5,
                                 " follow it"));
    }
    body = body.substr(5);
    if (compressed) {
      if (auto refused = inflate(body)) return std::move(*refused);
    }
  }
  // The generated class of the input type (the pool is the generated one), which the
  // application core takes.
  std::unique_ptr<Message> message = NewMessage(method->input_type());
  if (call.json) {
    // A newer client's fields are ignored (see FromJson), as Connect's servers do, so that it
    // can talk to an older server.
    if (auto s = FromJson(body.empty() ? "{}" : body, message.get()); !s.ok()) {
      return refuse(absl::StatusCode::kInvalidArgument,
                    absl::StrCat("the body is not a ", method->input_type()->name(), " in JSON: ",
                                 s.message()));
    }
  } else if (!message->ParseFromString(body)) {
    return refuse(absl::StatusCode::kInvalidArgument,
                  absl::StrCat("the body is not a ", method->input_type()->name(),
                               " in binary protobuf"));
  }
  call.request = std::move(message);
  if (!timeout_ms.empty()) {
    int64_t ms = 0;
    // The Connect protocol's limit: at most 10 digits (some 115 days).
    if (timeout_ms.size() > 10 || !absl::SimpleAtoi(timeout_ms, &ms) || ms <= 0) {
      return refuse(absl::StatusCode::kInvalidArgument,
                    absl::StrCat("Connect-Timeout-Ms must be a positive number of at most 10 "
                                 "digits, not \"", timeout_ms, "\""));
    }
    call.timeout = std::chrono::milliseconds(ms);
  }
  call.method = method;
  return call;
}

class HttpServer::Impl {
 public:
  Impl(HttpOptions options, Service* core)
      : options_(std::move(options)), core_(core), acceptor_(net::make_strand(ioc_)) {}

  absl::Status Start();
  void Shutdown(std::chrono::milliseconds grace);
  int port() const { return port_; }

  // What sessions need.
  const HttpOptions& options() const { return options_; }
  Service* core() const { return core_; }
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
  // Runs `f` on the converter thread, where large request bodies are decoded.
  template <class F>
  void Convert(F&& f) {
    net::post(converter_, std::forward<F>(f));
  }
  // The test hook (server/app/methods.h): a large conversion waits while it holds.
  void HoldConversion() const { HoldConversions(stopping_); }

 private:
  void Accept();

  HttpOptions options_;
  Service* const core_;
  std::atomic<bool> stopping_{false};
  // Before the io_context: handlers it still holds when it goes (a call the core finished
  // after the server stopped) own sessions, whose destructors unregister here.
  std::mutex sessions_mu_;
  std::map<SessionBase*, std::weak_ptr<SessionBase>> sessions_;
  net::io_context ioc_;
  // After the io_context, so destroyed before it: a conversion it still holds owns a session,
  // whose socket is the io_context's.
  net::thread_pool converter_{1};
  std::optional<ssl::context> tls_;
  tcp::acceptor acceptor_;  // on a strand of its own: its handler and Shutdown's close
  std::vector<std::thread> threads_;
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work_;
  int port_ = 0;
};

namespace {

template <class StreamType>
class Session final : public SessionBase {
 public:
  Session(HttpServer::Impl* server, StreamType stream)
      : server_(server), stream_(std::move(stream)) {}
  ~Session() override { server_->Unregister(this); }

  // Begins on the session's strand, where all it does runs (CloseWhenIdle's too).
  void Run() {
    net::dispatch(stream_.get_executor(), [self = Self()] { self->Open(); });
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

  void Open() {
    if constexpr (std::is_same_v<StreamType, TcpStream>) {
      Read();
    } else {
      Limit(std::min<std::chrono::steady_clock::duration>(std::chrono::seconds(30), IoTimeout()));
      stream_.async_handshake(ssl::stream_base::server,
                              [self = Self()](beast::error_code ec) {
                                if (ec) return self->Close();  // nothing to answer
                                self->Read();
                              });
    }
  }

  // The header first: a body declared past --max-message-bytes is drained, not read.
  void Read() {
    if (closing_) return Close();
    idle_ = true;
    header_parser_.emplace();
    header_parser_->header_limit(64 << 10);
    // Beast checks a declared length against the body limit with the header: not yet.
    header_parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
    Limit(IoTimeout());  // idle, then the header's read and the body's
    http::async_read_header(stream_, buffer_, *header_parser_,
                            [self = Self()](beast::error_code ec, size_t) { self->OnHeader(ec); });
  }

  void OnHeader(beast::error_code ec) {
    idle_ = false;
    if (ec) return Close();  // the peer went, timed out, or spoke no HTTP
    // What an answer follows of the request, whichever path answers it (a refusal of its
    // body included): its HTTP version, keep-alive, origin, and whether it is a HEAD.
    {
      const auto& req = header_parser_->get();
      version_ = req.version();
      head_ = req.method() == http::verb::head;
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
      return Error(absl::StatusCode::kResourceExhausted, TooLarge("the request body"));
    }
    if (ec) return Close();  // the peer went, timed out, or spoke no HTTP
    if (chunked_over_) {
      std::string().swap(chunked_body_);
      return Error(absl::StatusCode::kResourceExhausted, TooLarge("the request body"));
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
      return Error(absl::StatusCode::kResourceExhausted, drain_message_);
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
                       self->Error(absl::StatusCode::kResourceExhausted, self->drain_message_);
                     });
  }

  void Handle(http::request<http::string_body> req) {
    NoLimit();  // read: what comes next is answered, or the core's call (which has its own)
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
        return StaticFile(target);
      }
      // As a Connect server answers a service it does not have: 404, unimplemented.
      return Error(absl::StatusCode::kUnimplemented,
                   absl::StrCat("no such service or path: ", target, " (this server has ",
                                kService, ")"),
                   http::status::not_found);
    }
    std::string name = target.substr(prefix.size());
    auto header = [&req](const auto& field) {
      const auto v = req[field];
      return std::string(v.data(), v.size());
    };
    const std::string type = header(http::field::content_type);
    const bool streaming_type = absl::StrContains(absl::AsciiStrToLower(type), "connect+");
    const std::string encoding =
        header(streaming_type ? "Connect-Content-Encoding" : "Content-Encoding");
    // The token: the Authorization header, as gRPC's "authorization" metadata.
    std::string token = header(http::field::authorization);
    // A small body is decoded here; a large one, or a compressed one (which may inflate to
    // the limit), on the server's converter thread, while this I/O thread serves its other
    // connections.
    const bool here = req.body().size() <= kConvertHereBytes &&
                      (encoding.empty() || absl::EqualsIgnoreCase(encoding, "identity"));
    auto decode = [name, post = req.method() == http::verb::post, type,
                   body = std::move(req.body()), timeout = header("Connect-Timeout-Ms"), encoding,
                   limit = server_->options().max_body_bytes]() mutable {
      return DecodeConnectCall(name, post, type, std::move(body), timeout, encoding, limit);
    };
    if (here) return Begin(name, decode(), token);
    server_->Convert([self = Self(), decode = std::move(decode), name = std::move(name),
                      token = std::move(token)]() mutable {
      self->server_->HoldConversion();
      ConnectCall call = decode();
      net::post(self->stream_.get_executor(),
                [self, call = std::move(call), name = std::move(name),
                 token = std::move(token)]() mutable { self->Begin(name, std::move(call), token); });
    });
  }

  // A decoded call of the service's method `name`: refused, or handed to the core.
  void Begin(const std::string& name, ConnectCall call, const std::string& token) {
    if (call.method == nullptr) {
      return Error(call.code, call.message,
                   call.http_status ? std::optional(static_cast<http::status>(call.http_status))
                                    : std::nullopt);
    }
    const Method* method = FindMethod(name);
    if (method == nullptr) {  // a method of the proto this server does not serve
      return Error(absl::StatusCode::kUnimplemented,
                   absl::StrCat(kService, " has no method \"", name, "\""),
                   http::status::not_found);
    }
    json_ = call.json;
    content_type_ = call.content_type;
    // The call as the core takes it: its token, cancelled when its deadline passes.
    call_ = std::make_shared<Call>(token);
    ++calls_;
    deadline_passed_ = false;
    std::optional<std::chrono::steady_clock::time_point> deadline;
    if (call.timeout) deadline = std::chrono::steady_clock::now() + *call.timeout;
    if (method->streaming) {
      if (deadline) StartDeadline(*deadline);
      return Stream(*method, std::move(call.request));
    }
    Unary(*method, *call.method, std::move(call.request), deadline);
  }

  // Connect-Timeout-Ms: when it passes, the call is cancelled and answered DEADLINE_EXCEEDED.
  void StartDeadline(std::chrono::steady_clock::time_point deadline) {
    deadline_.emplace(stream_.get_executor(), deadline);
    deadline_->async_wait([self = Self(), generation = calls_](beast::error_code ec) {
      if (ec || generation != self->calls_) return;  // cancelled, or a later call's
      self->deadline_passed_ = true;
      // A unary call is answered before the core hears of it: the core's cancelled call may
      // answer at once, and that answer, whatever it says, then finds the call answered.
      if (self->unary_pending_) {
        self->unary_pending_ = false;
        self->Error(absl::StatusCode::kDeadlineExceeded,
                    "the call's deadline (Connect-Timeout-Ms) passed");
      }
      if (self->call_) self->call_->Cancel();
    });
  }
  void StopDeadline() {
    if (deadline_) deadline_->cancel();
  }

  // A unary call: the core's call, then one response, checked against --max-message-bytes
  // as gRPC checks what it sends.
  void Unary(const Method& method, const MethodDescriptor& descriptor,
             std::unique_ptr<Message> request,
             std::optional<std::chrono::steady_clock::time_point> deadline) {
    struct Exchange {
      std::unique_ptr<Message> request, response;
      bool answered = false;  // on the session's strand only
    };
    auto exchange = std::make_shared<Exchange>();
    exchange->request = std::move(request);
    exchange->response = NewMessage(descriptor.output_type());
    unary_pending_ = true;
    // The answer is encoded (and compressed) where the core answered: the caller's thread for
    // what it answers at once, its pool's for the rest, as a stream's messages are. A large
    // one encoded on an I/O thread would hold up every connection that thread serves. What
    // the core answers at once, on this session's strand, is sent at once; an answer from
    // any other thread is posted to the strand.
    method.unary(server_->core(), call_, *exchange->request, exchange->response.get(),
                 [self = Self(), exchange, generation = calls_, json = json_,
                  gzip = GzipAnswer()](const absl::Status& s) {
                   absl::StatusOr<Encoded> body =
                       s.ok() ? self->Encode(*exchange->response, json, gzip)
                              : absl::StatusOr<Encoded>(s);
                   auto answer = [self, exchange, body = std::move(body), generation]() mutable {
                     exchange->answered = true;
                     if (!self->unary_pending_ || generation != self->calls_) return;
                     self->unary_pending_ = false;
                     self->StopDeadline();
                     if (!body.ok()) {
                       return self->Error(body.status().code(),
                                          std::string(body.status().message()));
                     }
                     self->Send(http::status::ok, self->content_type_, std::move(body->body),
                                body->gzipped);
                   };
                   auto strand = self->stream_.get_executor();
                   if (strand.running_in_this_thread()) return answer();
                   net::post(strand, std::move(answer));
                 });
    // The deadline's timer only for a call not answered yet: one answered at once is sent,
    // and its timer would be set and cancelled for nothing (three system calls and a
    // handler). A timer set before a late answer is cancelled when that answer is sent.
    if (deadline && !exchange->answered) StartDeadline(*deadline);
  }

  struct Encoded {
    std::string body;
    bool gzipped = false;
  };
  // The response message's body, in JSON or binary as the request asked, gzip-compressed
  // when `gzip` (Compress); RESOURCE_EXHAUSTED past --max-message-bytes, as gRPC checks what
  // it sends.
  absl::StatusOr<Encoded> Encode(const Message& response, bool json, bool gzip) const {
    const size_t limit = server_->options().max_body_bytes;
    const size_t bytes = response.ByteSizeLong();
    if (bytes > limit) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "the answer is ", bytes, " bytes, over the limit of ", limit, " (--max-message-bytes)"));
    }
    if (bytes > kConvertHereBytes) server_->HoldConversion();
    Encoded out{json ? ToJson(response) : response.SerializeAsString()};
    out.gzipped = Compress(gzip, &out.body);
    return out;
  }

  // A server-streaming call: a 200 response with chunked transfer, one envelope per message
  // as the core writes it (the core writes the next once the last is sent: the HTTP
  // reader's pace is the stream's), then the end-of-stream envelope with the status. One
  // write at a time, in order: the header, each message, the end.
  class Out final : public StreamOut {
   public:
    Out(std::shared_ptr<Session> session, bool json)
        : session_(std::move(session)), json_(json) {}
    void Message(const google::protobuf::Message& message,
                 std::function<void(bool)> written) override {
      std::string payload = json_ ? ToJson(message) : message.SerializeAsString();
      auto session = session_;
      net::post(session->stream_.get_executor(),
                [session, payload = std::move(payload), written = std::move(written)]() mutable {
                  session->outgoing_.push_back({std::move(payload), std::move(written), {}});
                  session->Pump();
                });
    }
    void End(const absl::Status& status) override {
      auto session = std::move(session_);
      net::post(session->stream_.get_executor(), [session, status] {
        session->outgoing_.push_back({{}, nullptr, status});
        session->Pump();
      });
    }

   private:
    std::shared_ptr<Session> session_;
    const bool json_;
  };
  struct Outgoing {
    std::string payload;
    std::function<void(bool)> written;  // a message's
    std::optional<absl::Status> end;    // the end's
  };

  void Stream(const Method& method, std::unique_ptr<Message> request) {
    // The response header first; messages follow as they come.
    Head head(http::status::ok, version_);
    head.Field("Content-Type", content_type_).Field("Connect-Accept-Encoding", "gzip");
    Cors(head, "");
    // HTTP/1.0 has no chunks: its stream's body runs to the connection's close.
    chunked_ = version_ >= 11;
    if (chunked_) {
      head.Field("Transfer-Encoding", "chunked").KeepAlive(version_, keep_alive_ && !closing_);
    } else {
      keep_alive_ = false;
      head.KeepAlive(version_, false);
    }
    auto text = std::make_shared<std::string>(std::move(head).End());
    broken_ = false;
    writing_ = true;
    Limit(IoTimeout());
    net::async_write(stream_, net::buffer(*text),
                     [self = Self(), text](beast::error_code ec, size_t) { self->Written(ec); });
    // The request lives as long as the core's stream may read it: until its end.
    std::shared_ptr<Message> held(std::move(request));
    method.streaming(server_->core(), call_, *held, std::make_shared<Out>(Self(), json_));
    held_request_ = std::move(held);
  }

  // A write of the stream's is done: the next goes, if one waits.
  void Written(beast::error_code ec) {
    writing_ = false;
    // A reader that stops reading fails the write after --http-io-timeout-ms; between
    // messages (a watch waits for frames) there is no limit.
    NoLimit();
    if (ec) Broken();
    Pump();
  }

  // The connection failed under a stream: the core hears of it at its next write, and the
  // call is cancelled so that a stream waiting for frames ends now.
  void Broken() {
    if (broken_) return;
    broken_ = true;
    if (call_) call_->Cancel();
  }

  // Writes one of the stream's envelopes: a chunk of the chunked body (HTTP/1.1), or its
  // bytes as they are in a body that the connection's close ends (HTTP/1.0).
  template <class Handler>
  void WriteEnvelope(const std::shared_ptr<std::string>& envelope, Handler&& handler) {
    if (chunked_) {
      net::async_write(stream_, http::make_chunk(net::buffer(*envelope)),
                       std::forward<Handler>(handler));
    } else {
      net::async_write(stream_, net::buffer(*envelope), std::forward<Handler>(handler));
    }
  }

  // Writes the next outgoing message or the end, unless a write is under way.
  void Pump() {
    if (writing_ || outgoing_.empty()) return;
    Outgoing next = std::move(outgoing_.front());
    outgoing_.pop_front();
    if (next.end) return StreamEnd(*next.end);
    if (broken_) {
      next.written(false);
      return Pump();
    }
    auto chunk = std::make_shared<std::string>(Envelope(0, next.payload));
    writing_ = true;
    Limit(IoTimeout());
    WriteEnvelope(chunk, [self = Self(), chunk, written = std::move(next.written)](
                             beast::error_code ec, size_t) {
      self->Written(ec);
      written(!ec);
    });
  }

  void StreamEnd(absl::Status s) {
    StopDeadline();
    held_request_.reset();
    if (broken_) return Close();
    if (deadline_passed_ && !s.ok()) {
      s = absl::DeadlineExceededError("the call's deadline (Connect-Timeout-Ms) passed");
    }
    std::string end = "{}";
    if (!s.ok()) {
      const ConnectCode c = ToConnect(s.code());
      end = absl::StrCat("{\"error\":", ErrorJson(c.name, std::string(s.message())), "}");
    }
    auto chunk = std::make_shared<std::string>(Envelope(0x02, end));
    writing_ = true;
    Limit(IoTimeout());  // the end and the last chunk
    WriteEnvelope(chunk, [self = Self(), chunk](beast::error_code ec, size_t) {
                       if (ec || !self->chunked_) return self->Close();
                       net::async_write(self->stream_, http::make_chunk_last(),
                                        [self](beast::error_code ec2, size_t) {
                                          self->writing_ = false;
                                          if (ec2 || !self->keep_alive_) return self->Close();
                                          self->Read();
                                        });
                     });
  }

  void Preflight() {
    if (origin_.empty() || !server_->Allowed(origin_)) {
      return Error(absl::StatusCode::kPermissionDenied,
                   absl::StrCat("origin \"", origin_, "\" is not allowed (--http-cors-origins)"),
                   http::status::forbidden);
    }
    Head head(http::status::no_content, version_);
    Cors(head, "");
    head.Field("Access-Control-Allow-Methods", "POST, GET, OPTIONS")
        .Field("Access-Control-Allow-Headers",
               "Content-Type, Authorization, Connect-Protocol-Version, Connect-Timeout-Ms, "
               "Content-Encoding, Connect-Content-Encoding, Connect-Accept-Encoding")
        .Field("Access-Control-Max-Age", "7200");
    Write(std::move(head), std::string());
  }

  void StaticFile(const std::string& path) {
    const auto& files = server_->options().files;
    auto it = files.find(path.empty() ? "/" : path);
    if (it == files.end()) {
      return Error(absl::StatusCode::kNotFound, absl::StrCat("no such path: ", path));
    }
    Head fields(http::status::ok, version_);
    fields.Field("Content-Type", it->second.first).Field("Cache-Control", "no-cache");
    Cors(fields, "");
    Write(std::move(fields), it->second.second);
  }

  // The CORS fields where the request's origin is allowed, and the Vary field: what the
  // answer varies with (`vary`, where not empty), and the Origin then.
  void Cors(Head& head, absl::string_view vary) {
    std::string varies(vary);
    if (!origin_.empty() && server_->Allowed(origin_)) {
      head.Field("Access-Control-Allow-Origin", origin_);
      varies = varies.empty() ? "Origin" : absl::StrCat(varies, ", Origin");
    }
    if (!varies.empty()) head.Field("Vary", varies);
  }

  // `status`, where given, is the HTTP status even for a streaming request (an unknown
  // method's 404, an unsupported content type's 415).
  void Error(absl::StatusCode code, const std::string& message,
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
  // Whether the answer takes gzip: the request's Accept-Encoding does, and it is no stream's.
  bool GzipAnswer() const { return gzip_answer_ && stream_type_.empty(); }
  // Compresses *body when `gzip`, it is kGzipFrom bytes or more, and that makes it smaller;
  // whether it did.
  static bool Compress(bool gzip, std::string* body) {
    if (!gzip || body->size() < kGzipFrom) return false;
    std::string packed = Gzip(*body);
    if (packed.empty() || packed.size() >= body->size()) return false;
    *body = std::move(packed);
    return true;
  }
  void Send(http::status status, const std::string& type, std::string body) {
    const bool gzipped = Compress(GzipAnswer(), &body);
    Send(status, type, std::move(body), gzipped);
  }
  // `body` as it goes: gzip-compressed already when `gzipped`.
  void Send(http::status status, const std::string& type, std::string body, bool gzipped) {
    Head head(status, version_);
    head.Field("Content-Type", type).Field("Accept-Encoding", "gzip");  // what requests may be
    if (gzipped) head.Field("Content-Encoding", "gzip");
    Cors(head, stream_type_.empty() ? "Accept-Encoding" : "");
    Write(std::move(head), std::move(body));
  }

  // A whole response: `head`'s fields, the Content-Length and the Connection's, then the
  // body; the next request is read after it unless the connection closes. A HEAD's answer
  // (its refusals too) has its body's length and no body; a 204's has neither (RFC 9110).
  void Write(Head head, std::string body) {
    const bool keep = keep_alive_ && !closing_;
    if (head.status() != http::status::no_content) {
      head.Field("Content-Length", absl::StrCat(body.size()));
    }
    if (head_) body.clear();
    head.KeepAlive(version_, keep);
    auto out = std::make_shared<std::pair<std::string, std::string>>(std::move(head).End(),
                                                                     std::move(body));
    Limit(IoTimeout());
    const std::array<net::const_buffer, 2> buffers{net::buffer(out->first),
                                                   net::buffer(out->second)};
    net::async_write(stream_, buffers, [self = Self(), out, keep](beast::error_code ec, size_t) {
      if (ec || !keep) return self->Close();
      self->Read();
    });
  }

  // The limit on the reads and writes under way, from now: past it the connection closes,
  // and each of them fails. Beast's tcp_stream kept a timer an operation, set and cancelled
  // in the kernel around each read and each write (four system calls a request). Here one
  // timer a connection: an operation moves the limit (a clock read), and the timer, set to
  // the limit of its time, sleeps on to the current one when it wakes before that, so that a
  // busy connection sets the kernel's timer about once a limit's length. A shorter limit than
  // the timer's sets it anew.
  void Limit(std::chrono::steady_clock::duration length) {
    limit_ = std::chrono::steady_clock::now() + length;
    if (!limit_set_ || *limit_ < limit_timer_.expiry()) SetLimitTimer();
  }
  // None from now: between a stream's messages, and while the core has the call.
  void NoLimit() { limit_.reset(); }
  std::chrono::milliseconds IoTimeout() const { return server_->options().io_timeout; }
  void SetLimitTimer() {
    limit_set_ = true;
    // A wait under way ends (its handler does nothing); one that has just woken finds the
    // limit as it is now.
    limit_timer_.expires_at(*limit_);
    // Not the session's owner: a session that ends goes with its timer.
    limit_timer_.async_wait([weak = std::weak_ptr<Session>(Self())](beast::error_code ec) {
      auto self = weak.lock();
      if (ec || !self) return;  // set anew, or the session went
      self->limit_set_ = false;
      if (!self->limit_ || self->closed_) return;
      if (std::chrono::steady_clock::now() < *self->limit_) return self->SetLimitTimer();
      self->Close();
    });
  }

  void Close() {
    if (closed_) return;
    closed_ = true;
    beast::error_code ec;
    if constexpr (std::is_same_v<StreamType, TcpStream>) {
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
  bool head_ = false;  // the request is a HEAD
  bool chunked_ = true;  // the stream's body is chunked (HTTP/1.1)
  bool json_ = true, broken_ = false, writing_ = false;
  std::string origin_, content_type_;
  std::string stream_type_;  // the request's Content-Type where it is a Connect stream's
  bool gzip_answer_ = false;  // the request's Accept-Encoding takes gzip
  // The call under way (null before the first): the core's, its deadline, and whether it
  // has passed.
  CallPtr call_;
  std::optional<StrandTimer> deadline_;
  uint64_t calls_ = 0;  // the calls begun: a call's number, so that a stale callback does nothing
  bool deadline_passed_ = false;
  bool unary_pending_ = false;  // a unary call's answer is still to be sent
  // The limit on the reads and writes under way (none: no limit), and its timer (Limit).
  std::optional<std::chrono::steady_clock::time_point> limit_;
  StrandTimer limit_timer_{stream_.get_executor()};
  bool limit_set_ = false;  // the timer waits
  std::shared_ptr<Message> held_request_;  // a stream's request, until its end
  std::deque<Outgoing> outgoing_;          // a stream's messages and end, waiting to be written
};

}  // namespace

absl::Status HttpServer::Impl::Start() {
  if (options_.io_timeout <= std::chrono::milliseconds(0)) {
    return absl::InvalidArgumentError(absl::StrCat("the HTTP I/O timeout must be positive, not ",
                                                   options_.io_timeout.count(), " ms"));
  }
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
  const int threads = options_.threads > 0
                          ? options_.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency() / 2));
  for (int i = 0; i < threads; ++i) {
    threads_.emplace_back([this] {
      pthread_setname_np(pthread_self(), "gvd-http");
      ioc_.run();
    });
  }
  return absl::OkStatus();
}

void HttpServer::Impl::Accept() {
  acceptor_.async_accept(net::make_strand(ioc_), [this](beast::error_code ec, StrandSocket socket) {
    if (ec) {
      if (!stopping_ && ec != net::error::operation_aborted) Accept();
      return;
    }
    // Without it a stream's second small write (its first message after the headers, or
    // its end) waits for the client's delayed ACK of the first: 40 ms on Linux.
    socket.set_option(tcp::no_delay(true), ec);
    if (tls_) {
      auto s = std::make_shared<Session<beast::ssl_stream<TcpStream>>>(
          this, beast::ssl_stream<TcpStream>(std::move(socket), *tls_));
      Register(s);
      s->Run();
    } else {
      auto s = std::make_shared<Session<TcpStream>>(this, TcpStream(std::move(socket)));
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
  // No I/O thread is left to hand it work: what it has not begun goes, what it has ends.
  converter_.stop();
  converter_.join();
}

absl::StatusOr<std::unique_ptr<HttpServer>> HttpServer::Start(HttpOptions options,
                                                               Service* core) {
  auto impl = std::make_unique<Impl>(std::move(options), core);
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
