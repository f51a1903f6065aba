// The HTTP transport (--http-listen, the Connect protocol in JSON) against the real server:
// the same answers and the same errors as gRPC, bad requests refused with the field named
// and nothing changed, tokens, TLS and CORS, server streams, and the drain.
#include <gtest/gtest.h>

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/message_differencer.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <cmath>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <thread>
#include <utility>

#include <zlib.h>

#include "absl/strings/str_cat.h"
#include "gvd/client.h"
#include "server/http/http.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
namespace ssl = net::ssl;
using grpc::StatusCode;
using tcp = net::ip::tcp;

struct Reply {
  int status = 0;
  std::map<std::string, std::string> headers;  // lower-case names
  std::string body;
};

// What a reply's body holds so far, each time more of it is read.
using BodySoFar = std::function<void(const std::string&)>;

// One HTTP/1.1 request on a connection of its own (HTTPS when `ca` is set).
Reply Send(int port, http::verb verb, const std::string& target, const std::string& body,
           const std::map<std::string, std::string>& headers = {},
           const std::string& ca = "", const BodySoFar& progress = {}) {
  net::io_context ioc;
  http::request<http::string_body> req{verb, target, 11};
  req.set(http::field::host, "127.0.0.1");
  for (const auto& [k, v] : headers) req.set(k, v);
  req.body() = body;
  req.prepare_payload();
  // Not eager: each read returns once a part (a chunk's body too) is parsed.
  http::response_parser<http::string_body> parser;
  beast::flat_buffer buffer;
  auto exchange = [&](auto& stream) {
    http::write(stream, req);
    while (!parser.is_done()) {
      http::read_some(stream, buffer, parser);
      if (progress) progress(parser.get().body());
    }
  };
  tcp::resolver resolver(ioc);
  auto endpoints = resolver.resolve("127.0.0.1", std::to_string(port));
  if (ca.empty()) {
    beast::tcp_stream stream(ioc);
    stream.connect(endpoints);
    exchange(stream);
  } else {
    ssl::context ctx(ssl::context::tls_client);
    ctx.add_certificate_authority(net::buffer(ca));
    ctx.set_verify_mode(ssl::verify_peer);
    beast::ssl_stream<beast::tcp_stream> stream(ioc, ctx);
    beast::get_lowest_layer(stream).connect(endpoints);
    stream.handshake(ssl::stream_base::client);
    exchange(stream);
  }
  const http::response<http::string_body>& res = parser.get();
  Reply r;
  r.status = static_cast<int>(res.result_int());
  for (const auto& f : res) {
    std::string name(f.name_string());
    for (char& c : name) c = static_cast<char>(std::tolower(c));
    r.headers[name] = std::string(f.value());
  }
  r.body = res.body();
  return r;
}

Reply Post(int port, const std::string& method, const std::string& json,
           std::map<std::string, std::string> headers = {}) {
  headers.emplace("Content-Type", "application/json");
  return Send(port, http::verb::post, "/gvd.v1.VoronoiService/" + method, json, headers);
}

template <class M>
std::string Json(const M& m) {
  std::string out;
  EXPECT_TRUE(google::protobuf::util::MessageToJsonString(m, &out).ok());
  return out;
}
template <class M>
M Parse(const std::string& json) {
  M m;
  auto s = google::protobuf::util::JsonStringToMessage(json, &m);
  EXPECT_TRUE(s.ok()) << s.message() << " in " << json;
  return m;
}

// The string value of the first "key" in a JSON text (with \" and \\ unescaped), or "?".
// (Not protobuf's Struct: Debian's protobuf maps crash under the TSan build's instrumentation.)
std::string JsonString(const std::string& json, const std::string& key) {
  const std::string start = "\"" + key + "\":\"";
  size_t at = json.find(start);
  if (at == std::string::npos) return "?";
  std::string out;
  for (at += start.size(); at < json.size() && json[at] != '"'; ++at) {
    if (json[at] == '\\' && at + 1 < json.size()) ++at;
    out += json[at];
  }
  return out;
}

// The Connect error of a reply: its code and message.
std::pair<std::string, std::string> ConnectError(const Reply& r) {
  EXPECT_EQ(r.headers.count("content-type") ? r.headers.at("content-type") : "", "application/json");
  return {JsonString(r.body, "code"), JsonString(r.body, "message")};
}

const char* CodeName(StatusCode c) {
  switch (c) {
    case StatusCode::INVALID_ARGUMENT: return "invalid_argument";
    case StatusCode::NOT_FOUND: return "not_found";
    case StatusCode::ALREADY_EXISTS: return "already_exists";
    case StatusCode::OUT_OF_RANGE: return "out_of_range";
    case StatusCode::FAILED_PRECONDITION: return "failed_precondition";
    case StatusCode::RESOURCE_EXHAUSTED: return "resource_exhausted";
    case StatusCode::UNAUTHENTICATED: return "unauthenticated";
    case StatusCode::PERMISSION_DENIED: return "permission_denied";
    default: return "?";
  }
}

// The messages of a Connect server stream: the enveloped JSON messages, then the end.
struct StreamReply {
  int status = 0;
  std::vector<std::string> messages;
  std::string end;  // the end-of-stream JSON
};
// The length of the envelope at `at` (its 5-byte prefix whole there).
uint32_t EnvelopeLength(const std::string& body, size_t at) {
  return (uint32_t(uint8_t(body[at + 1])) << 24) | (uint32_t(uint8_t(body[at + 2])) << 16) |
         (uint32_t(uint8_t(body[at + 3])) << 8) | uint32_t(uint8_t(body[at + 4]));
}
StreamReply ReadStream(const std::string& body, int status) {
  StreamReply r;
  r.status = status;
  size_t at = 0;
  while (at + 5 <= body.size()) {
    const uint8_t flags = static_cast<uint8_t>(body[at]);
    const uint32_t n = EnvelopeLength(body, at);
    std::string payload = body.substr(at + 5, n);
    at += 5 + n;
    EXPECT_TRUE(r.end.empty()) << "an envelope after the end of the stream";
    if (flags & 0x02) {
      r.end = payload;
    } else {
      r.messages.push_back(payload);
    }
  }
  EXPECT_EQ(at, body.size()) << "bytes past the last whole envelope";
  return r;
}
std::string Envelope(const std::string& json) {
  std::string out(5, '\0');
  const uint32_t n = static_cast<uint32_t>(json.size());
  for (int i = 0; i < 4; ++i) out[1 + i] = static_cast<char>((n >> (24 - 8 * i)) & 0xff);
  return out + json;
}
// The number of whole envelopes at the start of a stream's body.
size_t WholeEnvelopes(const std::string& body) {
  size_t n = 0;
  for (size_t at = 0; at + 5 <= body.size(); ++n) {
    at += 5 + size_t{EnvelopeLength(body, at)};
    if (at > body.size()) break;
  }
  return n;
}

// A server stream's call; `first` (when set) is called once its first envelope has come
// whole, while the stream goes on.
StreamReply Stream(int port, const std::string& method, const std::string& json,
                   std::map<std::string, std::string> headers = {},
                   std::function<void()> first = {}) {
  headers.emplace("Content-Type", "application/connect+json");
  BodySoFar progress;
  if (first) {
    progress = [&first](const std::string& body) {
      if (first && WholeEnvelopes(body) > 0) std::exchange(first, nullptr)();
    };
  }
  Reply r = Send(port, http::verb::post, "/gvd.v1.VoronoiService/" + method, Envelope(json), headers,
                 "", progress);
  EXPECT_EQ(r.headers["content-type"], "application/connect+json");
  return ReadStream(r.body, r.status);
}

// `data` gzip-compressed (zlib's own encoder, not the server's decoder).
std::string Gzip(const std::string& data) {
  z_stream z{};
  deflateInit2(&z, Z_BEST_SPEED, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  std::string out(deflateBound(&z, data.size()), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

// `data` inflated (zlib's own decoder, not the server's encoder); empty when it is not whole.
std::string Gunzip(const std::string& data) {
  z_stream z{};
  inflateInit2(&z, 16 + MAX_WBITS);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  std::string out;
  char buf[1 << 16];
  int r = Z_OK;
  while (r == Z_OK) {
    z.next_out = reinterpret_cast<Bytef*>(buf);
    z.avail_out = sizeof buf;
    r = inflate(&z, Z_NO_FLUSH);
    out.append(buf, sizeof buf - z.avail_out);
  }
  inflateEnd(&z);
  return r == Z_STREAM_END ? out : std::string();
}

class HttpTest : public testing::SharedServerTest {
 protected:
  static void SetUpTestSuite() {
    StartServer({"--http-listen", "127.0.0.1:0", "--max-message-bytes", "200000",
                 "--http-cors-origins", "https://app.example.com"});
  }
  static int port() { return server_->http_port(); }
};

// Every kind of call, JSON over HTTP and gRPC, gives the same answer; the same bad requests
// get the same code and message.
TEST_F(HttpTest, JsonAndGrpcGiveTheSameAnswersAndErrors) {
  ASSERT_GT(port(), 0);
  const v1::CreateSceneRequest create = testing::UnitScene("both", 128, 128);
  Reply r = Post(port(), "CreateScene", Json(create));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.headers["content-type"], "application/json");
  v1::UpsertSitesRequest upsert;
  upsert.set_scene_id("both");
  for (const Site& s : std::vector<Site>{{"a", PointSite{{0.2, 0.3}}},
                                         {"b", SegmentSite{{0.6, 0.6}, {0.9, 0.7}}},
                                         {"c", PolygonSite{{{0.1, 0.8}, {0.3, 0.9}, {0.2, 0.6}}}}}) {
    *upsert.add_sites() = testing::ToProtoSite(s);
  }
  r = Post(port(), "UpsertSites", Json(upsert));
  ASSERT_EQ(r.status, 200) << r.body;
  const uint64_t version = Parse<v1::UpsertSitesResponse>(r.body).version();
  ASSERT_EQ(version, 2u);

  auto same = [&](const std::string& method, const google::protobuf::Message& grpc_answer,
                  const std::string& request) {
    Reply h = Post(port(), method, request);
    ASSERT_EQ(h.status, 200) << method << ": " << h.body;
    std::unique_ptr<google::protobuf::Message> parsed(grpc_answer.New());
    ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(h.body, parsed.get()).ok()) << h.body;
    EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(*parsed, grpc_answer))
        << method << "\nHTTP: " << parsed->DebugString() << "\ngRPC: " << grpc_answer.DebugString();
  };
  // Rendered first: the same frame answers both (a read of an unrendered version may come
  // from the index, exactly; see FindNearestRequest.min_version).
  ASSERT_TRUE(testing::WaitForRender(*client_, "both", version));
  v1::FindNearestRequest find;
  find.set_scene_id("both");
  find.set_min_version(version);
  for (double x : {0.1, 0.5, 0.85}) {
    auto* p = find.add_points();
    p->set_x(x);
    p->set_y(0.65);
  }
  v1::FindNearestResponse found;
  ASSERT_TRUE(client_->FindNearest(find, &found).ok());
  same("FindNearest", found, Json(find));
  v1::FindNearestRequest packed;
  packed.set_scene_id("both");
  packed.set_exact(true);
  for (double v : {0.1, 0.2, 0.5, 0.5, 2.0, -1.0}) packed.add_xy(v);
  ASSERT_TRUE(client_->FindNearest(packed, &found).ok());
  same("FindNearest", found, Json(packed));
  v1::GetSceneResponse scene;
  ASSERT_TRUE(client_->GetScene("both", scene.mutable_scene()).ok());
  v1::GetSceneRequest get;
  get.set_scene_id("both");
  same("GetScene", scene, Json(get));
  v1::ListSitesRequest list;
  list.set_scene_id("both");
  v1::ListSitesResponse sites;
  ASSERT_TRUE(client_->ListSites(list, &sites).ok());
  same("ListSites", sites, Json(list));
  v1::PickRequest pick;
  pick.set_scene_id("both");
  pick.mutable_point()->set_x(0.75);
  pick.mutable_point()->set_y(0.6);
  v1::PickResponse picked;
  ASSERT_TRUE(client_->Pick(pick, &picked).ok());
  same("Pick", picked, Json(pick));
  v1::RenderImageRequest image;
  image.set_scene_id("both");
  image.set_min_version(version);
  v1::RenderImageResponse png;
  ASSERT_TRUE(client_->RenderImage(image, &png).ok());
  same("RenderImage", png, Json(image));  // bytes travel as base64
  v1::GetBoundariesRequest bounds;
  bounds.set_scene_id("both");
  bounds.set_min_version(version);
  v1::GetBoundariesResponse boundaries;
  ASSERT_TRUE(client_->GetBoundaries(bounds, &boundaries).ok());
  same("GetBoundaries", boundaries, Json(bounds));

  // Errors: the same code and message both ways, and the HTTP status of the code.
  struct Bad {
    std::string method, json;
    std::function<grpc::Status()> grpc_call;
    int http_status;
  };
  v1::CreateSceneRequest zero = create;
  zero.set_scene_id("zero");
  zero.set_width_px(0);
  v1::FindNearestRequest ahead = find;
  ahead.set_min_version(99);
  v1::GetSceneRequest missing;
  missing.set_scene_id("missing");
  const std::vector<Bad> bad = {
      {"CreateScene", Json(zero), [&] { return client_->CreateScene(zero, scene.mutable_scene()); }, 400},
      {"CreateScene", Json(create), [&] { return client_->CreateScene(create, scene.mutable_scene()); }, 409},
      {"FindNearest", Json(ahead), [&] { return client_->FindNearest(ahead, &found); }, 400},
      {"GetScene", Json(missing), [&] { return client_->GetScene("missing", scene.mutable_scene()); }, 404},
  };
  for (const Bad& b : bad) {
    grpc::Status g = b.grpc_call();
    ASSERT_FALSE(g.ok()) << b.json;
    Reply h = Post(port(), b.method, b.json);
    EXPECT_EQ(h.status, b.http_status) << h.body;
    EXPECT_EQ(h.headers["content-type"], "application/json");
    auto [code, message] = ConnectError(h);
    EXPECT_EQ(code, CodeName(g.error_code())) << h.body;
    EXPECT_EQ(message, g.error_message());
  }
}

// Bad JSON or protobuf, fields of the wrong type, oversize bodies, unknown methods, wrong
// verbs and content types: a 4xx naming what is wrong, and nothing changed. Unknown JSON
// fields are ignored (forward compatibility).
TEST_F(HttpTest, BadRequestsAreRefusedByNameAndChangeNothing) {
  std::vector<v1::Scene> before, after;
  ASSERT_TRUE(client_->ListScenes(&before).ok());
  struct Case {
    std::string what;
    Reply reply;
    int status;
    std::string code, names;
  };
  const std::string huge(300000, ' ');
  const std::vector<Case> cases = {
      {"not JSON", Post(port(), "CreateScene", "{\"sceneId\": "), 400, "invalid_argument", ""},
      {"binary, not protobuf", Send(port(), http::verb::post, "/gvd.v1.VoronoiService/CreateScene",
                                    std::string("\xff\xff\xff", 3),
                                    {{"Content-Type", "application/proto"}}),
       400, "invalid_argument", "CreateSceneRequest"},
      {"wrong type", Post(port(), "CreateScene", R"({"sceneId": "x", "widthPx": "wide"})"), 400,
       "invalid_argument", "width_px"},
      {"wrong type in a list",
       Post(port(), "UpsertSites", R"({"sceneId": "x", "sites": [{"id": "a", "point": {"x": []}}]})"),
       400, "invalid_argument", "x"},
      {"oversize", Post(port(), "CreateScene", "{\"sceneId\": \"x\"" + huge + "}"), 429,
       "resource_exhausted", "--max-message-bytes"},
      {"unknown method", Post(port(), "MakeCoffee", "{}"), 404, "unimplemented", "MakeCoffee"},
      {"GET of a method", Send(port(), http::verb::get, "/gvd.v1.VoronoiService/ListScenes", ""), 405,
       "unimplemented", "POST"},
      {"plain text", Send(port(), http::verb::post, "/gvd.v1.VoronoiService/ListScenes", "{}",
                          {{"Content-Type", "text/plain"}}),
       415, "unimplemented", "application/json"},
      {"unknown path", Send(port(), http::verb::get, "/etc/passwd", ""), 404, "not_found",
       "/etc/passwd"},
      {"unknown service", Send(port(), http::verb::post, "/gvd.v2.VoronoiService/ListScenes", "{}",
                               {{"Content-Type", "application/json"}}),
       404, "unimplemented", "gvd.v2.VoronoiService"},
      {"bad timeout", Post(port(), "ListScenes", "{}", {{"Connect-Timeout-Ms", "soon"}}), 400,
       "invalid_argument", "Connect-Timeout-Ms"},
      // The Connect protocol's header holds at most 10 digits.
      {"long timeout", Post(port(), "ListScenes", "{}", {{"Connect-Timeout-Ms", "99999999999"}}),
       400, "invalid_argument", "at most 10 digits"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    EXPECT_EQ(c.reply.status, c.status) << c.reply.body;
    auto [code, message] = ConnectError(c.reply);
    EXPECT_EQ(code, c.code);
    EXPECT_NE(message.find(c.names), std::string::npos) << message;
  }
  ASSERT_TRUE(client_->ListScenes(&after).ok());
  EXPECT_EQ(before.size(), after.size());
  // The connection stays usable after a refusal it could read through.
  EXPECT_EQ(Post(port(), "ListScenes", "{}").status, 200);
  // A field this server does not know (a newer client's) is ignored.
  Reply newer = Post(port(), "CreateScene",
                     R"({"sceneId": "newer", "widthPx": 8, "heightPx": 8,
                         "window": {"maxX": 1, "maxY": 1}, "colour": "red"})");
  EXPECT_EQ(newer.status, 200) << newer.body;
  v1::Scene made;
  ASSERT_TRUE(client_->GetScene("newer", &made).ok());
  EXPECT_EQ(made.width_px(), 8u);
  ASSERT_TRUE(client_->DeleteScene("newer").ok());
}

// A body past --max-message-bytes (5 MB here, against 200,000 bytes) is read through and
// answered 429 resource_exhausted naming the flag, and the connection then serves the next
// request: a client sending it sees the answer, not a broken pipe.
TEST_F(HttpTest, OversizeBodiesAreReadThroughAndAnswered) {
  net::io_context ioc;
  tcp::resolver resolver(ioc);
  beast::tcp_stream stream(ioc);
  stream.connect(resolver.resolve("127.0.0.1", std::to_string(port())));
  beast::flat_buffer buffer;
  // `chunked`: the body sent in 64 KB chunks with no length, as a streaming client sends it.
  auto call = [&](const std::string& method, std::string body, bool chunked = false) {
    http::request<http::string_body> req{http::verb::post, "/gvd.v1.VoronoiService/" + method, 11};
    req.set(http::field::host, "127.0.0.1");
    req.set(http::field::content_type, "application/json");
    req.keep_alive(true);
    if (chunked) {
      req.chunked(true);
      http::request_serializer<http::string_body> head(req);
      http::write_header(stream, head);
      for (size_t at = 0; at < body.size(); at += 65536) {
        net::write(stream, http::make_chunk(net::buffer(body.substr(at, 65536))));
      }
      net::write(stream, http::make_chunk_last());
    } else {
      req.body() = std::move(body);
      req.prepare_payload();
      http::write(stream, req);
    }
    http::response<http::string_body> res;
    http::read(stream, buffer, res);
    Reply r;
    r.status = static_cast<int>(res.result_int());
    r.headers["content-type"] = std::string(res[http::field::content_type]);
    r.body = res.body();
    return r;
  };
  Reply big = call("CreateScene", "{\"sceneId\": \"x\"" + std::string(5 << 20, ' ') + "}");
  EXPECT_EQ(big.status, 429) << big.body;
  EXPECT_EQ(ConnectError(big).first, "resource_exhausted");
  EXPECT_NE(ConnectError(big).second.find("--max-message-bytes"), std::string::npos);
  EXPECT_EQ(call("ListScenes", "{}").status, 200);  // the same connection
  // Chunked: kept within the limit, read through and refused past it.
  EXPECT_EQ(call("ListScenes", "{}", /*chunked=*/true).status, 200);
  Reply chunked = call("CreateScene", "{\"sceneId\": \"x\"" + std::string(5 << 20, ' ') + "}", true);
  EXPECT_EQ(chunked.status, 429) << chunked.body;
  EXPECT_NE(ConnectError(chunked).second.find("--max-message-bytes"), std::string::npos);
  EXPECT_EQ(call("ListScenes", "{}").status, 200);  // the same connection still
}

// Request bodies compressed with gzip (Content-Encoding, and Connect-Content-Encoding with a
// compressed envelope for a stream) are answered as the same bodies plain; another coding is
// UNIMPLEMENTED naming what is supported; a body that inflates past --max-message-bytes is
// RESOURCE_EXHAUSTED (429); broken gzip is INVALID_ARGUMENT. Answers say gzip is accepted.
TEST_F(HttpTest, GzipRequestBodies) {
  const std::string create =
      R"({"sceneId": "zipped", "widthPx": 16, "heightPx": 16, "window": {"maxX": 1, "maxY": 1}})";
  Reply made = Post(port(), "CreateScene", Gzip(create), {{"Content-Encoding", "gzip"}});
  EXPECT_EQ(made.status, 200) << made.body;
  EXPECT_EQ(made.headers["accept-encoding"], "gzip");
  v1::Scene scene;
  ASSERT_TRUE(client_->GetScene("zipped", &scene).ok());
  const uint64_t v = Upsert("zipped", {{"a", PointSite{{0.25, 0.25}}}});
  Reply brotli = Post(port(), "GetScene", R"({"sceneId": "zipped"})", {{"Content-Encoding", "br"}});
  EXPECT_EQ(ConnectError(brotli).first, "unimplemented");
  EXPECT_NE(ConnectError(brotli).second.find("gzip"), std::string::npos);
  Reply bomb = Post(port(), "GetScene", Gzip("{\"sceneId\": \"zipped\"" + std::string(400000, ' ') + "}"),
                    {{"Content-Encoding", "gzip"}});
  EXPECT_EQ(bomb.status, 429) << bomb.body;
  EXPECT_EQ(ConnectError(bomb).first, "resource_exhausted");
  EXPECT_NE(ConnectError(bomb).second.find("--max-message-bytes"), std::string::npos);
  Reply broken = Post(port(), "GetScene", Gzip(create).substr(0, 10), {{"Content-Encoding", "gzip"}});
  EXPECT_EQ(ConnectError(broken).first, "invalid_argument");
  // A stream's compressed envelope.
  v1::FindNearestRequest find;
  find.set_scene_id("zipped");
  find.set_min_version(v);
  find.add_xy(0.5);
  find.add_xy(0.5);
  std::string envelope = Envelope(Gzip(Json(find)));
  envelope[0] = 0x01;
  Reply r = Send(port(), http::verb::post, "/gvd.v1.VoronoiService/FindNearestStream", envelope,
                 {{"Content-Type", "application/connect+json"}, {"Connect-Content-Encoding", "gzip"}});
  EXPECT_EQ(r.headers["connect-accept-encoding"], "gzip");
  StreamReply s = ReadStream(r.body, r.status);
  ASSERT_EQ(s.messages.size(), 1u) << r.body;
  EXPECT_EQ(Parse<v1::FindNearestStreamResponse>(s.messages[0]).packed().site_ids(0), "a");
  EXPECT_EQ(s.end, "{}");
}

// Answers are gzip-compressed where the request's Accept-Encoding takes gzip and the body is
// over 1 KB, and are then the same bytes inflated; not for q=0, small bodies or streams.
TEST_F(HttpTest, AnswersAreGzipWhereTheRequestTakesIt) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(testing::UnitScene("gzipped", 64, 64), &scene).ok());
  SiteTable sites;
  for (int i = 0; i < 300; ++i) sites.push_back({"site-" + std::to_string(i), PointSite{{i / 300.0, 0.5}}});
  const uint64_t v = Upsert("gzipped", sites);
  const std::string list = R"({"sceneId": "gzipped", "pageSize": 1000})";
  Reply plain = Post(port(), "ListSites", list);
  ASSERT_EQ(plain.status, 200) << plain.body;
  ASSERT_GT(plain.body.size(), 1024u);
  EXPECT_EQ(plain.headers.count("content-encoding"), 0u);
  for (const std::string accept : {"gzip", "deflate, gzip;q=0.8", "br, GZIP"}) {
    SCOPED_TRACE(accept);
    Reply zipped = Post(port(), "ListSites", list, {{"Accept-Encoding", accept}});
    EXPECT_EQ(zipped.headers["content-encoding"], "gzip");
    EXPECT_LT(zipped.body.size(), plain.body.size() / 2);
    EXPECT_EQ(Gunzip(zipped.body), plain.body);
  }
  // A page of an allowed origin: the answer varies with both.
  Reply cors = Post(port(), "ListSites", list,
                    {{"Accept-Encoding", "gzip"}, {"Origin", "https://app.example.com"}});
  EXPECT_EQ(cors.headers["content-encoding"], "gzip");
  EXPECT_EQ(cors.headers["vary"], "Accept-Encoding, Origin");
  Reply refused = Post(port(), "ListSites", list, {{"Accept-Encoding", "gzip;q=0, deflate"}});
  EXPECT_EQ(refused.headers.count("content-encoding"), 0u);
  EXPECT_EQ(refused.body, plain.body);
  Reply small = Post(port(), "GetScene", R"({"sceneId": "gzipped"})", {{"Accept-Encoding", "gzip"}});
  EXPECT_LT(small.body.size(), 1024u);
  EXPECT_EQ(small.headers.count("content-encoding"), 0u);
  v1::FindNearestRequest find;
  find.set_scene_id("gzipped");
  find.set_min_version(v);
  for (int i = 0; i < 500; ++i) {
    find.add_xy(i / 500.0);
    find.add_xy(0.25);
  }
  StreamReply stream = Stream(port(), "FindNearestStream", Json(find), {{"Accept-Encoding", "gzip"}});
  EXPECT_EQ(stream.status, 200);
  ASSERT_EQ(stream.messages.size(), 1u);
  EXPECT_EQ(Parse<v1::FindNearestStreamResponse>(stream.messages[0]).packed().distance_size(), 500);
}

// Server streams in the Connect protocol: FindNearestStream's chunks as gRPC gives them,
// WatchScene's events and its end at the scene's deletion, and an error's end.
TEST_F(HttpTest, ServerStreamsOverHttp) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(testing::UnitScene("streamed", 64, 64), &scene).ok());
  const uint64_t v = Upsert("streamed", {{"a", PointSite{{0.2, 0.2}}}, {"b", PointSite{{0.8, 0.7}}}});
  ASSERT_TRUE(testing::WaitForRender(*client_, "streamed", v));  // one frame answers both
  v1::FindNearestStreamRequest find;
  find.set_scene_id("streamed");
  find.set_min_version(v);
  find.set_chunk_size(3);
  for (int i = 0; i < 10; ++i) {
    find.add_xy(i / 10.0);
    find.add_xy(1 - i / 10.0);
  }
  std::vector<v1::FindNearestStreamResponse> chunks;
  ASSERT_TRUE(client_->FindNearestStream(find, &chunks).ok());
  StreamReply s = Stream(port(), "FindNearestStream", Json(find));
  EXPECT_EQ(s.status, 200);
  ASSERT_EQ(s.messages.size(), chunks.size());
  for (size_t k = 0; k < chunks.size(); ++k) {
    EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(
        Parse<v1::FindNearestStreamResponse>(s.messages[k]), chunks[k]));
  }
  EXPECT_EQ(s.end, "{}");

  // A watch from v, on its own thread until the deletion ends it. Its first event is a
  // version after v: of a frame it heard published, or the latest frame when it began
  // after the writes' renders.
  StreamReply watched;
  std::promise<void> first_event;
  std::thread watcher([&] {
    v1::WatchSceneRequest w;
    w.set_scene_id("streamed");
    w.set_after_version(v);
    watched = Stream(port(), "WatchScene", Json(w), {}, [&] { first_event.set_value(); });
  });
  uint64_t last = v;
  for (int i = 0; i < 3; ++i) {
    last = Upsert("streamed", {{"c" + std::to_string(i), PointSite{{0.5, 0.1 * i}}}});
  }
  EXPECT_EQ(first_event.get_future().wait_for(std::chrono::seconds(60)), std::future_status::ready);
  ASSERT_TRUE(client_->DeleteScene("streamed").ok());
  watcher.join();
  EXPECT_EQ(watched.status, 200);
  ASSERT_GE(watched.messages.size(), 2u);
  EXPECT_EQ(Parse<v1::WatchSceneResponse>(watched.messages.front()).scene_id(), "streamed");
  EXPECT_GT(Parse<v1::WatchSceneResponse>(watched.messages.front()).version(), v);
  EXPECT_TRUE(Parse<v1::WatchSceneResponse>(watched.messages.back()).deleted());
  EXPECT_LE(Parse<v1::WatchSceneResponse>(watched.messages[watched.messages.size() - 2]).version(), last);
  EXPECT_EQ(watched.end, "{}");

  v1::WatchSceneRequest gone;
  gone.set_scene_id("streamed");
  StreamReply error = Stream(port(), "WatchScene", Json(gone));
  EXPECT_EQ(error.status, 200);
  EXPECT_TRUE(error.messages.empty());
  EXPECT_EQ(error.end.rfind("{\"error\":{", 0), 0u) << error.end;
  EXPECT_EQ(JsonString(error.end, "code"), "not_found");

  // Errors found before the stream starts come the same way, 200 and the end-of-stream
  // message: streaming clients read no error from an HTTP status.
  StreamReply bad_timeout =
      Stream(port(), "WatchScene", Json(gone), {{"Connect-Timeout-Ms", "soon"}});
  EXPECT_EQ(bad_timeout.status, 200);
  EXPECT_TRUE(bad_timeout.messages.empty());
  EXPECT_EQ(JsonString(bad_timeout.end, "code"), "invalid_argument") << bad_timeout.end;
  EXPECT_NE(bad_timeout.end.find("Connect-Timeout-Ms"), std::string::npos) << bad_timeout.end;
  StreamReply oversize = Stream(port(), "FindNearestStream",
                                "{\"sceneId\": \"x\"" + std::string(300000, ' ') + "}");
  EXPECT_EQ(oversize.status, 200);
  EXPECT_EQ(JsonString(oversize.end, "code"), "resource_exhausted") << oversize.end;
  EXPECT_NE(oversize.end.find("--max-message-bytes"), std::string::npos) << oversize.end;
}

// CORS: a preflight from an allowed origin is answered with what a browser needs, from
// another origin refused; answers carry Access-Control-Allow-Origin only for allowed ones.
TEST_F(HttpTest, CorsForTheAllowedOriginsOnly) {
  Reply ok = Send(port(), http::verb::options, "/gvd.v1.VoronoiService/ListScenes", "",
                  {{"Origin", "https://app.example.com"},
                   {"Access-Control-Request-Method", "POST"},
                   {"Access-Control-Request-Headers", "content-type, authorization"}});
  EXPECT_EQ(ok.status, 204);
  EXPECT_EQ(ok.headers["access-control-allow-origin"], "https://app.example.com");
  EXPECT_NE(ok.headers["access-control-allow-headers"].find("Authorization"), std::string::npos);
  EXPECT_NE(ok.headers["access-control-allow-methods"].find("POST"), std::string::npos);
  Reply other = Send(port(), http::verb::options, "/gvd.v1.VoronoiService/ListScenes", "",
                     {{"Origin", "https://evil.example.com"}, {"Access-Control-Request-Method", "POST"}});
  EXPECT_EQ(other.status, 403);
  EXPECT_EQ(other.headers.count("access-control-allow-origin"), 0u);
  EXPECT_EQ(Post(port(), "ListScenes", "{}", {{"Origin", "https://app.example.com"}})
                .headers["access-control-allow-origin"],
            "https://app.example.com");
  EXPECT_EQ(Post(port(), "ListScenes", "{}", {{"Origin", "https://evil.example.com"}})
                .headers.count("access-control-allow-origin"),
            0u);
}

// Responses read off one connection by Beast's parser, which checks their framing: the
// requests' bytes are written whole first (pipelined), then `heads[k]` says whether the k-th
// answers a HEAD (a body's length and no body). `closed`: the server ended the connection
// after the last.
struct Exchanged {
  std::vector<http::response<http::string_body>> responses;
  bool closed = false;
};
Exchanged Exchange(int port, const std::string& requests, const std::vector<bool>& heads) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)));
  net::write(stream, net::buffer(requests));
  beast::flat_buffer buffer;
  Exchanged out;
  for (bool head : heads) {
    http::response_parser<http::string_body> parser;
    parser.skip(head);
    stream.expires_after(std::chrono::seconds(30));
    beast::error_code ec;
    http::read(stream, buffer, parser, ec);
    if (ec) {
      ADD_FAILURE() << "response " << out.responses.size() << ": " << ec.message();
      return out;
    }
    out.responses.push_back(parser.release());
  }
  // Bytes past the last response are none of its; a closing server sends none.
  stream.expires_after(std::chrono::seconds(30));
  char more;
  beast::error_code ec;
  const size_t n = stream.read_some(net::buffer(&more, 1), ec);
  out.closed = ec == net::error::eof && n == 0 && buffer.size() == 0;
  return out;
}

// Each response is framed as HTTP/1.1 (RFC 9110, 9112) says for its request: HTTP/1.0
// answered in 1.0 and closed unless it asks to be kept alive, HTTP/1.1 kept alive unless it
// says "close", a HEAD answered with its GET's length and no body (its refusals too), a
// preflight's 204 with neither, an HTTP/1.0 stream unchunked to the close; requests written
// together answered in order.
TEST_F(HttpTest, ResponsesAreFramedForEachVersionAndMethod) {
  auto post = [](const std::string& version, const std::string& connection) {
    return absl::StrCat("POST /gvd.v1.VoronoiService/ListScenes HTTP/", version,
                        "\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n",
                        connection.empty() ? "" : absl::StrCat("Connection: ", connection, "\r\n"),
                        "Content-Length: 2\r\n\r\n{}");
  };
  {
    const Exchanged x = Exchange(port(), post("1.0", ""), {false});
    ASSERT_EQ(x.responses.size(), 1u);
    EXPECT_EQ(x.responses[0].version(), 10);
    EXPECT_EQ(x.responses[0].result_int(), 200);
    EXPECT_FALSE(x.responses[0].keep_alive());
    EXPECT_EQ(x.responses[0].body().front(), '{') << x.responses[0].body();
    EXPECT_TRUE(x.closed);
  }
  {
    const Exchanged x =
        Exchange(port(), post("1.0", "keep-alive") + post("1.0", ""), {false, false});
    ASSERT_EQ(x.responses.size(), 2u);
    EXPECT_EQ(x.responses[0][http::field::connection], "keep-alive");
    EXPECT_TRUE(x.responses[0].keep_alive());
    EXPECT_FALSE(x.responses[1].keep_alive());
    EXPECT_EQ(x.responses[0].body(), x.responses[1].body());
    EXPECT_TRUE(x.closed);
  }
  {
    const Exchanged x = Exchange(port(), post("1.1", "") + post("1.1", "close"), {false, false});
    ASSERT_EQ(x.responses.size(), 2u);
    EXPECT_EQ(x.responses[0].version(), 11);
    EXPECT_TRUE(x.responses[0].keep_alive());
    EXPECT_EQ(x.responses[0].count(http::field::connection), 0u);
    EXPECT_EQ(x.responses[1][http::field::connection], "close");
    EXPECT_TRUE(x.closed);
  }
  {
    const std::string get = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    const std::string head = "HEAD / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    const std::string preflight =
        "OPTIONS /gvd.v1.VoronoiService/ListScenes HTTP/1.1\r\nHost: 127.0.0.1\r\n"
        "Origin: https://app.example.com\r\nAccess-Control-Request-Method: POST\r\n\r\n";
    const Exchanged x = Exchange(port(), head + preflight + get + post("1.1", "close"),
                                 {true, false, false, false});
    ASSERT_EQ(x.responses.size(), 4u);
    const auto& [h, p, g, last] =
        std::tie(x.responses[0], x.responses[1], x.responses[2], x.responses[3]);
    EXPECT_EQ(g.result_int(), 200);
    ASSERT_FALSE(g.body().empty());
    EXPECT_EQ(h.result_int(), 200);
    EXPECT_EQ(h[http::field::content_length], std::to_string(g.body().size()));
    EXPECT_EQ(h[http::field::content_type], g[http::field::content_type]);
    EXPECT_EQ(p.result_int(), 204);
    EXPECT_TRUE(p.body().empty());
    EXPECT_EQ(p.count(http::field::content_length), 0u);
    EXPECT_EQ(p[http::field::access_control_allow_origin], "https://app.example.com");
    EXPECT_EQ(last.result_int(), 200);
    EXPECT_TRUE(x.closed);
  }
  {
    // Refused HEADs: a path with no file, a method of the service's (which takes POST).
    const std::string missing = "HEAD /no-such-file HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    const std::string method =
        "HEAD /gvd.v1.VoronoiService/ListScenes HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    const Exchanged x =
        Exchange(port(), missing + method + post("1.1", "close"), {true, true, false});
    ASSERT_EQ(x.responses.size(), 3u);
    EXPECT_EQ(x.responses[0].result_int(), 404);
    EXPECT_GE(x.responses[1].result_int(), 400);
    EXPECT_EQ(x.responses[2].result_int(), 200);  // no refusal's body read as its answer
    EXPECT_EQ(x.responses[2].body().front(), '{') << x.responses[2].body();
    EXPECT_TRUE(x.closed);
  }
  {
    // A server stream over HTTP/1.0, which has no chunks: its envelopes as they are, the
    // body ended by the connection's close.
    ASSERT_EQ(Post(port(), "CreateScene", Json(testing::UnitScene("framing", 32, 32))).status,
              200);
    ASSERT_EQ(Post(port(), "UpsertSites",
                   R"({"sceneId": "framing", "sites": [{"id": "a", "point": {"x": 0.25, "y": 0.25}}]})")
                  .status,
              200);
    const std::string body = Envelope(R"({"sceneId": "framing", "points": [{"x": 0.5}]})");
    const Exchanged x = Exchange(
        port(),
        absl::StrCat("POST /gvd.v1.VoronoiService/FindNearestStream HTTP/1.0\r\nHost: 127.0.0.1"
                     "\r\nContent-Type: application/connect+json\r\nContent-Length: ",
                     body.size(), "\r\n\r\n", body),
        {false});
    ASSERT_EQ(x.responses.size(), 1u);
    EXPECT_EQ(x.responses[0].result_int(), 200);
    EXPECT_EQ(x.responses[0].count(http::field::transfer_encoding), 0u);
    const StreamReply stream = ReadStream(x.responses[0].body(), 200);
    ASSERT_EQ(stream.messages.size(), 1u) << x.responses[0].body();
    EXPECT_NE(stream.messages[0].find("\"a\""), std::string::npos) << stream.messages[0];
    EXPECT_EQ(stream.end, "{}");
    EXPECT_TRUE(x.closed);
  }
}

// Large FindNearestStream chunks in binary (1 MB each), several times over: each response
// whole, its chunked framing intact (Beast's reader refuses anything else), every message
// the same as gRPC's, the end last. (The end of the call used to be written while its last
// message still was, interleaving their bytes.)
TEST(HttpStreams, LargeChunksArriveWholeAndInOrder) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--http-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ClientOptions options;
  options.timeout = std::chrono::seconds(600);  // generous: the sanitizer builds are slow
  auto client = Client::Connect(server.address(), options);
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("large", 64, 64), &scene).ok());
  const v1::UpsertSitesRequest sites = testing::RandomPoints("large", 300, 41, "p");
  uint64_t version = 0;
  ASSERT_TRUE(client->UpsertSites(sites, &version).ok());
  v1::FindNearestStreamRequest find;
  find.set_scene_id("large");
  find.set_min_version(version);
  find.set_chunk_size(50000);  // four equal chunks of 1 MB: the last write is a large one
  std::mt19937_64 rng(41);
  rng.discard(600);  // past the sites' coordinates
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 200000; ++i) {
    find.add_xy(u(rng));
    find.add_xy(u(rng));
  }
  std::vector<v1::FindNearestStreamResponse> chunks;
  ASSERT_TRUE(client->FindNearestStream(find, &chunks).ok());
  ASSERT_EQ(chunks.size(), 4u);
  std::string body(5, '\0');
  const std::string request = find.SerializeAsString();
  for (int i = 0; i < 4; ++i) body[1 + i] = static_cast<char>((request.size() >> (24 - 8 * i)) & 0xff);
  body += request;
  for (int round = 0; round < 8; ++round) {
    SCOPED_TRACE(round);
    Reply r;
    try {
      r = Send(server.http_port(), http::verb::post, "/gvd.v1.VoronoiService/FindNearestStream", body,
               {{"Content-Type", "application/connect+proto"}});
    } catch (const std::exception& e) {
      FAIL() << "the response is not well-formed HTTP: " << e.what();
    }
    StreamReply s = ReadStream(r.body, r.status);
    EXPECT_EQ(s.status, 200);
    EXPECT_EQ(s.end, "{}");
    ASSERT_EQ(s.messages.size(), chunks.size());
    for (size_t k = 0; k < chunks.size(); ++k) {
      v1::FindNearestStreamResponse m;
      ASSERT_TRUE(m.ParseFromString(s.messages[k]));
      EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(m, chunks[k]));
    }
  }
}

// A large request body and a large answer are converted off the HTTP threads: with the
// server's one HTTP thread, while a call is held in either conversion (the test hook), a small
// call on another connection is answered, and the held call's answer is whole once it goes on.
TEST(HttpConversions, ALargeCallHoldsUpNoOtherConnection) {
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--http-listen", "127.0.0.1:0", "--http-threads", "1"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  const int port = server.http_port();
  ASSERT_EQ(Post(port, "CreateScene",
                 R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 64, "heightPx": 64})")
                .status,
            200);
  ASSERT_EQ(Post(port, "UpsertSites",
                 R"({"sceneId": "s", "sites": [{"id": "a", "point": {"x": 0.25, "y": 0.25}},)"
                 R"( {"id": "b", "point": {"x": 0.75, "y": 0.75}}]})")
                .status,
            200);
  const std::string hold = server.hold_conversions_path();
  // Runs `call` while the conversions are held, and a small call once one waits; then lets
  // it go and returns its reply.
  auto held = [&](const std::function<Reply()>& call) {
    std::ofstream(hold).put('x');
    Reply reply;
    std::thread big([&] { reply = call(); });
    EXPECT_TRUE(testing::WaitForFile(hold + ".waiting")) << "no conversion was held";
    auto small = std::async(std::launch::async, [port] { return Post(port, "ListScenes", "{}"); });
    EXPECT_EQ(small.wait_for(std::chrono::minutes(1)), std::future_status::ready)
        << "a small call waited for another connection's conversion";
    std::remove(hold.c_str());
    EXPECT_EQ(small.get().status, 200);
    big.join();
    return reply;
  };
  // A request of 6,000 points, some 140 KB of JSON: its body is held.
  std::string points;
  for (int k = 0; k < 6000; ++k) points += std::string(k ? "," : "") + R"({"x": 0.1, "y": 0.2})";
  const Reply found = held([&] {
    return Post(port, "FindNearest", R"({"sceneId": "s", "points": [)" + points + "]}");
  });
  ASSERT_EQ(found.status, 200) << found.body;
  const auto answers = Parse<v1::FindNearestResponse>(found.body);
  ASSERT_EQ(answers.results_size(), 6000);
  const double exact = std::hypot(0.25 - 0.1, 0.25 - 0.2);
  for (const auto& r : answers.results()) {
    ASSERT_EQ(r.site_id(), "a");
    ASSERT_LE(std::abs(r.distance() - exact), r.error_bound() + 1e-12);
  }
  // A small request whose answer, 160 x 160 pixels, is some 130 KB: the answer is held.
  const Reply window = held([&] {
    return Post(port, "RenderWindow",
                R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 160, "heightPx": 160})");
  });
  ASSERT_EQ(window.status, 200) << window.body;
  const auto raster = Parse<v1::RenderWindowResponse>(window.body);
  ASSERT_EQ(raster.ids_size(), 160 * 160);
  // Pixel centres at (0.25, 0.25) and (0.75, 0.75), away from the cells' border x + y = 1.
  auto site_at = [&raster](int i, int j) {
    const uint32_t id = raster.ids(j * 160 + i);
    return id == 0 ? std::string("none") : raster.site_ids(static_cast<int>(id) - 1);
  };
  EXPECT_EQ(site_at(40, 40), "a");
  EXPECT_EQ(site_at(120, 120), "b");
  // The flag's bound, refused by name.
  testing::ServerProcess many(GVD_SERVER_PATH,
                              {"--http-listen", "127.0.0.1:0", "--http-threads", "65"});
  EXPECT_NE(many.error().find("--http-threads needs 0 to 64, not 65"), std::string::npos)
      << many.error();
}

// Tokens and TLS apply to HTTP as to gRPC: no token, UNAUTHENTICATED (401); a read token on
// a write, PERMISSION_DENIED (403); a write token works; only over HTTPS with the server's
// certificate.
TEST(HttpSecurity, TokensAndTls) {
  char dir_template[] = "/tmp/gvd-http-pki-XXXXXX";
  const std::string d = mkdtemp(dir_template);
  const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes ";
  const std::string script =
      "cd " + d + " && exec >openssl.log 2>&1 && set -e && "
      "openssl req -x509" + ec + "-keyout ca.key -out ca.pem -days 2 -subj /CN=gvd-test-ca && "
      "openssl req" + ec + "-keyout server.key -out server.csr -subj /CN=localhost && "
      "printf 'subjectAltName=IP:127.0.0.1,DNS:localhost' > san.ext && "
      "openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
      "-out server.pem -days 2 -extfile san.ext";
  if (std::system(("bash -c \"" + script + "\"").c_str()) != 0) {
    GTEST_SKIP() << "openssl could not make test certificates";
  }
  std::ofstream(d + "/tokens") << "reader-token-0123456789 read\nwriter-token-0123456789 write\n";
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--http-listen", "127.0.0.1:0", "--tokens", d + "/tokens",
                                 "--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  std::stringstream ca;
  ca << std::ifstream(d + "/ca.pem").rdbuf();
  auto post = [&](const std::string& method, const std::string& json, const std::string& token) {
    std::map<std::string, std::string> h{{"Content-Type", "application/json"}};
    if (!token.empty()) h["Authorization"] = "Bearer " + token;
    return Send(server.http_port(), http::verb::post, "/gvd.v1.VoronoiService/" + method, json, h,
                ca.str());
  };
  const std::string create =
      R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 8, "heightPx": 8})";
  Reply r = post("ListScenes", "{}", "");
  EXPECT_EQ(r.status, 401);
  EXPECT_EQ(ConnectError(r).first, "unauthenticated");
  r = post("CreateScene", create, "reader-token-0123456789");
  EXPECT_EQ(r.status, 403);
  EXPECT_EQ(ConnectError(r).first, "permission_denied");
  EXPECT_EQ(post("CreateScene", create, "writer-token-0123456789").status, 200);
  EXPECT_EQ(post("ListScenes", "{}", "reader-token-0123456789").status, 200);
  // Plain HTTP on the TLS port gets no answer.
  EXPECT_ANY_THROW(Send(server.http_port(), http::verb::post, "/gvd.v1.VoronoiService/ListScenes", "{}",
                        {{"Content-Type", "application/json"}}));
  std::system(("rm -rf " + d).c_str());
}

// Connect-Timeout-Ms is the call's deadline: a read that waits for a render held back ends
// 504 deadline_exceeded when it passes (the call is cancelled in the core, which counts it no
// more), a stream's end says the same, and a call within its deadline is answered.
TEST_F(HttpTest, DeadlinesEndCallsThatWait) {
  ASSERT_EQ(Post(port(), "CreateScene", Json(testing::UnitScene("late", 32, 32))).status, 200);
  v1::FindNearestRequest find;
  find.set_scene_id("late");
  find.add_points()->set_x(0.5);
  {
    testing::HoldRenders hold(*server_);
    // Weighted: the index does not answer in place of the frame (see min_version).
    Site a{"a", PointSite{{0.25, 0.25}}};
    a.additive = 0.01;
    find.set_min_version(Upsert("late", {a}));
    const auto start = std::chrono::steady_clock::now();
    Reply late = Post(port(), "FindNearest", Json(find), {{"Connect-Timeout-Ms", "200"}});
    EXPECT_EQ(late.status, 504) << late.body;
    // The deadline's own answer, not the cancelled call's.
    EXPECT_EQ(ConnectError(late), std::make_pair(std::string("deadline_exceeded"),
                                                 std::string("the call's deadline "
                                                             "(Connect-Timeout-Ms) passed")))
        << late.body;
    EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(200));
    StreamReply stream = Stream(port(), "FindNearestStream", Json(find),
                                {{"Connect-Timeout-Ms", "200"}});
    EXPECT_EQ(stream.status, 200);
    EXPECT_TRUE(stream.messages.empty());
    EXPECT_EQ(JsonString(stream.end, "code"), "deadline_exceeded") << stream.end;
  }
  // Released: the same call within a generous deadline is answered.
  Reply answered = Post(port(), "FindNearest", Json(find), {{"Connect-Timeout-Ms", "600000"}});
  EXPECT_EQ(answered.status, 200) << answered.body;
  EXPECT_EQ(JsonString(answered.body, "siteId"), "a") << answered.body;
  // Calls answered at once under a short deadline, whose timer is never set, then one that
  // waits past it: each gets its own answer.
  for (int i = 0; i < 3; ++i) {
    Reply quick = Post(port(), "FindNearest", Json(find), {{"Connect-Timeout-Ms", "50"}});
    EXPECT_EQ(quick.status, 200) << quick.body;
  }
  testing::HoldRenders hold(*server_);
  Site b{"b", PointSite{{0.75, 0.25}}};
  b.additive = 0.01;
  find.set_min_version(Upsert("late", {b}));
  Reply waited = Post(port(), "FindNearest", Json(find), {{"Connect-Timeout-Ms", "50"}});
  EXPECT_EQ(waited.status, 504) << waited.body;
}

// SIGTERM: an HTTP watch ends with UNAVAILABLE in its end-of-stream, and the server exits 0.
TEST(HttpDrain, ShutdownEndsHttpStreams) {
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--http-listen", "127.0.0.1:0", "--shutdown-grace-ms", "600000"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ASSERT_EQ(Post(server.http_port(), "CreateScene",
                 R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 8, "heightPx": 8})")
                .status,
            200);
  StreamReply watched;
  std::promise<void> first_event;
  std::thread watcher([&] {
    watched = Stream(server.http_port(), "WatchScene", R"({"sceneId": "s"})", {},
                     [&] { first_event.set_value(); });
  });
  // The first event comes at once (the scene's frame); then the drain.
  EXPECT_EQ(first_event.get_future().wait_for(std::chrono::seconds(60)), std::future_status::ready);
  server.Terminate();
  watcher.join();
  EXPECT_EQ(watched.status, 200);
  ASSERT_FALSE(watched.messages.empty());
  EXPECT_EQ(watched.end.rfind("{\"error\":{", 0), 0u) << watched.end;
  EXPECT_EQ(JsonString(watched.end, "code"), "unavailable");
  const int status = server.Wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.log();
}

// SIGTERM while an HTTP call waits for a render held back (of a weighted site, which the
// index does not answer in place of the frame): the call's end comes after the
// HTTP server stopped serving, and the server still stops cleanly (the core's answer to a
// connection already gone is dropped with it: ASan's build checks nothing outlives it).
TEST(HttpDrain, ACallThatOutlivesTheServerEndsCleanly) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--http-listen", "127.0.0.1:0", "--shutdown-grace-ms",
                                                 "200", "--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  const int metrics = testing::MetricsPort(server.log());
  ASSERT_NE(metrics, 0) << server.log();
  ASSERT_EQ(Post(server.http_port(), "CreateScene",
                 R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 8, "heightPx": 8})")
                .status,
            200);
  testing::HoldRenders hold(server);
  Reply written = Post(server.http_port(), "UpsertSites",
                       R"({"sceneId": "s", "sites": [{"id": "a", "point": {"x": 0.5, "y": 0.5}, "additiveWeight": 0.01}]})");
  ASSERT_EQ(written.status, 200) << written.body;
  const std::string version = JsonString(written.body, "version");
  std::thread waiting([&] {
    try {
      Post(server.http_port(), "FindNearest",
           R"({"sceneId": "s", "points": [{"x": 0.1, "y": 0.1}], "minVersion": ")" + version + R"("})");
    } catch (const std::exception&) {
      // The connection closed with the server: what a client sees of a call cut short.
    }
  });
  const std::string in_flight = "gvd_rpc_in_flight{method=\"FindNearest\"} 1";
  const std::string text = testing::WaitForMetric(metrics, in_flight, 120);
  EXPECT_NE(text.find(in_flight), std::string::npos) << text;
  server.Terminate();
  waiting.join();
  const int status = server.Wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.log();
}

// --http-io-timeout-ms: a connection that sends nothing, or stops halfway through a request,
// is closed once the limit has passed, and not before; one whose requests keep coming stays
// open past it, as does one whose call the core holds longer (the limit is the transport's,
// not the call's), and a stream that waits longer between its messages.
TEST(HttpIoTimeout, IdleAndStalledConnectionsCloseAndBusyOnesStayOpen) {
  constexpr auto kLimit = std::chrono::milliseconds(1000);
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--http-listen", "127.0.0.1:0", "--http-io-timeout-ms", "1000"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  const int port = server.http_port();
  net::io_context ioc;
  const tcp::endpoint at(net::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port));
  // Asynchronous reads throughout: Beast's expiry bounds only those.
  auto run = [&ioc] {
    ioc.restart();
    ioc.run();
  };

  const auto start = std::chrono::steady_clock::now();
  beast::tcp_stream idle(ioc), stalled(ioc);
  idle.connect(at);
  stalled.connect(at);
  net::write(stalled, net::buffer(std::string("POST /gvd.v1.VoronoiService/ListScenes HTTP/1.1\r\nHost: 1")));
  struct Ending {
    beast::error_code ec = net::error::would_block;
    std::chrono::steady_clock::duration after{};
  };
  Ending ends[2];
  char bytes[2];
  beast::tcp_stream* streams[2] = {&idle, &stalled};
  for (int i = 0; i < 2; ++i) {
    streams[i]->expires_after(std::chrono::seconds(30));
    streams[i]->async_read_some(net::buffer(&bytes[i], 1),
                                [&, i](beast::error_code ec, size_t) {
                                  ends[i] = {ec, std::chrono::steady_clock::now() - start};
                                });
  }
  run();
  for (const Ending& e : ends) {
    EXPECT_TRUE(e.ec == net::error::eof || e.ec == net::error::connection_reset) << e.ec.message();
    EXPECT_GE(e.after, kLimit);
  }

  // Requests on one connection for over twice the limit, each well within it.
  beast::tcp_stream busy(ioc);
  busy.connect(at);
  beast::flat_buffer buffer;
  const auto busy_start = std::chrono::steady_clock::now();
  for (int i = 0; i < 25; ++i) {
    http::request<http::string_body> req{http::verb::post, "/gvd.v1.VoronoiService/ListScenes", 11};
    req.set(http::field::host, "127.0.0.1");
    req.set(http::field::content_type, "application/json");
    req.body() = "{}";
    req.prepare_payload();
    http::write(busy, req);
    http::response<http::string_body> res;
    beast::error_code ec = net::error::would_block;
    busy.expires_after(std::chrono::seconds(30));
    http::async_read(busy, buffer, res, [&ec](beast::error_code e, size_t) { ec = e; });
    run();
    ASSERT_FALSE(ec) << "request " << i << ": " << ec.message();
    EXPECT_EQ(res.result_int(), 200) << res.body();
    std::this_thread::sleep_for(kLimit / 10);
  }
  EXPECT_GE(std::chrono::steady_clock::now() - busy_start, 2 * kLimit);

  // A call that waits for a render held past the limit is answered on its connection.
  ASSERT_EQ(Post(port, "CreateScene",
                 R"({"sceneId": "s", "window": {"maxX": 1, "maxY": 1}, "widthPx": 8, "heightPx": 8})")
                .status,
            200);
  std::optional<testing::HoldRenders> hold(std::in_place, server);
  // Weighted: the index does not answer in place of the frame (see min_version).
  Reply written = Post(port, "UpsertSites",
                       R"({"sceneId": "s", "sites": [{"id": "a", "point": {"x": 0.5, "y": 0.5}, "additiveWeight": 0.01}]})");
  ASSERT_EQ(written.status, 200) << written.body;
  const std::string version = JsonString(written.body, "version");
  auto waited = std::async(std::launch::async, [&] {
    return Post(port, "FindNearest", R"({"sceneId": "s", "points": [{"x": 0.1, "y": 0.1}], "minVersion": ")" +
                                         version + R"("})");
  });
  std::this_thread::sleep_for(kLimit * 3 / 2);
  hold.reset();
  const Reply answer = waited.get();
  EXPECT_EQ(answer.status, 200) << answer.body;
  EXPECT_EQ(JsonString(answer.body, "siteId"), "a") << answer.body;

  // A watch with nothing to tell, ended by its deadline at two and a half limits: framed
  // whole to its end (a connection closed under it fails the read).
  const auto watch_start = std::chrono::steady_clock::now();
  StreamReply watch = Stream(port, "WatchScene",
                             R"({"sceneId": "s", "afterVersion": ")" + version + R"("})",
                             {{"Connect-Timeout-Ms", "2500"}});
  EXPECT_GE(std::chrono::steady_clock::now() - watch_start, kLimit * 5 / 2);
  EXPECT_EQ(watch.status, 200);
  EXPECT_EQ(JsonString(watch.end, "code"), "deadline_exceeded") << watch.end;
  EXPECT_EQ(server.Stop(), 0) << server.log();
}

}  // namespace
}  // namespace gvd
