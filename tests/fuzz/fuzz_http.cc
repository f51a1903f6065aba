// Fuzz target: bytes as an HTTP/1.1 request to the Connect transport: Boost.Beast parses them
// as gvd-server's sessions do, then DecodeConnectCall (server/http/http.h) turns the path, the
// headers and the body into a call. Whatever the input: no crash; a refusal has a code and a
// message; an accepted call names a method of gvd.v1.VoronoiService and carries a request of that
// method's input type, and a JSON request, written back as JSON by the transport's codec
// (server/http/json.h) and decoded again, gives the same request bytes.
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>
#include <google/protobuf/stubs/logging.h>

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "gvd/v1/voronoi.pb.h"
#include "server/http/http.h"
#include "server/http/json.h"

namespace {

namespace http = boost::beast::http;

void Check(bool ok) {
  if (!ok) std::abort();
}

std::string_view View(boost::beast::string_view v) { return {v.data(), v.size()}; }

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  // Links voronoi.proto's messages and builds its descriptors, so that the generated pool
  // knows gvd.v1.VoronoiService (nothing else in this binary names them).
  Check(gvd::v1::CreateSceneRequest::descriptor()->file()->FindServiceByName("VoronoiService") != nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  http::request_parser<http::string_body> parser;
  parser.body_limit(1 << 16);
  // Header and body in one put(), as a session's reads deliver them (by default put() stops
  // after the header).
  parser.eager(true);
  boost::beast::error_code ec;
  parser.put(boost::asio::buffer(data, size), ec);
  if (ec || !parser.is_done()) {
    // A request cut short: its end may come with the connection's close.
    if (ec == http::error::need_more) parser.put_eof(ec);
    if (ec || !parser.is_done()) return 0;
  }
  http::request<http::string_body> req = parser.release();
  std::string target(View(req.target()));
  target = target.substr(0, target.find('?'));
  const std::string prefix = "/gvd.v1.VoronoiService/";
  if (target.compare(0, prefix.size(), prefix) != 0) return 0;
  const std::string name = target.substr(prefix.size());
  const bool post = req.method() == http::verb::post;
  const std::string type(View(req[http::field::content_type]));
  const std::string timeout(View(req["Connect-Timeout-Ms"]));
  gvd::ConnectCall call = gvd::DecodeConnectCall(name, post, type, req.body(), timeout);
  if (call.method == nullptr) {
    Check(call.code != absl::StatusCode::kOk && !call.message.empty());
    Check(call.request == nullptr);
    return 0;
  }
  Check(call.method->service()->full_name() == "gvd.v1.VoronoiService" && post);
  Check(!call.timeout || call.timeout->count() > 0);
  // The request is of the method's input type, as the core takes it.
  Check(call.request != nullptr && call.request->GetDescriptor() == call.method->input_type());
  if (!call.json) return 0;
  const std::string json = gvd::ToJson(*call.request);
  std::string body = json;
  if (call.method->server_streaming()) {
    std::string envelope(5, '\0');
    for (int i = 0; i < 4; ++i) envelope[1 + i] = static_cast<char>((json.size() >> (24 - 8 * i)) & 0xff);
    body = envelope + json;
  }
  gvd::ConnectCall again =
      gvd::DecodeConnectCall(name, true, call.method->server_streaming() ? "application/connect+json"
                                                                         : "application/json",
                             body, "");
  Check(again.method == call.method);
  // Byte for byte (voronoi.proto has no maps, so serializing is deterministic; NaN, which no
  // field comparison finds equal to itself, round-trips through JSON's "NaN").
  Check(again.request->SerializeAsString() == call.request->SerializeAsString());
  return 0;
}
