// TLS, client certificates, bearer tokens and the config file, against the real server.
#include <gtest/gtest.h>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include <fstream>
#include <sstream>

#include "grpc/health/v1/health.grpc.pb.h"
#include "gvd/client.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;

std::string Read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class SecurityTest : public ::testing::Test {
 protected:
  // A throwaway CA, a server certificate for 127.0.0.1 and a client certificate.
  static void SetUpTestSuite() {
    char dir_template[] = "/tmp/gvd-pki-XXXXXX";
    dir_ = new std::string(mkdtemp(dir_template));
    std::string d = *dir_;
    std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes ";
    std::string script =
        "cd " + d + " && exec >openssl.log 2>&1 && set -e && "
        "openssl req -x509" + ec + "-keyout ca.key -out ca.pem -days 2 -subj /CN=gvd-test-ca && "
        "openssl req" + ec + "-keyout server.key -out server.csr -subj /CN=localhost && "
        "printf 'subjectAltName=IP:127.0.0.1,DNS:localhost' > san.ext && "
        "openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
        "-out server.pem -days 2 -extfile san.ext && "
        "openssl req" + ec + "-keyout client.key -out client.csr -subj /CN=gvd-test-client && "
        "openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
        "-out client.pem -days 2";
    ok_ = std::system(("bash -c \"" + script + "\"").c_str()) == 0;
    std::ofstream(d + "/tokens") << "# role per token\nreader-token-0123456789 read\n"
                                 << "writer-token-0123456789 write\n";
    std::ofstream(d + "/gvd.conf") << "# a config file\n--tokens " << d << "/tokens\n";
  }
  static void TearDownTestSuite() {
    std::system(("rm -rf " + *dir_).c_str());
    delete dir_;
  }
  void SetUp() override {
    if (!ok_) GTEST_SKIP() << "openssl could not make test certificates: " << Read(*dir_ + "/openssl.log");
  }

  static grpc::Status ListScenes(const std::string& address, ClientOptions options) {
    options.timeout = std::chrono::milliseconds(3000);
    std::vector<v1::Scene> scenes;
    return Client::Connect(address, options)->ListScenes(&scenes);
  }
  static grpc::Status CreateScene(const std::string& address, ClientOptions options,
                                  const std::string& id) {
    v1::Scene scene;
    return Client::Connect(address, options)->CreateScene(testing::UnitScene(id, 8, 8), &scene);
  }

  static inline std::string* dir_ = nullptr;
  static inline bool ok_ = false;
};

TEST_F(SecurityTest, TokensGateReadsAndWrites) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--tokens", *dir_ + "/tokens"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ClientOptions none, reader, writer, wrong;
  reader.token = "reader-token-0123456789";
  writer.token = "writer-token-0123456789";
  wrong.token = "writer-token-0123456780";
  EXPECT_EQ(ListScenes(server.address(), none).error_code(), StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(ListScenes(server.address(), wrong).error_code(), StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(ListScenes(server.address(), reader).ok());
  grpc::Status denied = CreateScene(server.address(), reader, "r");
  EXPECT_EQ(denied.error_code(), StatusCode::PERMISSION_DENIED) << denied.error_message();
  EXPECT_TRUE(CreateScene(server.address(), writer, "w").ok());
  EXPECT_EQ(CreateScene(server.address(), none, "n").error_code(), StatusCode::UNAUTHENTICATED);
  // Only the writer's scene exists.
  std::vector<v1::Scene> scenes;
  ASSERT_TRUE(Client::Connect(server.address(), reader)->ListScenes(&scenes).ok());
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_EQ(scenes[0].scene_id(), "w");
  // Probes need no token.
  auto health = grpc::health::v1::Health::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext ctx;
  grpc::health::v1::HealthCheckRequest hr;
  grpc::health::v1::HealthCheckResponse hs;
  ASSERT_TRUE(health->Check(&ctx, hr, &hs).ok());
  EXPECT_EQ(hs.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

TEST_F(SecurityTest, TlsServesOnlyTlsClients) {
  const std::string d = *dir_;
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ClientOptions tls;
  tls.tls_ca = Read(d + "/ca.pem");
  EXPECT_TRUE(ListScenes(server.address(), tls).ok());
  EXPECT_FALSE(ListScenes(server.address(), ClientOptions{}).ok());  // plaintext refused
  ClientOptions untrusted;
  untrusted.tls_ca = Read(d + "/client.pem");  // not the CA that signed the server
  EXPECT_FALSE(ListScenes(server.address(), untrusted).ok());
}

TEST_F(SecurityTest, ClientCertificatesWhenRequired) {
  const std::string d = *dir_;
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key",
                                 "--tls-client-ca", d + "/ca.pem"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  ClientOptions anonymous;
  anonymous.tls_ca = Read(d + "/ca.pem");
  EXPECT_FALSE(ListScenes(server.address(), anonymous).ok());
  ClientOptions with_cert = anonymous;
  with_cert.tls_cert = Read(d + "/client.pem");
  with_cert.tls_key = Read(d + "/client.key");
  EXPECT_TRUE(ListScenes(server.address(), with_cert).ok());
}

TEST_F(SecurityTest, ConfigFileSetsFlags) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--config", *dir_ + "/gvd.conf"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  EXPECT_EQ(ListScenes(server.address(), ClientOptions{}).error_code(), StatusCode::UNAUTHENTICATED);
  ClientOptions reader;
  reader.token = "reader-token-0123456789";
  EXPECT_TRUE(ListScenes(server.address(), reader).ok());
  EXPECT_NE(server.log().find("event=security tls=off client_certificates=\"not required\" tokens=2"),
            std::string::npos)
      << server.log();
}

// An API port beyond loopback, where anyone who reaches it could write, is served only with
// tokens or client certificates, or when --allow-unauthenticated says so; loopback and Unix
// sockets need neither.
TEST_F(SecurityTest, BeyondLoopbackTheApiNeedsAuthenticationOrAnExplicitFlag) {
  const std::string d = *dir_;
  const std::vector<std::vector<std::string>> open = {
      {"--listen", "0.0.0.0:0"},
      {"--listen", "[::]:0"},
      {"--http-listen", "0.0.0.0:0"},
      {"--listen", "127.0.0.1:0", "--http-listen", "[::]:0"},
  };
  for (const auto& flags : open) {
    testing::ServerProcess server(GVD_SERVER_PATH, flags);
    EXPECT_NE(server.error().find(" reaches beyond loopback, where anyone who reaches it could "
                                  "write: give --tokens FILE (or --tls-client-ca), or "
                                  "--allow-unauthenticated"),
              std::string::npos)
        << flags[1] << ": " << server.error();
  }
  // Served: with tokens, whose absence refuses a write; with client certificates; on
  // purpose; and on loopback or a Unix socket without anything.
  {
    testing::ServerProcess server(GVD_SERVER_PATH, {"--listen", "0.0.0.0:0", "--tokens", d + "/tokens"});
    ASSERT_TRUE(server.error().empty()) << server.error();
    EXPECT_EQ(CreateScene(server.address(), ClientOptions{}, "open").error_code(),
              StatusCode::UNAUTHENTICATED);
  }
  const std::vector<std::vector<std::string>> served = {
      {"--listen", "0.0.0.0:0", "--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key",
       "--tls-client-ca", d + "/ca.pem"},
      {"--listen", "0.0.0.0:0", "--http-listen", "0.0.0.0:0", "--allow-unauthenticated"},
      {"--listen", "localhost:0", "--http-listen", "127.0.0.2:0"},
      {"--listen", "unix:" + d + "/gvd.sock"},
  };
  for (const auto& flags : served) {
    testing::ServerProcess server(GVD_SERVER_PATH, flags);
    EXPECT_TRUE(server.error().empty()) << flags[1] << ": " << server.error();
  }
}

TEST_F(SecurityTest, CliCarriesTokenAndTls) {
  const std::string d = *dir_;
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key",
                                 "--tokens", d + "/tokens"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  std::string base = std::string(GVD_CLI_PATH) + " --server " + server.address() + " --tls-ca " +
                     d + "/ca.pem ";
  EXPECT_EQ(WEXITSTATUS(std::system((base + "scene ls >/dev/null 2>&1").c_str())), 1);
  EXPECT_EQ(WEXITSTATUS(std::system(
                (base + "--token writer-token-0123456789 scene create cli --window 0,0,1,1 "
                        "--size 8x8 >/dev/null 2>&1").c_str())),
            0);
}

}  // namespace
}  // namespace gvd
