// The gRPC port beside the service's methods, against the real server: server reflection
// describes the services as their .proto files declare them (read here from the source tree),
// the health service's Watch follows the server from serving to its drain, a call of no
// method or with bytes that are no request is refused by name, and a large request is parsed
// off the thread that serves every other call.
#include <gtest/gtest.h>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/descriptor_database.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <future>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "gvd/v1/voronoi.grpc.pb.h"
#include "tests/support/server_process.h"

namespace gvd {
namespace {

namespace reflection = grpc::reflection::v1alpha;
using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

std::shared_ptr<grpc::Channel> Channel(const testing::ServerProcess& server) {
  return grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());
}

void Deadline(grpc::ClientContext* ctx, int seconds = 60) {
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(seconds));
}

// A method as a .proto file declares it: its request and response types as written there,
// and which of them stream.
struct Declared {
  std::string input, output;
  bool client_streaming = false, server_streaming = false;
  bool operator==(const Declared&) const = default;
};
std::ostream& operator<<(std::ostream& os, const Declared& d) {
  return os << (d.client_streaming ? "stream " : "") << d.input << " -> "
            << (d.server_streaming ? "stream " : "") << d.output;
}

// The methods of `service` in the .proto file at `path`, read from its text.
std::map<std::string, Declared> MethodsInFile(const std::string& path, const std::string& service) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string all = text.str();
  const size_t begin = all.find("service " + service + " {");
  EXPECT_NE(begin, std::string::npos) << path;
  const std::string body = all.substr(begin, all.find("\n}", begin) - begin);
  static const std::regex rpc(
      R"(rpc\s+(\w+)\s*\(\s*(stream\s+)?([\w.]+)\s*\)\s*returns\s*\(\s*(stream\s+)?([\w.]+)\s*\))");
  std::map<std::string, Declared> methods;
  for (std::sregex_iterator it(body.begin(), body.end(), rpc), end; it != end; ++it) {
    methods[(*it)[1]] = {(*it)[3], (*it)[5], (*it)[2].matched, (*it)[4].matched};
  }
  return methods;
}

// The methods of the service named `full_name` as a descriptor built from reflected files
// has them, their types as the file's package writes them.
std::map<std::string, Declared> MethodsReflected(const google::protobuf::ServiceDescriptor& s) {
  const std::string package = s.file()->package() + ".";
  auto local = [&package](const std::string& name) {
    return name.rfind(package, 0) == 0 ? name.substr(package.size()) : name;
  };
  std::map<std::string, Declared> methods;
  for (int i = 0; i < s.method_count(); ++i) {
    const auto* m = s.method(i);
    methods[m->name()] = {local(m->input_type()->full_name()),
                          local(m->output_type()->full_name()), m->client_streaming(),
                          m->server_streaming()};
  }
  return methods;
}

TEST(GrpcPort, ReflectionDescribesEachServiceAsItsProtoFileDeclaresIt) {
  testing::ServerProcess server(GVD_SERVER_PATH);
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto stub = reflection::ServerReflection::NewStub(Channel(server));
  grpc::ClientContext ctx;
  Deadline(&ctx);
  auto stream = stub->ServerReflectionInfo(&ctx);
  auto ask = [&stream](const reflection::ServerReflectionRequest& request) {
    reflection::ServerReflectionResponse response;
    EXPECT_TRUE(stream->Write(request));
    EXPECT_TRUE(stream->Read(&response));
    return response;
  };

  reflection::ServerReflectionRequest list;
  list.set_list_services("");
  const auto listed = ask(list);
  std::set<std::string> services;
  for (const auto& s : listed.list_services_response().service()) services.insert(s.name());
  EXPECT_EQ(services, (std::set<std::string>{"gvd.v1.VoronoiService", "grpc.health.v1.Health",
                                             "grpc.reflection.v1alpha.ServerReflection"}));

  // Each service's file, with what it imports, makes a pool of its own whose service has
  // the methods its .proto file in the source tree declares.
  const std::map<std::string, std::string> files = {
      {"gvd.v1.VoronoiService", "gvd/v1/voronoi.proto"},
      {"grpc.health.v1.Health", "grpc/health/v1/health.proto"},
      {"grpc.reflection.v1alpha.ServerReflection", "grpc/reflection/v1alpha/reflection.proto"}};
  for (const auto& [service, file] : files) {
    reflection::ServerReflectionRequest symbol;
    symbol.set_file_containing_symbol(service);
    const auto answer = ask(symbol);
    ASSERT_TRUE(answer.has_file_descriptor_response()) << answer.DebugString();
    google::protobuf::SimpleDescriptorDatabase db;
    std::set<std::string> names;
    for (const std::string& bytes : answer.file_descriptor_response().file_descriptor_proto()) {
      google::protobuf::FileDescriptorProto proto;
      ASSERT_TRUE(proto.ParseFromString(bytes));
      names.insert(proto.name());
      ASSERT_TRUE(db.Add(proto)) << proto.name();
    }
    EXPECT_TRUE(names.count(file)) << service;
    google::protobuf::DescriptorPool pool(&db);
    const auto* described = pool.FindServiceByName(service);
    ASSERT_NE(described, nullptr) << service;
    const std::string short_name = service.substr(service.rfind('.') + 1);
    const auto declared = MethodsInFile(std::string(GVD_PROTO_DIR) + "/" + file, short_name);
    EXPECT_FALSE(declared.empty()) << file;
    EXPECT_EQ(MethodsReflected(*described), declared) << service;

    // The same file by its name.
    reflection::ServerReflectionRequest by_name;
    by_name.set_file_by_filename(file);
    const auto again = ask(by_name);
    ASSERT_TRUE(again.has_file_descriptor_response()) << again.DebugString();
    google::protobuf::FileDescriptorProto first;
    ASSERT_TRUE(first.ParseFromString(again.file_descriptor_response().file_descriptor_proto(0)));
    EXPECT_EQ(first.name(), file);
  }

  // What is not there, by name.
  reflection::ServerReflectionRequest missing;
  missing.set_file_by_filename("no/such.proto");
  auto refused = ask(missing);
  EXPECT_EQ(refused.error_response().error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_NE(refused.error_response().error_message().find("no/such.proto"), std::string::npos);
  missing.set_file_containing_symbol("gvd.v1.NoSuchThing");
  refused = ask(missing);
  EXPECT_EQ(refused.error_response().error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(refused.original_request().file_containing_symbol(), "gvd.v1.NoSuchThing");

  ASSERT_TRUE(stream->WritesDone());
  const grpc::Status end = stream->Finish();
  EXPECT_TRUE(end.ok()) << end.error_message();
}

TEST(GrpcPort, HealthWatchFollowsTheServerToItsDrain) {
  testing::ServerProcess server(GVD_SERVER_PATH);
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto stub = grpc::health::v1::Health::NewStub(Channel(server));
  // Check: the server as a whole and "liveness" serve; a name it does not know, NOT_FOUND.
  for (const char* name : {"", "liveness"}) {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    HealthCheckRequest request;
    request.set_service(name);
    HealthCheckResponse response;
    ASSERT_TRUE(stub->Check(&ctx, request, &response).ok()) << name;
    EXPECT_EQ(response.status(), HealthCheckResponse::SERVING) << name;
  }
  {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    HealthCheckRequest request;
    request.set_service("nope");
    HealthCheckResponse response;
    EXPECT_EQ(stub->Check(&ctx, request, &response).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  // Watch: a name it does not know is SERVICE_UNKNOWN, and the stream goes on.
  grpc::ClientContext unknown_ctx;
  Deadline(&unknown_ctx);
  HealthCheckRequest unknown;
  unknown.set_service("nope");
  auto unknown_watch = stub->Watch(&unknown_ctx, unknown);
  HealthCheckResponse seen;
  ASSERT_TRUE(unknown_watch->Read(&seen));
  EXPECT_EQ(seen.status(), HealthCheckResponse::SERVICE_UNKNOWN);
  unknown_ctx.TryCancel();
  // The server as a whole: SERVING, then NOT_SERVING once it is told to stop, then the end.
  grpc::ClientContext ctx;
  Deadline(&ctx);
  auto watch = stub->Watch(&ctx, HealthCheckRequest());
  ASSERT_TRUE(watch->Read(&seen));
  EXPECT_EQ(seen.status(), HealthCheckResponse::SERVING);
  auto stopped = std::async(std::launch::async, [&server] { return server.Stop(); });
  ASSERT_TRUE(watch->Read(&seen));
  EXPECT_EQ(seen.status(), HealthCheckResponse::NOT_SERVING);
  EXPECT_FALSE(watch->Read(&seen));
  EXPECT_FALSE(watch->Finish().ok());
  const int status = stopped.get();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.log();
}

TEST(GrpcPort, NoMethodAndNoRequestAreRefusedByName) {
  testing::ServerProcess server(GVD_SERVER_PATH);
  ASSERT_TRUE(server.error().empty()) << server.error();
  grpc::GenericStub stub(Channel(server));
  auto call = [&stub](const std::string& method, const std::string& bytes) {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    grpc::Slice slice(bytes);
    grpc::ByteBuffer request(&slice, 1), response;
    std::promise<grpc::Status> done;
    stub.UnaryCall(&ctx, method, grpc::StubOptions(), &request, &response,
                   [&done](grpc::Status s) { done.set_value(s); });
    return done.get_future().get();
  };
  grpc::Status s = call("/gvd.v1.VoronoiService/NoSuchMethod", "");
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED);
  EXPECT_NE(s.error_message().find("/gvd.v1.VoronoiService/NoSuchMethod"), std::string::npos)
      << s.error_message();
  s = call("/other.Service/Method", "");
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED);
  // A field 1 (scene_id) whose length runs past the end.
  s = call("/gvd.v1.VoronoiService/FindNearest", std::string("\x0a\x7f\x01", 3));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("gvd.v1.FindNearestRequest"), std::string::npos)
      << s.error_message();
  // An empty message is a request (every field at its default): the core refuses it.
  s = call("/gvd.v1.VoronoiService/FindNearest", "");
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("scene_id"), std::string::npos) << s.error_message();
}

// While a large request is held in its conversion (the test hook), a small call is answered,
// and the held call's answer is whole once it goes on.
TEST(GrpcPort, ALargeRequestHoldsUpNoOtherCall) {
  testing::ServerProcess server(GVD_SERVER_PATH);
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto stub = v1::VoronoiService::NewStub(Channel(server));
  {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    v1::CreateSceneRequest create;
    create.set_scene_id("s");
    create.mutable_window()->set_max_x(1);
    create.mutable_window()->set_max_y(1);
    create.set_width_px(64);
    create.set_height_px(64);
    v1::CreateSceneResponse created;
    ASSERT_TRUE(stub->CreateScene(&ctx, create, &created).ok());
  }
  {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    v1::UpsertSitesRequest upsert;
    upsert.set_scene_id("s");
    auto* a = upsert.add_sites();
    a->set_id("a");
    a->mutable_point()->set_x(0.25);
    a->mutable_point()->set_y(0.25);
    auto* b = upsert.add_sites();
    b->set_id("b");
    b->mutable_point()->set_x(0.75);
    b->mutable_point()->set_y(0.75);
    v1::UpsertSitesResponse upserted;
    ASSERT_TRUE(stub->UpsertSites(&ctx, upsert, &upserted).ok());
  }
  // 6,000 points, some 120 KB.
  v1::FindNearestRequest big;
  big.set_scene_id("s");
  for (int k = 0; k < 6000; ++k) {
    auto* p = big.add_points();
    p->set_x(0.1 + k * 1e-6);
    p->set_y(0.2);
  }
  ASSERT_GT(big.ByteSizeLong(), size_t{64} << 10);
  const std::string hold = server.hold_conversions_path();
  std::ofstream(hold).put('x');
  v1::FindNearestResponse found;
  grpc::Status big_status;
  std::thread caller([&] {
    grpc::ClientContext ctx;
    Deadline(&ctx, 120);
    big_status = stub->FindNearest(&ctx, big, &found);
  });
  EXPECT_TRUE(testing::WaitForFile(hold + ".waiting")) << "no conversion was held";
  auto small = std::async(std::launch::async, [&stub] {
    grpc::ClientContext ctx;
    Deadline(&ctx);
    v1::ListScenesResponse scenes;
    return stub->ListScenes(&ctx, v1::ListScenesRequest(), &scenes);
  });
  EXPECT_EQ(small.wait_for(std::chrono::minutes(1)), std::future_status::ready)
      << "a small call waited for another call's conversion";
  std::remove(hold.c_str());
  EXPECT_TRUE(small.get().ok());
  caller.join();
  ASSERT_TRUE(big_status.ok()) << big_status.error_message();
  ASSERT_EQ(found.results_size(), 6000);
  for (int k = 0; k < 6000; ++k) {
    const auto& r = found.results(k);
    ASSERT_EQ(r.site_id(), "a") << k;
    const double exact = std::hypot(0.25 - (0.1 + k * 1e-6), 0.25 - 0.2);
    ASSERT_LE(std::abs(r.distance() - exact), r.error_bound() + 1e-12) << k;
  }
}

}  // namespace
}  // namespace gvd
