// Integration tests: the real gvd-server on a loopback port, driven through the client
// library, answers checked against the exact oracle.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "gvd/client.h"
#include "render/kernel/exact2.h"
#include "tests/support/pixel_oracle.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;

class ServerTest : public testing::SharedServerTest {
 protected:
  static v1::Scene Create(const std::string& id, Window w, uint32_t width, uint32_t height,
                          double max_error = 0, v1::RenderMode mode = v1::RENDER_MODE_MESH) {
    v1::CreateSceneRequest r;
    r.set_scene_id(id);
    r.mutable_window()->set_min_x(w.min_x);
    r.mutable_window()->set_min_y(w.min_y);
    r.mutable_window()->set_max_x(w.max_x);
    r.mutable_window()->set_max_y(w.max_y);
    r.set_width_px(width);
    r.set_height_px(height);
    r.set_max_error(max_error);
    r.set_render_mode(mode);
    v1::Scene scene;
    grpc::Status s = client_->CreateScene(r, &scene);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return scene;
  }

  static uint64_t Upsert(const std::string& scene, const std::vector<Site>& sites) {
    v1::UpsertSitesRequest r;
    r.set_scene_id(scene);
    for (const Site& s : sites) *r.add_sites() = testing::ToProtoSite(s);
    uint64_t version = 0;
    grpc::Status s = client_->UpsertSites(r, &version);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return version;
  }

  static v1::FindNearestResponse Nearest(const std::string& scene, const std::vector<Vec2>& points,
                                         uint64_t min_version) {
    v1::FindNearestRequest r;
    r.set_scene_id(scene);
    r.set_min_version(min_version);
    for (Vec2 p : points) {
      auto* q = r.add_points();
      q->set_x(p.x);
      q->set_y(p.y);
    }
    v1::FindNearestResponse response;
    grpc::Status s = client_->FindNearest(r, &response);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return response;
  }

  // The API's contract for one answer, against the oracle over `sites`.
  static void ExpectContract(const std::vector<Site>& sites, Vec2 q, const v1::NearestSite& n) {
    auto it = std::find_if(sites.begin(), sites.end(), [&](const Site& s) { return s.id == n.site_id(); });
    ASSERT_NE(it, sites.end()) << "unknown site " << n.site_id();
    const double tolerance = oracle::Tolerance(q, n.distance()) + oracle::CurveRounding(n.distance(), *it);
    EXPECT_NEAR(n.distance(), oracle::Distance(q, it->geometry), tolerance) << n.site_id();
    EXPECT_TRUE(testing::IsNearestFeature(q, it->geometry, n.feature_kind(), n.feature_index()))
        << n.site_id() << " feature " << n.feature_kind() << " " << n.feature_index();
    oracle::Best truth = oracle::BestSite(q, sites);
    EXPECT_GE(truth.value + tolerance, n.distance() - n.error_bound())
        << "q=(" << q.x << "," << q.y << ") got " << n.site_id() << " truth "
        << sites[truth.index].id;
    EXPECT_GE(n.error_bound(), 0);
  }

  static std::vector<Site> RandomSites(size_t n, const Window& w, uint64_t seed,
                                       const std::string& prefix = "s") {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
    std::vector<Site> sites;
    for (size_t i = 0; i < n; ++i) {
      sites.push_back({prefix + std::to_string(i), PointSite{{ux(rng), uy(rng)}}});
    }
    return sites;
  }

};

TEST_F(ServerTest, SceneLifecycle) {
  v1::Scene s = Create("life", {0, 0, 100, 50}, 1024, 512);
  EXPECT_EQ(s.scene_id(), "life");
  EXPECT_EQ(s.window().max_x(), 100);
  EXPECT_EQ(s.width_px(), 1024u);
  EXPECT_EQ(s.height_px(), 512u);
  EXPECT_DOUBLE_EQ(s.max_error(), 100.0 / 1024);  // 0 means one pixel
  EXPECT_EQ(s.version(), 1u);
  EXPECT_EQ(s.site_count(), 0u);
  // Square pixels on a 1024-wide grid whose diagonal is shorter than 1024 x 1024's: at most 85.
  EXPECT_LE(s.cone_triangles(), 85u);

  v1::Scene got;
  ASSERT_TRUE(client_->GetScene("life", &got).ok());
  EXPECT_EQ(got.SerializeAsString(), s.SerializeAsString());
  std::vector<v1::Scene> all;
  ASSERT_TRUE(client_->ListScenes(&all).ok());
  EXPECT_TRUE(std::any_of(all.begin(), all.end(), [](auto& x) { return x.scene_id() == "life"; }));

  ASSERT_TRUE(client_->DeleteScene("life").ok());
  EXPECT_EQ(client_->GetScene("life", &got).error_code(), StatusCode::NOT_FOUND);
  EXPECT_EQ(client_->DeleteScene("life").error_code(), StatusCode::NOT_FOUND);
}

TEST_F(ServerTest, TenThousandRandomSitesAnswerWithinTheirBound) {
  for (v1::RenderMode mode : {v1::RENDER_MODE_MESH, v1::RENDER_MODE_EXACT}) {
  const std::string name = mode == v1::RENDER_MODE_MESH ? "random10k" : "random10k-exact";
  Window w{-50, 20, 150, 220};
  v1::Scene scene = Create(name, w, 384, 384, 0, mode);
  EXPECT_EQ(scene.render_mode(), mode);
  auto sites = RandomSites(10000, w, 42);
  // In two requests, so the second upsert also exercises replacement-free growth.
  uint64_t v1 = Upsert(name, {sites.begin(), sites.begin() + 5000});
  uint64_t v2 = Upsert(name, {sites.begin() + 5000, sites.end()});
  EXPECT_EQ(v2, v1 + 1);

  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
  std::vector<Vec2> queries;
  for (int i = 0; i < 10000; ++i) queries.push_back({ux(rng), uy(rng)});
  queries.push_back({w.min_x, w.min_y});  // the window's corners are inside it
  queries.push_back({w.max_x, w.max_y});
  auto response = Nearest(name, queries, v2);
  ASSERT_EQ(response.results_size(), int(queries.size()));
  EXPECT_GE(response.version(), v2);
  double pixel_diagonal = std::hypot(200.0 / 384, 200.0 / 384);
  double worst = 0;
  for (size_t i = 0; i < queries.size(); ++i) {
    ExpectContract(sites, queries[i], response.results(i));
    worst = std::max(worst, response.results(i).error_bound());
  }
  // The bound stays near the sampling resolution: a pixel diagonal plus twice the meshes' eps.
  EXPECT_LE(worst, pixel_diagonal + 2 * scene.max_error());
  }
}

TEST_F(ServerTest, TiesAndCoincidentSites) {
  // Sites: four corners of a square around (50, 50), and two sites at one point.
  Window w{0, 0, 100, 100};
  Create("ties", w, 200, 200);
  std::vector<Site> sites = {{"a", PointSite{{40, 40}}}, {"b", PointSite{{60, 40}}},
                             {"c", PointSite{{40, 60}}}, {"d", PointSite{{60, 60}}},
                             {"e", PointSite{{10, 90}}}, {"f", PointSite{{10, 90}}}};
  uint64_t v = Upsert("ties", sites);
  std::vector<Vec2> q = {{50, 50}, {50, 40}, {10, 90}, {10.2, 89.9}, {0, 100}};
  auto r = Nearest("ties", q, v);
  for (size_t i = 0; i < q.size(); ++i) ExpectContract(sites, q[i], r.results(i));
  // At the centre all four are at distance sqrt(200); whichever is named, it is exact.
  EXPECT_DOUBLE_EQ(r.results(0).distance(), std::sqrt(200.0));
  EXPECT_TRUE(r.results(2).site_id() == "e" || r.results(2).site_id() == "f");
  EXPECT_EQ(r.results(2).distance(), 0);
}

TEST_F(ServerTest, UpsertReplacesAndDeleteRemoves) {
  Window w{0, 0, 10, 10};
  Create("moves", w, 128, 128);
  uint64_t v = Upsert("moves", {{"a", PointSite{{1, 1}}}, {"b", PointSite{{9, 9}}}});
  // (2, 6) is 5.10 from a and 7.62 from b; once a moves to (9.5, 0.5) it is 9.30 from a.
  EXPECT_EQ(Nearest("moves", {{2, 6}}, v).results(0).site_id(), "a");
  v = Upsert("moves", {{"a", PointSite{{9.5, 0.5}}}});
  auto r = Nearest("moves", {{2, 6}, {9, 1}}, v);
  EXPECT_EQ(r.results(0).site_id(), "b");
  EXPECT_EQ(r.results(1).site_id(), "a");
  EXPECT_DOUBLE_EQ(r.results(1).distance(), std::hypot(0.5, 0.5));
  v1::Scene s;
  ASSERT_TRUE(client_->GetScene("moves", &s).ok());
  EXPECT_EQ(s.site_count(), 2u);

  ASSERT_TRUE(client_->DeleteSites("moves", {"b"}, &v).ok());
  r = Nearest("moves", {{2, 2}}, v);
  EXPECT_EQ(r.results(0).site_id(), "a");
  std::vector<v1::Site> listed;
  ASSERT_TRUE(client_->ListAllSites("moves", &listed).ok());
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].id(), "a");
  EXPECT_EQ(listed[0].point().x(), 9.5);

  // Deleting every site leaves a scene that refuses queries until it has sites again.
  ASSERT_TRUE(client_->DeleteSites("moves", {"a"}, &v).ok());
  v1::FindNearestRequest q;
  q.set_scene_id("moves");
  q.set_min_version(v);
  q.add_points()->set_x(1);
  v1::FindNearestResponse response;
  EXPECT_EQ(client_->FindNearest(q, &response).error_code(), StatusCode::FAILED_PRECONDITION);
}

TEST_F(ServerTest, ListSitesPagesInIdOrder) {
  Create("pages", {0, 0, 1, 1}, 16, 16);
  auto sites = RandomSites(25, {0, 0, 1, 1}, 3, "id");
  Upsert("pages", sites);
  v1::ListSitesRequest r;
  r.set_scene_id("pages");
  r.set_page_size(10);
  std::vector<std::string> ids;
  int pages = 0;
  while (true) {
    v1::ListSitesResponse page;
    ASSERT_TRUE(client_->ListSites(r, &page).ok());
    ++pages;
    for (auto& s : page.sites()) ids.push_back(s.id());
    if (page.next_page_token().empty()) break;
    r.set_page_token(page.next_page_token());
  }
  EXPECT_EQ(pages, 3);
  ASSERT_EQ(ids.size(), 25u);
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
  EXPECT_EQ(std::set<std::string>(ids.begin(), ids.end()).size(), 25u);
}

// Each bad input is refused with its code and a message naming the field and the value,
// and changes nothing.
TEST_F(ServerTest, BadInputIsRefusedAndChangesNothing) {
  Create("guarded", {0, 0, 10, 10}, 64, 64);
  uint64_t v = Upsert("guarded", {{"keep", PointSite{{5, 5}}}});
  auto state = [] {
    v1::Scene s;
    EXPECT_TRUE(client_->GetScene("guarded", &s).ok());
    std::vector<v1::Site> sites;
    EXPECT_TRUE(client_->ListAllSites("guarded", &sites).ok());
    std::string all = std::to_string(s.version()) + "/" + std::to_string(s.site_count());
    for (auto& site : sites) all += "/" + site.SerializeAsString();
    return all;
  };
  const std::string before = state();

  auto create = [](std::function<void(v1::CreateSceneRequest&)> edit) {
    v1::CreateSceneRequest r;
    r.set_scene_id("fresh");
    r.mutable_window()->set_max_x(1);
    r.mutable_window()->set_max_y(1);
    r.set_width_px(8);
    r.set_height_px(8);
    edit(r);
    v1::Scene s;
    return client_->CreateScene(r, &s);
  };
  auto upsert = [](std::function<void(v1::UpsertSitesRequest&)> edit) {
    v1::UpsertSitesRequest r;
    r.set_scene_id("guarded");
    auto* ok = r.add_sites();  // a valid first site: a refusal must not half-apply it
    ok->set_id("new");
    ok->mutable_point()->set_x(1);
    edit(r);
    uint64_t version;
    return client_->UpsertSites(r, &version);
  };
  auto nearest = [](std::function<void(v1::FindNearestRequest&)> edit) {
    v1::FindNearestRequest r;
    r.set_scene_id("guarded");
    edit(r);
    v1::FindNearestResponse response;
    return client_->FindNearest(r, &response);
  };
  const double nan = std::nan(""), inf = INFINITY;
  struct Case {
    const char* name;
    grpc::Status status;
    StatusCode code;
    std::string message;  // a substring the message must hold
  };
  std::vector<Case> cases = {
      {"empty scene id", create([](auto& r) { r.set_scene_id(""); }), StatusCode::INVALID_ARGUMENT,
       "scene_id is empty"},
      {"scene id with a slash", create([](auto& r) { r.set_scene_id("a/b"); }),
       StatusCode::INVALID_ARGUMENT, "scene_id \"a/b\""},
      {"oversize scene id", create([](auto& r) { r.set_scene_id(std::string(129, 'x')); }),
       StatusCode::INVALID_ARGUMENT, "129 characters"},
      {"no window", create([](auto& r) { r.clear_window(); }), StatusCode::INVALID_ARGUMENT,
       "window is not set"},
      {"NaN window", create([&](auto& r) { r.mutable_window()->set_min_y(nan); }),
       StatusCode::INVALID_ARGUMENT, "window.min_y is NaN"},
      {"infinite window", create([&](auto& r) { r.mutable_window()->set_max_x(inf); }),
       StatusCode::INVALID_ARGUMENT, "window.max_x is inf"},
      {"inverted window", create([](auto& r) { r.mutable_window()->set_min_x(2); }),
       StatusCode::INVALID_ARGUMENT, "window.min_x 2 must be less than window.max_x 1"},
      {"empty window", create([](auto& r) { r.mutable_window()->set_max_y(0); }),
       StatusCode::INVALID_ARGUMENT, "window.min_y 0 must be less than window.max_y 0"},
      {"zero width", create([](auto& r) { r.set_width_px(0); }), StatusCode::INVALID_ARGUMENT,
       "width_px is 0"},
      {"oversize height", create([](auto& r) { r.set_height_px(100000); }),
       StatusCode::INVALID_ARGUMENT, "height_px is 100000; it must be 1 to 8192 (--max-side-px)"},
      {"negative max_error", create([](auto& r) { r.set_max_error(-1); }),
       StatusCode::INVALID_ARGUMENT, "max_error is -1"},
      {"tiny max_error", create([](auto& r) { r.set_max_error(1e-9); }),
       StatusCode::INVALID_ARGUMENT, "max_error 1e-09 is below 1/64 pixel"},
      {"existing scene", create([](auto& r) { r.set_scene_id("guarded"); }),
       StatusCode::ALREADY_EXISTS, "scene \"guarded\" already exists"},

      {"upsert to unknown scene", upsert([](auto& r) { r.set_scene_id("nope"); }),
       StatusCode::NOT_FOUND, "scene \"nope\" does not exist"},
      {"empty site id", upsert([](auto& r) { r.add_sites()->mutable_point(); }),
       StatusCode::INVALID_ARGUMENT, "sites[1].id is empty"},
      {"oversize site id",
       upsert([](auto& r) {
         auto* s = r.add_sites();
         s->set_id(std::string(300, 'q'));
         s->mutable_point();
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].id \"qqqq"},
      {"duplicate site ids",
       upsert([](auto& r) {
         auto* s = r.add_sites();
         s->set_id("new");
         s->mutable_point();
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].id \"new\" repeats sites[0].id"},
      {"site without geometry", upsert([](auto& r) { r.add_sites()->set_id("bare"); }),
       StatusCode::INVALID_ARGUMENT, "sites[1].geometry is not set"},
      {"NaN coordinate",
       upsert([&](auto& r) {
         auto* s = r.add_sites();
         s->set_id("n");
         s->mutable_point()->set_x(nan);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].point.x is NaN"},
      {"infinite coordinate",
       upsert([&](auto& r) {
         auto* s = r.add_sites();
         s->set_id("i");
         s->mutable_point()->set_y(-inf);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].point.y is -inf"},
      {"no sites", upsert([](auto& r) { r.clear_sites(); }), StatusCode::INVALID_ARGUMENT,
       "sites is empty"},

      {"query with no points", nearest([](auto&) {}), StatusCode::INVALID_ARGUMENT,
       "points is empty"},
      {"query point NaN",
       nearest([&](auto& r) {
         r.add_points();
         r.add_points()->set_x(nan);
       }),
       StatusCode::INVALID_ARGUMENT, "points[1].x is NaN"},
      {"odd packed coordinates",
       nearest([](auto& r) {
         r.add_xy(1);
         r.add_xy(2);
         r.add_xy(3);
       }),
       StatusCode::INVALID_ARGUMENT, "xy has 3 values; it needs x, y pairs"},
      {"both point forms",
       nearest([](auto& r) {
         r.add_points();
         r.add_xy(1);
         r.add_xy(2);
       }),
       StatusCode::INVALID_ARGUMENT, "points and xy are both set"},
      {"packed NaN",
       nearest([&](auto& r) {
         r.add_xy(1);
         r.add_xy(nan);
       }),
       StatusCode::INVALID_ARGUMENT, "xy[1] is NaN"},
      {"query ahead of the scene",
       nearest([&](auto& r) {
         r.add_points();
         r.set_min_version(v + 100);
       }),
       StatusCode::OUT_OF_RANGE, "min_version " + std::to_string(v + 100) + " is ahead"},
      {"query on unknown scene",
       nearest([](auto& r) {
         r.set_scene_id("nope");
         r.add_points();
       }),
       StatusCode::NOT_FOUND, "scene \"nope\" does not exist"},
  };
  uint64_t version;
  cases.push_back({"delete unknown site", client_->DeleteSites("guarded", {"keep", "ghost"}, &version),
                   StatusCode::NOT_FOUND, "ids[1] \"ghost\" is not a site of scene \"guarded\""});
  cases.push_back({"delete duplicate ids", client_->DeleteSites("guarded", {"keep", "keep"}, &version),
                   StatusCode::INVALID_ARGUMENT, "ids[1] \"keep\" repeats ids[0]"});
  cases.push_back({"delete empty id", client_->DeleteSites("guarded", {""}, &version),
                   StatusCode::INVALID_ARGUMENT, "ids[0] is empty"});
  v1::ListSitesRequest big_page;
  big_page.set_scene_id("guarded");
  big_page.set_page_size(1'000'000);
  v1::ListSitesResponse page;
  cases.push_back({"oversize page", client_->ListSites(big_page, &page),
                   StatusCode::INVALID_ARGUMENT, "page_size is 1000000"});

  for (const Case& c : cases) {
    EXPECT_EQ(c.status.error_code(), c.code) << c.name << ": " << c.status.error_message();
    EXPECT_NE(c.status.error_message().find(c.message), std::string::npos)
        << c.name << ": \"" << c.status.error_message() << "\" lacks \"" << c.message << "\"";
  }
  EXPECT_EQ(state(), before);
  v1::Scene fresh;
  EXPECT_EQ(client_->GetScene("fresh", &fresh).error_code(), StatusCode::NOT_FOUND);

  // A scene with no sites refuses queries.
  Create("bare", {0, 0, 1, 1}, 8, 8);
  v1::FindNearestRequest r;
  r.set_scene_id("bare");
  r.add_points();
  v1::FindNearestResponse response;
  grpc::Status s = client_->FindNearest(r, &response);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("scene \"bare\" has no sites"), std::string::npos);
}

// Readers run while a writer moves sites; every answer is checked against the oracle of
// the version it says it was served from.
TEST_F(ServerTest, ConcurrentQueriesSeeConsistentVersions) {
  Window w{0, 0, 1, 1};
  Create("busy", w, 96, 96);
  std::mutex mu;
  std::map<uint64_t, std::vector<Site>> at_version;
  std::vector<Site> sites = RandomSites(200, w, 1);
  uint64_t first = Upsert("busy", sites);
  at_version[first] = sites;

  std::atomic<bool> writing{true};
  std::thread writer([&] {
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> u(0, 1);
    std::uniform_int_distribution<size_t> pick(0, sites.size() - 1);
    for (int step = 0; step < 40; ++step) {
      std::vector<Site> moved;
      for (int k = 0; k < 10; ++k) {
        Site s = sites[pick(rng)];
        s.geometry = PointSite{{u(rng), u(rng)}};
        moved.push_back(s);
      }
      std::sort(moved.begin(), moved.end(), [](auto& a, auto& b) { return a.id < b.id; });
      moved.erase(std::unique(moved.begin(), moved.end(), [](auto& a, auto& b) { return a.id == b.id; }),
                  moved.end());
      // The oracle must know a version before any reader can be served from it.
      std::lock_guard<std::mutex> lock(mu);
      for (const Site& m : moved) {
        for (Site& s : sites) {
          if (s.id == m.id) s = m;
        }
      }
      uint64_t v = Upsert("busy", moved);
      at_version[v] = sites;
    }
    writing = false;
  });

  std::atomic<int> checked{0};
  auto reader = [&](uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    while (writing || checked < 200) {
      std::vector<Vec2> q = {{u(rng), u(rng)}, {u(rng), u(rng)}};
      auto r = Nearest("busy", q, 0);
      std::vector<Site> oracle;
      {
        std::lock_guard<std::mutex> lock(mu);
        auto it = at_version.find(r.version());
        ASSERT_NE(it, at_version.end()) << "served from unknown version " << r.version();
        oracle = it->second;
      }
      for (size_t i = 0; i < q.size(); ++i) ExpectContract(oracle, q[i], r.results(i));
      ++checked;
    }
  };
  std::thread r1(reader, 1), r2(reader, 2);
  writer.join();
  r1.join();
  r2.join();
  EXPECT_GE(checked, 200);
}

TEST_F(ServerTest, MinVersionWaitsAndHonoursTheDeadline) {
  Window w{0, 0, 1, 1};
  Create("held", w, 64, 64);
  v1::FindNearestRequest r;
  r.set_scene_id("held");
  r.add_points()->set_x(0.5);
  v1::FindNearestResponse response;
  ClientOptions quick;
  quick.timeout = std::chrono::milliseconds(100);
  auto impatient = Client::Connect(server_->address(), quick);
  uint64_t v = 0;
  // Weighted sites: an index answer may score every site, so a raster read waits for its frame.
  auto sites = RandomSites(50, w, 5);
  for (Site& site : sites) site.additive = 0.01;
  {
    // The version stays unrendered until the hold ends, however fast the renderer.
    testing::HoldRenders hold(*server_);
    v = Upsert("held", sites);
    r.set_min_version(v);
    grpc::Status s = impatient->FindNearest(r, &response);
    EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << s.error_message();
    // The exact answer needs no frame: it does not wait (were it to wait, the hold would
    // outlast even the patient client's deadline). The patient client asks, as an exact
    // answer may take more than 100 ms on a slow or instrumented build.
    r.set_exact(true);
    s = client_->FindNearest(r, &response);
    EXPECT_TRUE(s.ok()) << s.error_message();
    EXPECT_EQ(response.version(), v);
    r.set_exact(false);
  }
  // Released: a patient query gets the version it asked for.
  ASSERT_TRUE(client_->FindNearest(r, &response).ok());
  EXPECT_GE(response.version(), v);
}

// A raster read of a version committed but not yet rendered, of at most 64 points in a
// NEAREST scene of plain sites, is answered at once through the index, at that version: the
// renders are held throughout, so a read that waited would outlast the client's deadline.
// Every kind moves (a point into empty space takes a large cell), and each answer is checked
// against the oracle over that version's sites: one from the frame before the moves, or from
// any version before the read's, names a site where it no longer is. Beziers are measured to
// the true curves, so the answers are certified, their bound the rounding of that measure.
TEST_F(ServerTest, CommittedVersionsAreAnsweredBeforeTheirRender) {
  Window w{0, 0, 1, 1};
  Create("unrendered", w, 128, 128);
  std::mt19937_64 rng(41);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto p = [&] { return Vec2{u(0, 1), u(0, 1)}; };
  const double curve_tolerance = 0.002;
  auto random_site = [&](size_t i) {
    const Vec2 a = p();
    Geometry g;
    switch (i % 5) {
      case 0: g = PointSite{a}; break;
      case 1: g = SegmentSite{a, {a.x + u(-0.1, 0.1), a.y + u(-0.1, 0.1)}}; break;
      case 2: g = PolylineSite{{a, {a.x + 0.05, a.y + u(-0.05, 0.05)}, {a.x + 0.1, a.y}}}; break;
      case 3: g = PolygonSite{{a, {a.x + u(0.02, 0.1), a.y}, {a.x, a.y + u(0.02, 0.1)}}}; break;
      default:
        g = MakeBezier({a, {a.x + u(-0.1, 0.1), a.y + 0.1}, {a.x + 0.1, a.y + u(-0.1, 0.1)}},
                       curve_tolerance);
    }
    return Site{"s" + std::to_string(i), g};
  };
  std::vector<Site> sites;
  for (size_t i = 0; i < 200; ++i) sites.push_back(random_site(i));
  // Rendered once: the frame then shows the sites before any move.
  uint64_t v = Upsert("unrendered", sites);
  ASSERT_TRUE(testing::WaitForRender(*client_, "unrendered", v));
  testing::HoldRenders hold(*server_);
  for (int round = 0; round < 30; ++round) {
    std::vector<Site> moved;
    std::vector<Vec2> q;
    for (int k = 0; k < 3; ++k) {
      const size_t i = rng() % sites.size();
      q.push_back(oracle::Segments(sites[i].geometry).front().first);  // where it was
      sites[i] = random_site(i);
      if (round % 10 == 0 && i % 5 == 0) sites[i].geometry = PointSite{{u(1.5, 2), u(1.5, 2)}};
      moved.push_back(sites[i]);
      q.push_back(oracle::Segments(sites[i].geometry).front().first);  // where it is
    }
    while (q.size() < 64) q.push_back(p());
    v = Upsert("unrendered", moved);
    v1::FindNearestResponse response = Nearest("unrendered", q, v);
    ASSERT_EQ(response.results_size(), int(q.size())) << "round " << round;
    EXPECT_EQ(response.version(), v);
    for (size_t i = 0; i < q.size(); ++i) {
      const v1::NearestSite& n = response.results(int(i));
      ExpectContract(sites, q[i], n);
      // Certified: the best distance to the true curves, within the rounding of measuring
      // them (every control point lies within 3 of the origin).
      const double rounding = 0x1p-41 * (n.distance() + 3);
      EXPECT_LE(n.distance(), oracle::BestSite(q[i], sites).value + oracle::Tolerance(q[i], n.distance()) + rounding)
          << "round " << round << " point " << i;
      EXPECT_LE(n.error_bound(), rounding);
      EXPECT_TRUE(n.exact());
    }
  }
  // Without curves, the same answers are certified exact.
  std::vector<std::string> curves;
  for (const Site& site : sites) {
    if (std::holds_alternative<BezierSite>(site.geometry)) curves.push_back(site.id);
  }
  uint64_t deleted = 0;
  ASSERT_TRUE(client_->DeleteSites("unrendered", curves, &deleted).ok());
  v1::FindNearestResponse plain = Nearest("unrendered", {{0.25, 0.75}}, deleted);
  EXPECT_EQ(plain.version(), deleted);
  EXPECT_TRUE(plain.results(0).exact());
  EXPECT_EQ(plain.results(0).error_bound(), 0);
}

// Exact answers: certified, equal to the oracle's nearest distance, also outside the window,
// and from the latest version without waiting for a render.
TEST_F(ServerTest, ExactAnswersMatchTheOracle) {
  Window w{0, 0, 10, 10};
  Create("exact", w, 128, 128);
  auto sites = RandomSites(3000, w, 17);
  uint64_t v = Upsert("exact", sites);
  // Wait for the render, so that exact answers inside the window start from the frame's bound
  // (the index-only path is taken by points outside, and by the query after the next upsert).
  ASSERT_TRUE(testing::WaitForRender(*client_, "exact", v));
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-5, 15);  // about half of them outside the window
  v1::FindNearestRequest r;
  r.set_scene_id("exact");
  r.set_exact(true);
  r.set_min_version(v);
  std::vector<Vec2> q;
  for (int i = 0; i < 4000; ++i) {
    q.push_back({u(rng), u(rng)});
    auto* p = r.add_points();
    p->set_x(q.back().x);
    p->set_y(q.back().y);
  }
  v1::FindNearestResponse response;
  ASSERT_TRUE(client_->FindNearest(r, &response).ok());
  EXPECT_EQ(response.version(), v);
  for (size_t i = 0; i < q.size(); ++i) {
    const auto& n = response.results(i);
    EXPECT_TRUE(n.exact());
    EXPECT_EQ(n.error_bound(), 0);
    EXPECT_NEAR(n.distance(), oracle::BestSite(q[i], sites).value,
                oracle::Tolerance(q[i], n.distance())) << i;
    ExpectContract(sites, q[i], n);
  }
  // Without `exact`, a point outside the window is answered exactly all the same.
  auto far = Nearest("exact", {{-100, 50}, {5, 5}}, v);
  EXPECT_TRUE(far.results(0).exact());
  EXPECT_TRUE(far.results(1).exact());
  EXPECT_NEAR(far.results(0).distance(), oracle::BestSite({-100, 50}, sites).value,
              oracle::Tolerance({-100, 50}, far.results(0).distance()));
  // Exact answers see the latest version at once.
  sites.push_back({"fresh", PointSite{{2.5, 2.5}}});
  uint64_t v2 = Upsert("exact", {sites.back()});
  v1::FindNearestRequest now;
  now.set_scene_id("exact");
  now.set_exact(true);
  now.add_points()->set_x(2.5);
  now.mutable_points(0)->set_y(2.5);
  ASSERT_TRUE(client_->FindNearest(now, &response).ok());
  EXPECT_EQ(response.version(), v2);
  EXPECT_EQ(response.results(0).site_id(), "fresh");
  EXPECT_EQ(response.results(0).distance(), 0);
}

// A batch large enough to be answered tile by tile (OrderByTile): every answer, raster and
// exact, belongs to its own point, against the oracle; points on the window's border and
// repeated among them, and (answered exactly, as any batch holding one) outside it.
TEST_F(ServerTest, LargeBatchesAnswerEveryPointInItsPlace) {
  Window w{0, 0, 1, 1};
  Create("large", w, 128, 128);
  const auto sites = RandomSites(300, w, 31);
  const uint64_t v = Upsert("large", sites);
  std::mt19937_64 rng(32);
  for (bool outside : {false, true}) {
    std::uniform_real_distribution<double> u(outside ? -0.2 : 0, outside ? 1.2 : 1);
    std::vector<Vec2> points;
    for (int i = 0; i < 40000; ++i) {
      if (i % 97 == 0) {
        points.push_back({0, double(i % 5) / 4});  // on the border
      } else if (i % 89 == 0 && !points.empty()) {
        points.push_back(points[points.size() / 2]);  // again
      } else {
        points.push_back({u(rng), u(rng)});
      }
    }
    v1::FindNearestRequest r;
    r.set_scene_id("large");
    r.set_min_version(v);
    for (Vec2 p : points) {
      r.add_xy(p.x);
      r.add_xy(p.y);
    }
    for (bool exact : {false, true}) {
      r.set_exact(exact);
      v1::FindNearestResponse b;
      ASSERT_TRUE(client_->FindNearest(r, &b).ok());
      ASSERT_EQ(b.packed().site_size(), int(points.size()));
      std::map<std::string, const Site*> by_id;
      for (const Site& s : sites) by_id[s.id] = &s;
      int failures = 0;
      for (size_t i = 0; i < points.size() && failures < 5; ++i) {
        const Vec2 q = points[i];
        const uint32_t named = b.packed().site(i);
        ASSERT_GE(named, 1u) << "point " << i;
        ASSERT_LE(named, uint32_t(b.packed().site_ids_size())) << "point " << i;
        const std::string& id = b.packed().site_ids(named - 1);
        const double d = b.packed().distance(i), bound = b.packed().error_bound(i);
        const double truth = oracle::BestSite(q, sites).value, tol = oracle::Tolerance(q, d);
        const bool ok = by_id.count(id) &&
                        std::abs(d - oracle::Distance(q, by_id[id]->geometry)) <= tol &&
                        truth + tol >= d - bound && (!exact || (bound == 0 && d <= truth + tol));
        if (!ok) {
          ++failures;
          ADD_FAILURE() << (exact ? "exact" : "raster") << " point " << i << " (" << q.x << ", "
                        << q.y << "): " << id << " at " << d << " +- " << bound << ", truth " << truth;
        }
      }
      // Without `exact`, a batch inside the window gets raster answers, not all exact.
      if (!exact && !outside) {
        EXPECT_LT(std::count(b.packed().error_bound().begin(), b.packed().error_bound().end(), 0.0),
                  int(points.size()) / 2);
      }
    }
  }
}

// The packed form and the stream give the same answers as the per-point form.
TEST_F(ServerTest, PackedAndStreamedAnswersAgree) {
  Window w{0, 0, 1, 1};
  Create("packed", w, 256, 256);
  auto sites = RandomSites(2000, w, 23);
  uint64_t v = Upsert("packed", sites);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  v1::FindNearestRequest plain, packed;
  plain.set_scene_id("packed");
  plain.set_min_version(v);
  packed = plain;
  for (int i = 0; i < 5000; ++i) {
    double x = u(rng), y = u(rng);
    auto* p = plain.add_points();
    p->set_x(x);
    p->set_y(y);
    packed.add_xy(x);
    packed.add_xy(y);
  }
  v1::FindNearestResponse a, b;
  ASSERT_TRUE(client_->FindNearest(plain, &a).ok());
  ASSERT_TRUE(client_->FindNearest(packed, &b).ok());
  ASSERT_EQ(b.packed().site_size(), 5000);
  EXPECT_EQ(a.results_size(), 5000);
  for (int i = 0; i < 5000; ++i) {
    EXPECT_EQ(a.results(i).site_id(), testing::Named(b.packed(), i));
    EXPECT_EQ(a.results(i).distance(), b.packed().distance(i));
    EXPECT_EQ(a.results(i).error_bound(), b.packed().error_bound(i));
  }
  // Exact answers too, each id named once (2,000 sites answer 5,000 points).
  for (auto* r : {&plain, &packed}) r->set_exact(true);
  ASSERT_TRUE(client_->FindNearest(plain, &a).ok());
  ASSERT_TRUE(client_->FindNearest(packed, &b).ok());
  ASSERT_EQ(b.packed().site_size(), 5000);
  std::set<std::string> named(b.packed().site_ids().begin(), b.packed().site_ids().end());
  EXPECT_EQ(named.size(), size_t(b.packed().site_ids_size())) << "an id is named twice";
  EXPECT_LE(named.size(), sites.size());
  for (int i = 0; i < 5000; ++i) {
    EXPECT_EQ(a.results(i).site_id(), testing::Named(b.packed(), i));
    EXPECT_EQ(a.results(i).distance(), b.packed().distance(i));
    EXPECT_TRUE(b.packed().exact(i));
  }
  for (auto* r : {&plain, &packed}) r->set_exact(false);
  std::vector<v1::FindNearestStreamResponse> chunks;
  ASSERT_TRUE(client_->FindNearestStream(testing::StreamOf(packed, 1200), &chunks).ok());
  ASSERT_EQ(chunks.size(), 5u);  // 1200 x 4 + 200
  int i = 0;
  for (const auto& c : chunks) {
    EXPECT_EQ(c.offset(), uint64_t(i));
    for (int k = 0; k < c.packed().site_size(); ++k, ++i) {
      EXPECT_EQ(testing::Named(c.packed(), k), a.results(i).site_id());
      EXPECT_EQ(c.packed().distance(k), a.results(i).distance());
    }
  }
  EXPECT_EQ(i, 5000);
  // Small chunks of a larger scene: each names its own sites, once.
  ASSERT_TRUE(client_->FindNearestStream(testing::StreamOf(packed, 97), &chunks).ok());
  i = 0;
  for (const auto& c : chunks) {
    std::set<std::string> ids(c.packed().site_ids().begin(), c.packed().site_ids().end());
    EXPECT_EQ(ids.size(), size_t(c.packed().site_ids_size()));
    for (int k = 0; k < c.packed().site_size(); ++k, ++i) {
      EXPECT_EQ(testing::Named(c.packed(), k), a.results(i).site_id());
    }
  }
  EXPECT_EQ(i, 5000);
  // A stream for an unknown scene fails with its status.
  packed.set_scene_id("nowhere");
  EXPECT_EQ(client_->FindNearestStream(testing::StreamOf(packed), &chunks).error_code(),
            StatusCode::NOT_FOUND);
}

// A packed answer carries the columns asked for, with the values of the full answer; the
// others come back empty. Bad field lists are refused by name.
TEST_F(ServerTest, PackedAnswersCarryTheFieldsAskedFor) {
  Window w{0, 0, 1, 1};
  Create("fields", w, 128, 128);
  SiteTable sites = RandomSites(300, w, 31);
  sites.push_back({"seg", SegmentSite{{0.1, 0.1}, {0.9, 0.2}}});
  sites.push_back({"poly", PolylineSite{{{0.2, 0.8}, {0.5, 0.6}, {0.8, 0.9}}}});
  uint64_t v = Upsert("fields", sites);
  std::mt19937_64 rng(10);
  std::uniform_real_distribution<double> u(-0.1, 1.1);  // some outside: exact answers
  v1::FindNearestRequest all;
  all.set_scene_id("fields");
  all.set_min_version(v);
  for (int i = 0; i < 2000; ++i) {
    all.add_xy(u(rng));
    all.add_xy(u(rng));
  }
  using Field = v1::NearestField;
  for (bool exact : {false, true}) {
    all.set_exact(exact);
    v1::FindNearestResponse full;
    ASSERT_TRUE(client_->FindNearest(all, &full).ok());
    const auto& f = full.packed();
    ASSERT_EQ(f.site_size(), 2000);
    ASSERT_EQ(f.feature_kind_size(), 2000);
    // The full answer keeps the contract, against the oracle.
    for (int i = 0; i < 2000 && !HasFailure(); ++i) {
      v1::NearestSite n;
      n.set_site_id(testing::Named(f, i));
      n.set_distance(f.distance(i));
      n.set_error_bound(f.error_bound(i));
      n.set_feature_index(f.feature_index(i));
      n.set_feature_kind(f.feature_kind(i));
      ExpectContract(sites, {all.xy(2 * i), all.xy(2 * i + 1)}, n);
      EXPECT_TRUE(f.exact(i) || !exact);
    }
    for (const std::vector<Field>& want :
         {std::vector<Field>{v1::NEAREST_FIELD_SITE, v1::NEAREST_FIELD_DISTANCE}, {v1::NEAREST_FIELD_FEATURE}, {v1::NEAREST_FIELD_EXACT, v1::NEAREST_FIELD_ERROR_BOUND},
          {v1::NEAREST_FIELD_DISTANCE, v1::NEAREST_FIELD_DISTANCE}}) {
      v1::FindNearestRequest some = all;
      for (Field field : want) some.add_fields(field);
      v1::FindNearestResponse r;
      ASSERT_TRUE(client_->FindNearest(some, &r).ok());
      const auto& p = r.packed();
      auto has = [&](Field x) { return std::find(want.begin(), want.end(), x) != want.end(); };
      EXPECT_EQ(p.site_size(), has(v1::NEAREST_FIELD_SITE) ? 2000 : 0);
      EXPECT_EQ(p.site_ids_size() > 0, has(v1::NEAREST_FIELD_SITE));
      EXPECT_EQ(p.distance_size(), has(v1::NEAREST_FIELD_DISTANCE) ? 2000 : 0);
      EXPECT_EQ(p.error_bound_size(), has(v1::NEAREST_FIELD_ERROR_BOUND) ? 2000 : 0);
      EXPECT_EQ(p.exact_size(), has(v1::NEAREST_FIELD_EXACT) ? 2000 : 0);
      EXPECT_EQ(p.feature_index_size(), has(v1::NEAREST_FIELD_FEATURE) ? 2000 : 0);
      EXPECT_EQ(p.feature_kind_size(), has(v1::NEAREST_FIELD_FEATURE) ? 2000 : 0);
      for (int i = 0; i < 2000; ++i) {
        if (has(v1::NEAREST_FIELD_SITE)) {
          ASSERT_EQ(testing::Named(p, i), testing::Named(f, i));
        }
        if (has(v1::NEAREST_FIELD_DISTANCE)) {
          ASSERT_EQ(p.distance(i), f.distance(i));
        }
        if (has(v1::NEAREST_FIELD_ERROR_BOUND)) {
          ASSERT_EQ(p.error_bound(i), f.error_bound(i));
        }
        if (has(v1::NEAREST_FIELD_EXACT)) {
          ASSERT_EQ(p.exact(i), f.exact(i));
        }
        if (has(v1::NEAREST_FIELD_FEATURE)) {
          ASSERT_EQ(p.feature_index(i), f.feature_index(i));
          ASSERT_EQ(p.feature_kind(i), f.feature_kind(i));
        }
      }
    }
  }
  // Bad lists: an unset or unknown field, and fields with per-point answers.
  v1::FindNearestResponse r;
  v1::FindNearestRequest bad = all;
  bad.add_fields(v1::NEAREST_FIELD_SITE);
  bad.add_fields(v1::NEAREST_FIELD_UNSPECIFIED);
  grpc::Status s = client_->FindNearest(bad, &r);
  EXPECT_EQ(s.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("fields[1] is 0"), std::string::npos) << s.error_message();
  bad.set_fields(1, static_cast<Field>(9));
  s = client_->FindNearest(bad, &r);
  EXPECT_NE(s.error_message().find("fields[1] is 9"), std::string::npos) << s.error_message();
  bad.clear_xy();
  bad.clear_fields();
  bad.add_fields(v1::NEAREST_FIELD_CLOSEST);
  bad.add_fields(v1::NEAREST_FIELD_SITE);
  bad.add_points()->set_x(0.5);
  s = client_->FindNearest(bad, &r);
  EXPECT_EQ(s.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("fields[1] is NEAREST_FIELD_SITE; with points"), std::string::npos)
      << s.error_message();
}

// Every answer can carry the answering site's nearest point and the unit gradient of its
// distance: packed or per point, raster or exact, in a scene of every kind with weights, and
// Pick's too. Judged by the oracle: the point lies on the feature the answer names and is as
// near the query point as the site is; the gradient runs from it to the query point.
TEST_F(ServerTest, ClosestPointsAndGradients) {
  Create("closest", {0, 0, 1, 1}, 128, 128);
  Generator gen(2611);
  std::vector<Site> sites;
  for (int k = 0; k < 140; ++k) {
    Site site{"k" + std::to_string(k), gen.Kind(k % Generator::kKinds)};
    if (k % 5 == 1) site.additive = gen.U(0, 0.05);
    if (k % 5 == 2) site.multiplicative = gen.U(0.8, 2);
    sites.push_back(site);
  }
  const uint64_t v = Upsert("closest", sites);
  std::map<std::string, const Site*> by_id;
  for (const Site& site : sites) by_id[site.id] = &site;
  // Random points, some outside the window, and points on the sites (a zero gradient).
  std::vector<Vec2> queries;
  for (int i = 0; i < 1500; ++i) queries.push_back(gen.P());
  for (int k = 0; k < 140; k += 3) queries.push_back(oracle::Segments(sites[k].geometry)[0].first);
  using Field = v1::NearestField;
  int checked = 0;
  auto check = [&](Vec2 q, const std::string& id, v1::FeatureKind kind, uint32_t index,
                   const v1::Point& closest, const v1::Point& gradient) {
    ASSERT_TRUE(by_id.count(id)) << id;
    ASSERT_TRUE(testing::IsClosestPoint(q, by_id[id]->geometry, kind, index, closest, gradient))
        << "q (" << q.x << ", " << q.y << ") site " << id << " feature " << kind << " "
        << index << " closest (" << closest.x() << ", " << closest.y() << ") gradient ("
        << gradient.x() << ", " << gradient.y() << ")";
    ++checked;
  };
  for (bool exact : {false, true}) {
    // Per point: the whole NearestSite, with closest and gradient added.
    v1::FindNearestRequest each;
    each.set_scene_id("closest");
    each.set_min_version(v);
    each.set_exact(exact);
    for (Vec2 q : queries) testing::SetPoint(q, each.add_points());
    each.add_fields(v1::NEAREST_FIELD_GRADIENT);
    each.add_fields(v1::NEAREST_FIELD_CLOSEST);
    v1::FindNearestResponse r;
    grpc::Status s = client_->FindNearest(each, &r);
    ASSERT_TRUE(s.ok()) << s.error_message();
    ASSERT_EQ(r.results_size(), static_cast<int>(queries.size()));
    for (size_t i = 0; i < queries.size(); ++i) {
      const v1::NearestSite& n = r.results(static_cast<int>(i));
      if (n.empty()) continue;
      const Site& site = *by_id.at(n.site_id());
      const double value = oracle::Value(queries[i], site);
      EXPECT_NEAR(n.distance(), value, oracle::Tolerance(queries[i], value, site.multiplicative));
      ASSERT_TRUE(n.has_closest() && n.has_gradient());
      check(queries[i], n.site_id(), n.feature_kind(), n.feature_index(), n.closest(), n.gradient());
    }
    // Packed: the columns asked for, x and y an answer.
    v1::FindNearestRequest packed;
    packed.set_scene_id("closest");
    packed.set_min_version(v);
    packed.set_exact(exact);
    for (Vec2 q : queries) {
      packed.add_xy(q.x);
      packed.add_xy(q.y);
    }
    for (Field f : {v1::NEAREST_FIELD_SITE, v1::NEAREST_FIELD_FEATURE, v1::NEAREST_FIELD_CLOSEST,
                    v1::NEAREST_FIELD_GRADIENT}) {
      packed.add_fields(f);
    }
    s = client_->FindNearest(packed, &r);
    ASSERT_TRUE(s.ok()) << s.error_message();
    const auto& p = r.packed();
    ASSERT_EQ(p.closest_size(), static_cast<int>(2 * queries.size()));
    ASSERT_EQ(p.gradient_size(), static_cast<int>(2 * queries.size()));
    EXPECT_EQ(p.distance_size(), 0);
    for (size_t i = 0; i < queries.size(); ++i) {
      const int k = static_cast<int>(i);
      if (p.site(k) == 0) {  // no site
        EXPECT_TRUE(std::isnan(p.closest(2 * k)) && std::isnan(p.gradient(2 * k)));
        continue;
      }
      v1::Point closest, gradient;
      testing::SetPoint({p.closest(2 * k), p.closest(2 * k + 1)}, &closest);
      testing::SetPoint({p.gradient(2 * k), p.gradient(2 * k + 1)}, &gradient);
      check(queries[i], testing::Named(p, k), p.feature_kind(k), p.feature_index(k), closest,
            gradient);
    }
    // Left out unless asked for: a packed answer's default columns stay as they were.
    packed.clear_fields();
    s = client_->FindNearest(packed, &r);
    ASSERT_TRUE(s.ok()) << s.error_message();
    EXPECT_EQ(r.packed().closest_size(), 0);
    EXPECT_EQ(r.packed().gradient_size(), 0);
    EXPECT_EQ(r.packed().distance_size(), static_cast<int>(queries.size()));
  }
  // Pick: the nearest site by distance, with its nearest point and gradient.
  for (size_t i = 0; i < queries.size(); i += 7) {
    v1::PickRequest pick;
    pick.set_scene_id("closest");
    testing::SetPoint(queries[i], pick.mutable_point());
    v1::PickResponse picked;
    grpc::Status s = client_->Pick(pick, &picked);
    ASSERT_TRUE(s.ok()) << s.error_message();
    ASSERT_TRUE(picked.found());
    check(queries[i], picked.site_id(), picked.feature_kind(), picked.feature_index(),
          picked.closest(), picked.gradient());
  }
  EXPECT_GT(checked, 6000);
}

// Each limit, set small on a server of its own, refuses with its code and names its flag.
TEST(LimitsTest, EveryLimitIsEnforcedAndNamed) {
  testing::ServerProcess server(
      GVD_SERVER_PATH, {"--max-scenes", "2", "--max-sites-per-scene", "5", "--max-side-px", "64",
                        "--max-points-per-query", "10", "--max-sites-per-request", "4",
                        "--max-message-bytes", "20000"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  auto create = [&](const std::string& id, uint32_t side) {
    v1::CreateSceneRequest c;
    c.set_scene_id(id);
    c.mutable_window()->set_max_x(1);
    c.mutable_window()->set_max_y(1);
    c.set_width_px(side);
    c.set_height_px(side);
    v1::Scene scene;
    return client->CreateScene(c, &scene);
  };
  auto upsert = [&](int first, int count) {
    v1::UpsertSitesRequest u;
    u.set_scene_id("a");
    for (int i = first; i < first + count; ++i) {
      auto* s = u.add_sites();
      s->set_id(std::to_string(i));
      s->mutable_point()->set_x(0.5);
    }
    uint64_t v;
    return client->UpsertSites(u, &v);
  };
  auto expect = [](const grpc::Status& s, StatusCode code, const std::string& text) {
    EXPECT_EQ(s.error_code(), code) << s.error_message();
    EXPECT_NE(s.error_message().find(text), std::string::npos) << s.error_message();
  };
  expect(create("big", 65), StatusCode::INVALID_ARGUMENT, "(--max-side-px)");
  ASSERT_TRUE(create("a", 64).ok());
  ASSERT_TRUE(create("b", 8).ok());
  expect(create("c", 8), StatusCode::RESOURCE_EXHAUSTED, "the limit (--max-scenes) is 2");
  expect(upsert(0, 5), StatusCode::RESOURCE_EXHAUSTED, "(--max-sites-per-request)");
  ASSERT_TRUE(upsert(0, 4).ok());
  expect(upsert(4, 2), StatusCode::RESOURCE_EXHAUSTED, "the limit per scene is 5 (--max-sites-per-scene)");
  v1::FindNearestRequest q;
  q.set_scene_id("a");
  for (int i = 0; i < 11; ++i) q.add_points();
  v1::FindNearestResponse r;
  expect(client->FindNearest(q, &r), StatusCode::RESOURCE_EXHAUSTED, "(--max-points-per-query)");
  v1::FindNearestRequest huge;
  huge.set_scene_id("a");
  for (int i = 0; i < 4000; ++i) huge.add_xy(0.5);  // 32 KB, over --max-message-bytes
  expect(client->FindNearest(huge, &r), StatusCode::RESOURCE_EXHAUSTED, "larger than max");
  // Nothing refused was applied.
  v1::Scene a;
  ASSERT_TRUE(client->GetScene("a", &a).ok());
  EXPECT_EQ(a.site_count(), 4u);
  std::vector<v1::Scene> all;
  ASSERT_TRUE(client->ListScenes(&all).ok());
  EXPECT_EQ(all.size(), 2u);
}

TEST_F(ServerTest, HealthServiceSaysServing) {
  auto channel = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  auto health = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  ASSERT_TRUE(health->Check(&ctx, request, &response).ok());
  EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

TEST_F(ServerTest, LogNamesTheRenderDevice) {
  std::string log = server_->log();
  EXPECT_NE(log.find("event=render_context"), std::string::npos) << log;
  EXPECT_NE(log.find("gl_renderer="), std::string::npos) << log;
}

}  // namespace
}  // namespace gvd
