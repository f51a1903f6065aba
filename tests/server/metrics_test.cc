// /metrics on its own port, scraped as Prometheus would, after calls whose counts are known.
#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <thread>

#include <grpcpp/create_channel.h>

#include "gvd/client.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

// A server with its metrics listener, the listener's port, a client, and a raw stub for
// calls the client does not make (contexts cancelled midway).
struct Metered {
  testing::ServerProcess server{GVD_SERVER_PATH, {"--metrics-listen", "127.0.0.1:0"}};
  int port = testing::MetricsPort(server.log());
  std::unique_ptr<Client> client = Client::Connect(server.address());
  std::unique_ptr<v1::VoronoiService::Stub> stub = v1::VoronoiService::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
};

::testing::AssertionResult Started(const Metered& m) {
  if (!m.server.error().empty()) return ::testing::AssertionFailure() << m.server.error();
  if (m.port == 0) return ::testing::AssertionFailure() << "no metrics port: " << m.server.log();
  return ::testing::AssertionSuccess();
}

// Scene "s", 64 x 64 pixels, of side x side points on a grid, with additive weights
// 1e-3 (i % 7) when `weighted`.
void GridScene(Client& client, int side, bool weighted) {
  v1::Scene scene;
  ASSERT_TRUE(client.CreateScene(testing::UnitScene("s", 64, 64), &scene).ok());
  v1::UpsertSitesRequest u;
  u.set_scene_id("s");
  for (int i = 0; i < side * side; ++i) {
    auto* s = u.add_sites();
    s->set_id(std::to_string(i));
    s->mutable_point()->set_x((i % side + 0.5) / side);
    s->mutable_point()->set_y((i / side + 0.5) / side);
    if (weighted) s->set_additive_weight(1e-3 * (i % 7));
  }
  uint64_t v;
  ASSERT_TRUE(client.UpsertSites(u, &v).ok());
}

TEST(MetricsTest, ScrapeShowsCallsRendersCommitsAndScenes) {
  Metered m;
  ASSERT_TRUE(Started(m));
  const int port = m.port;
  auto& client = m.client;
  // A FARTHEST diagram is drawn as meshes on every device, so its full render reports a fill.
  v1::CreateSceneRequest c = testing::UnitScene("metered", 64, 64);
  c.set_diagram(v1::DIAGRAM_FARTHEST);
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(c, &scene).ok());
  EXPECT_EQ(client->CreateScene(c, &scene).error_code(), grpc::StatusCode::ALREADY_EXISTS);
  v1::UpsertSitesRequest u;
  u.set_scene_id("metered");
  for (int i = 0; i < 3; ++i) {
    auto* s = u.add_sites();
    s->set_id(std::to_string(i));
    s->mutable_point()->set_x(0.2 * (i + 1));
    s->mutable_point()->set_y(0.5);
  }
  uint64_t v;
  ASSERT_TRUE(client->UpsertSites(u, &v).ok());
  v1::FindNearestRequest q;
  q.set_scene_id("metered");
  q.set_min_version(v);
  q.add_points();
  v1::FindNearestResponse r;
  ASSERT_TRUE(client->FindNearest(q, &r).ok());

  std::string text = testing::Scrape(port);
  ASSERT_FALSE(text.empty());
  for (const char* want : {
           "gvd_rpc_total{code=\"OK\",method=\"CreateScene\"} 1",
           "gvd_rpc_total{code=\"ALREADY_EXISTS\",method=\"CreateScene\"} 1",
           "gvd_rpc_total{code=\"OK\",method=\"UpsertSites\"} 1",
           "gvd_rpc_total{code=\"OK\",method=\"FindNearest\"} 1",
           "gvd_rpc_duration_seconds_count{method=\"FindNearest\"} 1",
           "gvd_render_seconds_count{kind=\"full\"} 1",
           "gvd_render_fill_ratio_count{kind=\"full\"} 1",
           "gvd_store_commit_seconds_count 2",  // the scene, then the sites
           "gvd_scene_sites{scene=\"metered\"} 3",
           "gvd_scene_version_lag{scene=\"metered\"} 0",
           "gvd_scene_frame_age_seconds{scene=\"metered\"}",
       }) {
    EXPECT_NE(text.find(want), std::string::npos) << "missing: " << want << "\n" << text;
  }
  // The full render's meshes reach every pixel centre, so together they cover at least the
  // square through the outermost centres: (63/64)^2 of the window.
  std::smatch fill;
  ASSERT_TRUE(std::regex_search(text, fill,
                                std::regex("gvd_render_fill_ratio_sum\\{kind=\"full\"\\} (\\S+)")))
      << text;
  EXPECT_GE(std::stod(fill[1]), (63.0 / 64) * (63.0 / 64));

  // An EXACT nearest diagram's first render is computed: it reports its candidates per pixel
  // instead, at least one (every pixel centre scans the site nearest to it).
  c = testing::UnitScene("computed", 64, 64);
  c.set_render_mode(v1::RENDER_MODE_EXACT);
  ASSERT_TRUE(client->CreateScene(c, &scene).ok());
  u.set_scene_id("computed");
  ASSERT_TRUE(client->UpsertSites(u, &v).ok());
  ASSERT_TRUE(testing::WaitForRender(*client, "computed", v));
  text = testing::Scrape(port);
  for (const char* want : {"gvd_render_seconds_count{kind=\"full\"} 2",
                           "gvd_render_fill_ratio_count{kind=\"full\"} 1",
                           "gvd_render_candidates_per_pixel_count{kind=\"full\"} 1"}) {
    EXPECT_NE(text.find(want), std::string::npos) << "missing: " << want << "\n" << text;
  }
  std::smatch candidates;
  ASSERT_TRUE(std::regex_search(
      text, candidates,
      std::regex("gvd_render_candidates_per_pixel_sum\\{kind=\"full\"\\} (\\S+)")))
      << text;
  EXPECT_GE(std::stod(candidates[1]), 1.0);
}

// A query cancelled while it computes stops there: the server records it as cancelled
// instead of finishing hours of work for nobody. (A deadline that passes cancels the same
// way; the client cancels here so that the call is certain to have started first, however
// slow the machine.)
TEST(MetricsTest, CancelledBatchesStopWorking) {
  Metered m;
  ASSERT_TRUE(Started(m));
  const int port = m.port;
  // Sites: 10,000 weighted points, so an exact answer scores every one of them.
  GridScene(*m.client, 100, true);
  if (::testing::Test::HasFatalFailure()) return;
  // A million points: 1e10 site evaluations, minutes of work on a few cores.
  v1::FindNearestRequest q;
  q.set_scene_id("s");
  q.set_exact(true);
  for (int i = 0; i < 1000000; ++i) {
    q.add_xy((i % 1000) / 1000.0);
    q.add_xy((i / 1000) / 1000.0);
  }
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(10));
  v1::FindNearestResponse r;
  grpc::Status status;
  std::thread call([&] { status = m.stub->FindNearest(&ctx, q, &r); });
  std::string text = testing::WaitForMetric(port, "gvd_rpc_in_flight{method=\"FindNearest\"} 1", 120);
  EXPECT_NE(text.find("gvd_rpc_in_flight{method=\"FindNearest\"} 1"), std::string::npos) << text;
  ctx.TryCancel();
  call.join();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED) << status.error_message();
  // The server notices within about a million site evaluations.
  const std::string cancelled = "gvd_rpc_total{code=\"CANCELLED\",method=\"FindNearest\"} 1";
  text = testing::WaitForMetric(port, cancelled, 60);
  EXPECT_NE(text.find(cancelled), std::string::npos) << text;
  text = testing::WaitForMetric(port, "gvd_rpc_in_flight{method=\"FindNearest\"} 0", 60);
  EXPECT_NE(text.find("gvd_rpc_in_flight{method=\"FindNearest\"} 0"), std::string::npos) << text;
}

// A stream whose client goes after a few of its many chunks: the call ends CANCELLED, the
// server lets it go (none in flight) as its write fails, and answers the next call.
TEST(MetricsTest, AStreamLeftMidwayEnds) {
  Metered m;
  ASSERT_TRUE(Started(m));
  const int port = m.port;
  auto& client = m.client;
  GridScene(*client, 10, false);
  if (::testing::Test::HasFatalFailure()) return;
  v1::FindNearestRequest q;
  q.set_scene_id("s");
  for (int i = 0; i < 200000; ++i) {
    q.add_xy((i % 1000) / 1000.0);
    q.add_xy((i / 1000) / 200.0);
  }
  grpc::ClientContext ctx;
  auto reader = m.stub->FindNearestStream(&ctx, testing::StreamOf(q, 64));
  v1::FindNearestStreamResponse chunk;
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE(reader->Read(&chunk));
    EXPECT_EQ(chunk.offset(), 64u * k);
    EXPECT_EQ(chunk.packed().distance_size(), 64);
  }
  ctx.TryCancel();
  while (reader->Read(&chunk)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  const std::string ended = "gvd_rpc_in_flight{method=\"FindNearestStream\"} 0";
  std::string text = testing::WaitForMetric(port, ended, 60);
  EXPECT_NE(text.find(ended), std::string::npos) << text;
  v1::FindNearestResponse r;
  q.mutable_xy()->Truncate(2);
  ASSERT_TRUE(client->FindNearest(q, &r).ok());
  EXPECT_EQ(r.packed().distance_size(), 1);
}

}  // namespace
}  // namespace gvd
