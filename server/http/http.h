// The gvd.v1.VoronoiService over HTTP/1.1 in the Connect protocol (https://connectrpc.com),
// for browsers, curl and Connect clients: every RPC at POST /gvd.v1.VoronoiService/METHOD, unary
// ones with application/json (the canonical protobuf JSON mapping) or application/proto
// bodies, server-streaming ones (FindNearestStream, WatchScene) as enveloped
// application/connect+json or +proto streams; errors as {"code": "invalid_argument",
// "message": ...} with the matching HTTP status.
//
// A transport that only translates: each request is decoded into its request message and
// handed to the application core (server/app/service.h) with its Authorization header as the
// call's token and its Connect-Timeout-Ms as the deadline, so every call has the same
// admission, limits, tokens, metrics and drain as over gRPC. It adds only what HTTP needs: TLS
// on its own port, CORS for the origins allowed, and the limit on request bodies and answers
// (--max-message-bytes). Boost.Beast, asynchronous: a connection waiting on a long stream
// holds no thread, and no connection waits for another's large conversion (HttpOptions).
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/app/service.h"

namespace gvd {

struct HttpOptions {
  std::string listen;  // HOST:PORT (port 0 picks one)
  // Origins whose pages may call (CORS), exactly as browsers send them
  // ("https://app.example.com"); "*" allows any. None by default.
  std::vector<std::string> cors_origins;
  // TLS, as PEM text: the certificate chain and key, and the CA that client certificates
  // must chain to (required when set). No TLS when cert is empty.
  std::string tls_cert, tls_key, tls_client_ca;
  size_t max_body_bytes = 64 << 20;
  // I/O threads; 0: half the machine's cores, at least one. They convert only small
  // messages: a large request body is decoded on a converter thread of the server's, and an
  // answer is encoded on the thread the core answered from.
  int threads = 0;
  // How long a connection may wait idle for a request and then take to read it (its header
  // and body), and how long an answer's write (or each of a stream's) may take, before the
  // connection is closed; a TLS handshake has at most 30 s of it.
  std::chrono::milliseconds io_timeout{120'000};
  // Static files served by GET: path ("/", "/app.js") to (content type, body).
  std::map<std::string, std::pair<std::string, std::string>> files;
};

// A call as an HTTP request states it, decoded (the part of the transport that reads what
// the client sent): the method named in the path, the request message (parsed from JSON, or
// binary protobuf, into the generated class of the method's input type), and the deadline
// asked for. `method` is null when the request is refused: then `code` and `message` say
// why, and `http_status` the HTTP status when it is not the code's own (0).
struct ConnectCall {
  const google::protobuf::MethodDescriptor* method = nullptr;
  bool json = false;
  std::string content_type;  // the answer's: the request's, canonical ("application/json"...)
  std::unique_ptr<google::protobuf::Message> request;
  std::optional<std::chrono::milliseconds> timeout;
  absl::StatusCode code = absl::StatusCode::kOk;
  std::string message;
  int http_status = 0;
};
// `name`: the path after /gvd.v1.VoronoiService/; `post`: whether the HTTP method is POST;
// `timeout_ms`: the Connect-Timeout-Ms header (empty when absent); `encoding`: the body's
// Content-Encoding (unary) or Connect-Content-Encoding (streaming): "", "identity" or "gzip"
// (anything else is UNIMPLEMENTED); a gzip body inflated past `max_bytes` is
// RESOURCE_EXHAUSTED.
ConnectCall DecodeConnectCall(const std::string& name, bool post, const std::string& content_type,
                              std::string body, const std::string& timeout_ms,
                              const std::string& encoding = "",
                              size_t max_bytes = std::numeric_limits<size_t>::max());

class HttpServer {
 public:
  // Listens and serves the calls of `core`, which must outlive the server. Fails when the
  // address cannot be bound or the TLS files do not load.
  static absl::StatusOr<std::unique_ptr<HttpServer>> Start(HttpOptions options, Service* core);
  ~HttpServer();

  int port() const;
  // Stops accepting connections (those open finish the request under way; the core's drain
  // ends the streams); closes everything left after `grace`.
  void Shutdown(std::chrono::milliseconds grace);

  class Impl;

 private:
  explicit HttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace gvd
