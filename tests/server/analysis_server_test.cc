// Boundaries, neighbours, Delaunay, zoom windows, clearance, planning and picking through the
// real gvd-server, against the exact oracle; bad input refused by name.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "gvd/client.h"
#include "render/kernel/exact2.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"
#include "tests/support/maze.h"
#include "tests/support/qhull_delaunay.h"

namespace gvd {
namespace {

using grpc::StatusCode;
using testing::IsNearestFeature;
using testing::ToProtoSite;

class AnalysisServerTest : public testing::SharedServerTest {
 protected:
  static void SetUpTestSuite() { StartServer({"--max-side-px", "4096"}); }
  // A scene over the unit square at size x size pixels.
  static void Create(const std::string& id, uint32_t size, v1::Diagram diagram = v1::DIAGRAM_NEAREST,
                     v1::RenderMode mode = v1::RENDER_MODE_MESH) {
    v1::CreateSceneRequest r = testing::UnitScene(id, size, size);
    r.set_diagram(diagram);
    r.set_render_mode(mode);
    v1::Scene scene;
    auto s = client_->CreateScene(r, &scene);
    ASSERT_TRUE(s.ok()) << s.error_message();
  }
  static SiteTable RandomPoints(int n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    SiteTable sites;
    for (int i = 0; i < n; ++i) sites.push_back({"p" + std::to_string(i), PointSite{{u(rng), u(rng)}}});
    return sites;
  }
};

const Site& ById(const SiteTable& sites, const std::string& id) {
  for (const Site& s : sites) {
    if (s.id == id) return s;
  }
  static const Site kNone;
  ADD_FAILURE() << "no site " << id;
  return kNone;
}

// Delaunay of random points: every triangle's circumcircle is empty (checked against all
// points), triangles are counter-clockwise, their edges are the neighbour pairs, and the
// triangles cover the points' convex hull as Euler's formula says.
TEST_F(AnalysisServerTest, DelaunayTrianglesHaveEmptyCircumcircles) {
  Create("delaunay", 1024);
  SiteTable sites = RandomPoints(300, 7);
  uint64_t v = Upsert("delaunay", sites);
  v1::GetDelaunayRequest r;
  r.set_scene_id("delaunay");
  r.set_min_version(v);
  v1::GetDelaunayResponse d;
  auto s = client_->GetDelaunay(r, &d);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(d.version(), v);
  auto at = [&](const std::string& id) { return std::get<PointSite>(ById(sites, id).geometry).p; };
  for (const auto& t : d.triangles()) {
    Vec2 a = at(t.a()), b = at(t.b()), c = at(t.c());
    EXPECT_GT((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x), 0) << "clockwise";
    double det = 2 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
    Vec2 o{(glm::dot(a, a) * (b.y - c.y) + glm::dot(b, b) * (c.y - a.y) + glm::dot(c, c) * (a.y - b.y)) / det,
           (glm::dot(a, a) * (c.x - b.x) + glm::dot(b, b) * (a.x - c.x) + glm::dot(c, c) * (b.x - a.x)) / det};
    double r2 = Distance(o, a);
    for (const Site& p : sites) {
      if (p.id == t.a() || p.id == t.b() || p.id == t.c()) continue;
      ASSERT_GT(Distance(o, std::get<PointSite>(p.geometry).p), r2 * (1 - 1e-9))
          << p.id << " lies inside the circumcircle of " << t.a() << " " << t.b() << " " << t.c();
    }
  }
  // Every Delaunay triangle (Qhull's) whose circumcentre, its Voronoi vertex, lies in the
  // window a pixel from its border or more is there.
  std::vector<Vec2> pts;
  for (const Site& p : sites) pts.push_back(std::get<PointSite>(p.geometry).p);
  std::vector<std::array<uint32_t, 3>> tris;
  testing::QhullEdges(pts, &tris);
  std::set<std::set<std::string>> ours;
  for (const auto& t : d.triangles()) ours.insert({t.a(), t.b(), t.c()});
  size_t inside = 0;
  for (const auto& t : tris) {
    Vec2 a = pts[t[0]], b = pts[t[1]], c = pts[t[2]];
    double det = 2 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
    Vec2 o{(glm::dot(a, a) * (b.y - c.y) + glm::dot(b, b) * (c.y - a.y) + glm::dot(c, c) * (a.y - b.y)) / det,
           (glm::dot(a, a) * (c.x - b.x) + glm::dot(b, b) * (a.x - c.x) + glm::dot(c, c) * (b.x - a.x)) / det};
    const double margin = 1.0 / 1024;
    if (o.x < margin || o.y < margin || o.x > 1 - margin || o.y > 1 - margin) continue;
    ++inside;
    EXPECT_TRUE(ours.count({sites[t[0]].id, sites[t[1]].id, sites[t[2]].id}))
        << sites[t[0]].id << " " << sites[t[1]].id << " " << sites[t[2]].id;
  }
  EXPECT_GT(inside, 450u);
  // The edges are GetNeighbors' pairs.
  v1::GetNeighborsRequest nr;
  nr.set_scene_id("delaunay");
  v1::GetNeighborsResponse n;
  ASSERT_TRUE(client_->GetNeighbors(nr, &n).ok());
  ASSERT_EQ(n.pairs_size(), d.edges_size());
  for (int k = 0; k < n.pairs_size(); ++k) {
    EXPECT_EQ(n.pairs(k).site_a(), d.edges(k).site_a());
    EXPECT_EQ(n.pairs(k).site_b(), d.edges(k).site_b());
    EXPECT_LT(n.pairs(k).site_a(), n.pairs(k).site_b());
  }
  // One site's neighbours only.
  nr.set_site_id("p0");
  ASSERT_TRUE(client_->GetNeighbors(nr, &n).ok());
  ASSERT_GE(n.pairs_size(), 2);
  for (const auto& p : n.pairs()) EXPECT_TRUE(p.site_a() == "p0" || p.site_b() == "p0");
}

// Boundaries of random points: both methods find the same pixel pairs; each boundary is
// between two neighbours and its inner points are equidistant from them.
TEST_F(AnalysisServerTest, BoundariesByBothMethods) {
  Create("bounds", 400, v1::DIAGRAM_NEAREST, v1::RENDER_MODE_EXACT);
  SiteTable sites = RandomPoints(40, 11);
  uint64_t v = Upsert("bounds", sites);
  v1::GetBoundariesRequest r;
  r.set_scene_id("bounds");
  r.set_min_version(v);
  v1::GetBoundariesResponse full, walk;
  ASSERT_TRUE(client_->GetBoundaries(r, &full).ok());
  r.set_method(v1::GetBoundariesRequest::METHOD_CONTINUATION);
  ASSERT_TRUE(client_->GetBoundaries(r, &walk).ok());
  EXPECT_EQ(full.boundary_pixel_pairs(), walk.boundary_pixel_pairs());
  EXPECT_EQ(full.boundaries_size(), walk.boundaries_size());
  EXPECT_LT(walk.cells_visited(), full.cells_visited());
  // Crossings are located exactly where the two pixels' sites are right (in EXACT mode, all
  // but float ties), else at the pixels' midpoint.
  size_t exact = 0, points = 0;
  for (const auto& b : full.boundaries()) {
    ASSERT_FALSE(b.site_a().empty());
    const Vec2 pa = std::get<PointSite>(ById(sites, b.site_a()).geometry).p;
    const Vec2 pb = std::get<PointSite>(ById(sites, b.site_b()).geometry).p;
    for (int k = 2; k + 3 < b.xy_size(); k += 2) {  // not the ends: junctions are means
      Vec2 p{b.xy(k), b.xy(k + 1)};
      double gap = std::abs(Distance(p, pa) - Distance(p, pb));
      ++points;
      exact += gap < 1e-12;
      EXPECT_LT(gap, 2.0 / 400);
    }
  }
  EXPECT_GT(exact, points * 99 / 100);
  // A window of the scene: fewer boundaries, all inside it.
  r.set_method(v1::GetBoundariesRequest::METHOD_FULL_SCAN);
  r.mutable_window()->set_min_x(0.25);
  r.mutable_window()->set_min_y(0.25);
  r.mutable_window()->set_max_x(0.5);
  r.mutable_window()->set_max_y(0.5);
  v1::GetBoundariesResponse part;
  ASSERT_TRUE(client_->GetBoundaries(r, &part).ok());
  EXPECT_LT(part.boundary_pixel_pairs(), full.boundary_pixel_pairs() / 4);
  for (const auto& b : part.boundaries()) {
    for (int k = 0; k + 1 < b.xy_size(); k += 2) {
      EXPECT_TRUE(b.xy(k) > 0.24 && b.xy(k) < 0.51 && b.xy(k + 1) > 0.24 && b.xy(k + 1) < 0.51);
    }
  }
}

// A zoom window rendered by the server: every pixel's site is within 2 eps (at the zoom's
// resolution) of the exact nearest, even for a window outside the scene's.
TEST_F(AnalysisServerTest, ZoomWindowsAgainstTheOracle) {
  Create("zoom", 256, v1::DIAGRAM_NEAREST, v1::RENDER_MODE_EXACT);
  SiteTable sites = RandomPoints(60, 3);
  sites.push_back({"seg", SegmentSite{{0.1, 0.9}, {0.6, 0.7}}});
  uint64_t v = Upsert("zoom", sites);
  for (auto [x0, y0, x1, y1] : {std::tuple{0.4, 0.4, 0.43, 0.41}, {-0.5, 0.2, 0.1, 0.5}}) {
    v1::RenderWindowRequest r;
    r.set_scene_id("zoom");
    r.mutable_window()->set_min_x(x0);
    r.mutable_window()->set_min_y(y0);
    r.mutable_window()->set_max_x(x1);
    r.mutable_window()->set_max_y(y1);
    r.set_width_px(120);
    r.set_height_px(40);
    r.set_min_version(v);
    v1::RenderWindowResponse z;
    auto s = client_->RenderWindow(r, &z);
    ASSERT_TRUE(s.ok()) << s.error_message();
    ASSERT_EQ(z.ids_size(), 120 * 40);
    Grid g{{x0, y0, x1, y1}, 120, 40};
    for (uint32_t j = 0; j < 40; ++j) {
      for (uint32_t i = 0; i < 120; ++i) {
        uint32_t id = z.ids(j * 120 + i);
        ASSERT_GT(id, 0u);
        const Site& site = ById(sites, z.site_ids(id - 1));
        Vec2 p = g.Center(i, j);
        oracle::Best truth = oracle::BestSite(p, sites);
        ASSERT_LE(oracle::Distance(p, site.geometry) - truth.value, 2 * z.max_error() + 1e-6)
            << "pixel " << i << "," << j;
        EXPECT_NEAR(z.distances(j * 120 + i), oracle::Distance(p, site.geometry), 1e-4);
      }
    }
  }
  // Without a size: the scene's own pixels over the window, from its frame.
  v1::RenderWindowRequest r;
  r.set_scene_id("zoom");
  v1::RenderWindowResponse all;
  ASSERT_TRUE(client_->RenderWindow(r, &all).ok());
  EXPECT_EQ(all.width_px(), 256u);
  EXPECT_EQ(all.ids_size(), 256 * 256);
  EXPECT_EQ(all.window().max_x(), 1);
}

// The clearance field bounds the true clearance from below, within the meshes' error, and
// is 0 inside a solid polygon.
TEST_F(AnalysisServerTest, ClearanceFieldBoundsTheDistance) {
  Create("clear", 128);
  SiteTable sites = RandomPoints(10, 5);
  sites.push_back({"block", PolygonSite{{{0.3, 0.3}, {0.6, 0.32}, {0.5, 0.6}}}});
  uint64_t v = Upsert("clear", sites);
  v1::GetClearanceFieldRequest r;
  r.set_scene_id("clear");
  r.set_min_version(v);
  v1::GetClearanceFieldResponse c;
  ASSERT_TRUE(client_->GetClearanceField(r, &c).ok());
  ASSERT_EQ(c.clearance_size(), 128 * 128);
  const Grid g{{0, 0, 1, 1}, 128, 128};
  const auto& tri = std::get<PolygonSite>(sites.back().geometry).vertices;
  size_t inside = 0;
  for (uint32_t j = 0; j < 128; ++j) {
    for (uint32_t i = 0; i < 128; ++i) {
      Vec2 p = g.Center(i, j);
      float got = c.clearance(j * 128 + i);
      if (oracle::Inside(p, tri)) {
        ++inside;
        EXPECT_EQ(got, 0);
        continue;
      }
      double truth = oracle::BestSite(p, sites).value;
      ASSERT_LE(got, truth * (1 + 1e-6)) << i << "," << j;
      ASSERT_GE(got, truth - 2.5 * g.pixel_size()) << i << "," << j;
    }
  }
  EXPECT_GT(inside, 500u);
}

// Paths through a maze served by the server; then a wall moves and the plan follows.
TEST_F(AnalysisServerTest, PlansThroughAMazeAndReplansWhenWallsMove) {
  Create("maze", 512);
  const int k = 6;
  SiteTable walls = testing::Maze(k, 4);
  uint64_t v = Upsert("maze", walls);
  const double half = 0.5 / k, px = 1.0 / 512;
  v1::PlanPathRequest r;
  r.set_scene_id("maze");
  r.mutable_start()->set_x(half);
  r.mutable_start()->set_y(half);
  r.mutable_goal()->set_x(1 - half);
  r.mutable_goal()->set_y(1 - half);
  r.set_robot_radius(half - 3 * px);
  r.set_min_version(v);
  v1::PlanPathResponse plan;
  auto s = client_->PlanPath(r, &plan);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_GE(plan.min_clearance(), r.robot_radius());
  auto check = [&](const v1::PlanPathResponse& p, const SiteTable& sites) {
    for (int n = 1; n < p.path_size(); ++n) {
      Vec2 a{p.path(n - 1).x(), p.path(n - 1).y()}, b{p.path(n).x(), p.path(n).y()};
      int steps = std::max(1, int(Distance(a, b) / px * 10));
      for (int t = 0; t <= steps; ++t) {
        Vec2 q = a + (double(t) / steps) * (b - a);
        ASSERT_GE(oracle::BestSite(q, sites).value, p.min_clearance() * (1 - 1e-9));
      }
    }
  };
  check(plan, walls);
  // Wider than the corridors (the start's among them): NOT_FOUND, saying why.
  r.set_robot_radius(half + px);
  s = client_->PlanPath(r, &plan);
  EXPECT_EQ(s.error_code(), StatusCode::NOT_FOUND);
  EXPECT_NE(s.error_message().find("is within robot_radius"), std::string::npos) << s.error_message();
  // A wall across the first cell's only way out: now there is no path at all...
  v1::PlanPathResponse before;
  r.set_robot_radius(0.01);
  ASSERT_TRUE(client_->PlanPath(r, &before).ok());
  SiteTable boxed = walls;
  boxed.push_back({"lid", SegmentSite{{0, 2 * half}, {2 * half, 2 * half}}});
  boxed.push_back({"side", SegmentSite{{2 * half, 0}, {2 * half, 2 * half}}});
  v = Upsert("maze", {boxed[boxed.size() - 2], boxed.back()});
  r.set_min_version(v);
  s = client_->PlanPath(r, &plan);
  EXPECT_EQ(s.error_code(), StatusCode::NOT_FOUND) << s.error_message();
  // ...and once the lid moves away again, the plan is back, on the new version.
  v1::UpsertSitesRequest move;
  move.set_scene_id("maze");
  *move.add_sites() = ToProtoSite({"lid", SegmentSite{{5, 5}, {5.1, 5}}});
  ASSERT_TRUE(client_->UpsertSites(move, &v).ok());
  r.set_min_version(v);
  s = client_->PlanPath(r, &plan);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(plan.version(), v);
  SiteTable now = boxed;
  now[now.size() - 2] = {"lid", SegmentSite{{5, 5}, {5.1, 5}}};
  check(plan, now);
}

// Pick: the site whose geometry is nearest by Euclidean distance, exactly, weights aside.
TEST_F(AnalysisServerTest, PickIsTheExactNearestObject) {
  Create("pick", 256);
  SiteTable sites = RandomPoints(50, 9);
  sites.push_back({"seg", SegmentSite{{0.2, 0.2}, {0.8, 0.3}}});
  sites.push_back({"poly", PolygonSite{{{0.6, 0.6}, {0.9, 0.62}, {0.7, 0.9}}}});
  Site heavy{"heavy", PointSite{{0.5, 0.5}}};
  heavy.additive = 10;  // weights do not change what is picked
  sites.push_back(heavy);
  Upsert("pick", sites);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  for (int k = 0; k < 2000; ++k) {
    Vec2 q{u(rng), u(rng)};
    v1::PickRequest r;
    r.set_scene_id("pick");
    r.mutable_point()->set_x(q.x);
    r.mutable_point()->set_y(q.y);
    v1::PickResponse p;
    ASSERT_TRUE(client_->Pick(r, &p).ok());
    ASSERT_TRUE(p.found());
    double best = INFINITY;
    for (const Site& s : sites) best = std::min(best, oracle::Distance(q, s.geometry));
    const double tolerance = oracle::Tolerance(q, best);
    ASSERT_NEAR(p.distance(), best, tolerance);
    ASSERT_NEAR(oracle::Distance(q, ById(sites, p.site_id()).geometry), best, tolerance);
    EXPECT_TRUE(IsNearestFeature(q, ById(sites, p.site_id()).geometry, p.feature_kind(),
                                 p.feature_index()))
        << p.feature_kind() << " " << p.feature_index();
    // Beyond max_distance: nothing.
    r.set_max_distance(best * 0.999);
    ASSERT_TRUE(client_->Pick(r, &p).ok());
    ASSERT_FALSE(p.found());
  }
}

// A site squeezed between pixel centres holds no pixel: GetScene counts it, GetNeighbors
// finds it by zooming, with its ring of neighbours.
TEST_F(AnalysisServerTest, HiddenSitesAreReportedAndRecovered) {
  Create("hidden", 64);
  const double r = 1.0 / 64 / 10;
  const Vec2 c{0.5 + 0.3 / 64, 0.5 + 0.2 / 64};
  SiteTable sites = {{"centre", PointSite{c}}, {"far", PointSite{{0.1, 0.1}}}};
  for (int k = 0; k < 6; ++k) {
    sites.push_back({"ring" + std::to_string(k),
                     PointSite{{c.x + r * std::cos(k * M_PI / 3), c.y + r * std::sin(k * M_PI / 3)}}});
  }
  uint64_t v = Upsert("hidden", sites);
  v1::GetNeighborsRequest nr;
  nr.set_scene_id("hidden");
  nr.set_min_version(v);
  v1::GetNeighborsResponse n;
  ASSERT_TRUE(client_->GetNeighbors(nr, &n).ok());
  ASSERT_EQ(n.hidden_size(), 1);
  EXPECT_EQ(n.hidden(0).site_id(), "centre");
  EXPECT_TRUE(n.hidden(0).recovered());
  std::set<std::string> around;
  for (const auto& p : n.pairs()) {
    if (p.site_a() == "centre") around.insert(p.site_b());
    if (p.site_b() == "centre") around.insert(p.site_a());
  }
  EXPECT_EQ(around.size(), 6u);
  EXPECT_GT(n.zoom_windows(), 0u);
  v1::Scene scene;
  ASSERT_TRUE(client_->GetScene("hidden", &scene).ok());
  EXPECT_EQ(scene.hidden_site_count(), 1u);
  ASSERT_EQ(scene.hidden_site_ids_size(), 1);
  EXPECT_EQ(scene.hidden_site_ids(0), "centre");
  // Coarse: the pixels as they are; the centre has no pairs at all.
  nr.set_coarse(true);
  ASSERT_TRUE(client_->GetNeighbors(nr, &n).ok());
  EXPECT_FALSE(n.hidden(0).recovered());
  for (const auto& p : n.pairs()) EXPECT_NE(p.site_a(), "centre");
}

// A coarse raster of many points leaves many answers ambiguous: the best two sites around the
// query within the bound of each other. Those come back certified and right; asked to skip
// the refinement, the raster's answers stay within their bound but are more often the wrong
// site.
TEST_F(AnalysisServerTest, AmbiguousAnswersAreRefined) {
  {
    // Meshes four pixels off: many pixels hold a close second. (Where full renders are
    // computed, pixel centres hold exact values, but a point between centres still can.)
    v1::CreateSceneRequest c = testing::UnitScene("ambiguous", 64, 64);
    c.set_max_error(4.0 / 64);
    v1::Scene scene;
    ASSERT_TRUE(client_->CreateScene(c, &scene).ok());
  }
  SiteTable sites = RandomPoints(400, 13);
  uint64_t v = Upsert("ambiguous", sites);
  std::mt19937_64 rng(14);
  std::uniform_real_distribution<double> u(0, 1);
  v1::FindNearestRequest r;
  r.set_scene_id("ambiguous");
  r.set_min_version(v);
  std::vector<Vec2> qs;
  for (int k = 0; k < 5000; ++k) {
    qs.push_back({u(rng), u(rng)});
    r.add_xy(qs.back().x);
    r.add_xy(qs.back().y);
  }
  size_t wrong[2] = {0, 0}, certified[2] = {0, 0};
  for (int skip : {0, 1}) {
    r.set_skip_refinement(skip);
    v1::FindNearestResponse a;
    ASSERT_TRUE(client_->FindNearest(r, &a).ok());
    const auto& p = a.packed();
    for (size_t k = 0; k < qs.size(); ++k) {
      oracle::Best truth = oracle::BestSite(qs[k], sites);
      const double got = p.distance(int(k));
      const double tolerance = oracle::Tolerance(qs[k], got);
      ASSERT_GE(got, truth.value - tolerance);
      ASSERT_LE(got - truth.value, p.error_bound(int(k)) + tolerance);
      const bool right = std::abs(got - truth.value) <= tolerance;
      wrong[skip] += !right;
      if (p.exact(int(k))) {
        ++certified[skip];
        ASSERT_TRUE(right) << "a certified answer is wrong at " << qs[k].x << "," << qs[k].y;
      }
    }
  }
  std::printf("of 5000 answers: refined %zu wrong, %zu certified; raster only %zu wrong, %zu certified\n",
              wrong[0], certified[0], wrong[1], certified[1]);
  // Refining only replaces answers by exact ones, so it can only mend: here it does, though
  // answers whose four pixels hold a single site are not ambiguous and stay as they are.
  EXPECT_GT(wrong[1], 5u) << "the raster alone should sometimes pick a close second";
  EXPECT_LT(wrong[0], wrong[1]);
  EXPECT_GT(certified[0], 1000u);
  EXPECT_EQ(certified[1], 0u);
}

TEST_F(AnalysisServerTest, BadInputIsRefusedByName) {
  Create("bad", 64);
  Create("far", 64, v1::DIAGRAM_FARTHEST);
  SiteTable sites = {{"a", PointSite{{0.2, 0.2}}}, {"s", SegmentSite{{0.5, 0.5}, {0.7, 0.6}}}};
  Upsert("bad", sites);
  Upsert("far", sites);
  auto expect = [](const grpc::Status& s, StatusCode code, const std::string& words) {
    EXPECT_EQ(s.error_code(), code) << s.error_message();
    EXPECT_NE(s.error_message().find(words), std::string::npos) << s.error_message();
  };
  {
    v1::GetBoundariesRequest r;
    v1::GetBoundariesResponse out;
    r.set_scene_id("nope");
    expect(client_->GetBoundaries(r, &out), StatusCode::NOT_FOUND, "\"nope\"");
    r.set_scene_id("bad");
    r.set_method(static_cast<v1::GetBoundariesRequest::Method>(7));
    expect(client_->GetBoundaries(r, &out), StatusCode::INVALID_ARGUMENT, "method is 7");
    r.set_method(v1::GetBoundariesRequest::METHOD_FULL_SCAN);
    r.mutable_window()->set_min_x(5);
    r.mutable_window()->set_max_x(6);
    r.mutable_window()->set_max_y(1);
    expect(client_->GetBoundaries(r, &out), StatusCode::INVALID_ARGUMENT, "holds no pixel centre");
    r.clear_window();
    r.set_min_version(99);
    expect(client_->GetBoundaries(r, &out), StatusCode::OUT_OF_RANGE, "min_version 99");
  }
  {
    v1::GetNeighborsRequest r;
    v1::GetNeighborsResponse out;
    r.set_scene_id("bad");
    r.set_site_id("ghost");
    expect(client_->GetNeighbors(r, &out), StatusCode::NOT_FOUND, "\"ghost\"");
  }
  {
    v1::GetDelaunayRequest r;
    v1::GetDelaunayResponse out;
    r.set_scene_id("bad");
    expect(client_->GetDelaunay(r, &out), StatusCode::FAILED_PRECONDITION, "\"s\" is not a point");
  }
  {
    v1::RenderWindowRequest r;
    v1::RenderWindowResponse out;
    r.set_scene_id("bad");
    r.set_width_px(5000);
    r.set_height_px(10);
    expect(client_->RenderWindow(r, &out), StatusCode::INVALID_ARGUMENT, "--max-side-px");
    r.set_width_px(10);
    r.mutable_window()->set_min_x(1);
    r.mutable_window()->set_max_x(0);
    r.mutable_window()->set_max_y(1);
    expect(client_->RenderWindow(r, &out), StatusCode::INVALID_ARGUMENT, "window.min_x 1");
    r.mutable_window()->set_max_x(NAN);
    expect(client_->RenderWindow(r, &out), StatusCode::INVALID_ARGUMENT, "window.max_x");
  }
  {
    v1::GetClearanceFieldRequest r;
    v1::GetClearanceFieldResponse out;
    r.set_scene_id("far");
    expect(client_->GetClearanceField(r, &out), StatusCode::FAILED_PRECONDITION, "FARTHEST");
  }
  {
    v1::PlanPathRequest r;
    v1::PlanPathResponse out;
    r.set_scene_id("bad");
    expect(client_->PlanPath(r, &out), StatusCode::INVALID_ARGUMENT, "start is not set");
    r.mutable_start()->set_x(2);
    r.mutable_goal()->set_x(0.5);
    r.mutable_goal()->set_y(0.9);
    expect(client_->PlanPath(r, &out), StatusCode::INVALID_ARGUMENT, "start (2, 0) lies outside");
    r.mutable_start()->set_x(0.9);
    r.mutable_start()->set_y(0.1);
    r.set_robot_radius(-1);
    expect(client_->PlanPath(r, &out), StatusCode::INVALID_ARGUMENT, "robot_radius is -1");
    r.set_robot_radius(0.01);
    r.mutable_goal()->set_x(0.2);
    r.mutable_goal()->set_y(0.205);
    expect(client_->PlanPath(r, &out), StatusCode::NOT_FOUND, "goal (0.2, 0.205) is within robot_radius");
    r.set_scene_id("far");
    expect(client_->PlanPath(r, &out), StatusCode::FAILED_PRECONDITION, "FARTHEST");
  }
  {
    v1::PickRequest r;
    v1::PickResponse out;
    r.set_scene_id("bad");
    expect(client_->Pick(r, &out), StatusCode::INVALID_ARGUMENT, "point is not set");
    r.mutable_point()->set_x(INFINITY);
    expect(client_->Pick(r, &out), StatusCode::INVALID_ARGUMENT, "inf");
    r.mutable_point()->set_x(0);
    r.set_max_distance(-2);
    expect(client_->Pick(r, &out), StatusCode::INVALID_ARGUMENT, "max_distance is -2");
  }
}

// With one analysis thread and room for one waiting call, a third call at once is refused
// with RESOURCE_EXHAUSTED naming the flag; the others complete. The calls are zoom windows,
// which the one render thread draws, and it is held in a render of another scene until the
// test lets it go: the call on the analysis thread waits there whatever the machine's speed.
TEST(AnalysisLimitsTest, QueuedAnalysesAreBounded) {
  testing::ServerProcess server(GVD_SERVER_PATH, {"--analysis-threads", "1",
                                                  "--max-queued-analyses", "1",
                                                  "--render-threads", "1"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  v1::Scene scene;
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("busy", 64, 64), &scene).ok());
  uint64_t v;
  ASSERT_TRUE(client->UpsertSites(testing::RandomPoints("busy", 100, 3), &v).ok());
  ASSERT_TRUE(testing::WaitForRender(*client, "busy", v));
  // The render thread goes into the held render of "held" and stays there.
  const std::string held = server.hold_renders_path() + ".held";
  std::ofstream(held).put('x');
  ASSERT_TRUE(client->CreateScene(testing::UnitScene("held", 64, 64), &scene).ok());
  ASSERT_TRUE(client->UpsertSites(testing::RandomPoints("held", 10, 4), &v).ok());
  ASSERT_TRUE(testing::WaitForHeldRender(server, "held")) << "the render of \"held\" never began";
  std::vector<grpc::Status> results(3);
  std::vector<std::thread> calls;
  std::mutex mu;
  std::condition_variable cv;
  int answered = 0;      // guarded by mu
  bool let_go = false;   // guarded by mu
  int done_held = 0;     // calls that succeeded while held; guarded by mu
  for (int k = 0; k < 3; ++k) {
    calls.emplace_back([&, k] {
      v1::RenderWindowRequest r;
      r.set_scene_id("busy");
      r.set_width_px(16);
      r.set_height_px(16);
      v1::RenderWindowResponse out;
      grpc::Status s = client->RenderWindow(r, &out);
      std::lock_guard<std::mutex> lock(mu);
      results[k] = s;
      if (s.ok() && !let_go) ++done_held;
      ++answered;
      cv.notify_all();
    });
  }
  {
    // No call can succeed while the render thread is held, and the queue is full once a call
    // waits in it: the first answer is a refusal.
    std::unique_lock<std::mutex> lock(mu);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::minutes(1), [&] { return answered > 0; }))
        << "no call was refused while the analysis thread and its queue were full";
    let_go = true;
  }
  std::remove(held.c_str());
  for (auto& t : calls) t.join();
  EXPECT_EQ(done_held, 0) << "a zoom window was drawn while the render thread was held";
  int refused = 0;
  for (const auto& s : results) {
    if (s.ok()) continue;
    ++refused;
    EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
    EXPECT_NE(s.error_message().find("--max-queued-analyses"), std::string::npos) << s.error_message();
  }
  // One call or none is on the analysis thread when the last arrives (the pool may not have
  // taken the first yet), and one waits: one refusal or two.
  EXPECT_GE(refused, 1);
  EXPECT_LE(refused, 2);
}

}  // namespace
}  // namespace gvd
