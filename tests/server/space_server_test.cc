// 3D scenes through the real gvd-server: created with a depth, written with 3D sites
// (points and segments with z, triangles, meshes), queried with 3D points (raster answers
// within their bounds, exact ones equal to the tests' own oracle, closest points and
// gradients), and bad 3D input refused by name with nothing applied.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>
#include <mutex>
#include <condition_variable>
#include <functional>
#include <tuple>
#include <random>
#include <string>
#include <vector>

#include "gvd/client.h"
#include "tests/support/image_files.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"
#include "tests/support/server_process.h"

namespace gvd {
namespace {

using grpc::StatusCode;

void Set(v1::Point* p, Vec3 v) {
  p->set_x(v.x);
  p->set_y(v.y);
  p->set_z(v.z);
}

v1::Site ToProto3(const Site3& s) {
  v1::Site out;
  out.set_id(s.id);
  if (const auto* p = std::get_if<PointSite3>(&s.geometry)) {
    Set(out.mutable_point(), p->p);
  } else if (const auto* g = std::get_if<SegmentSite3>(&s.geometry)) {
    Set(out.mutable_segment()->mutable_a(), g->a);
    Set(out.mutable_segment()->mutable_b(), g->b);
  } else if (const auto* t = std::get_if<TriangleSite3>(&s.geometry)) {
    Set(out.mutable_triangle()->mutable_a(), t->a);
    Set(out.mutable_triangle()->mutable_b(), t->b);
    Set(out.mutable_triangle()->mutable_c(), t->c);
  } else {
    const auto& m = std::get<MeshSite3>(s.geometry);
    for (Vec3 v : m.vertices) {
      for (int k = 0; k < 3; ++k) out.mutable_mesh()->add_xyz(v[k]);
    }
    for (const auto& t : m.triangles) {
      for (uint32_t k : t) out.mutable_mesh()->add_triangles(k);
    }
  }
  if (s.additive != 0) out.set_additive_weight(s.additive);
  return out;
}

class SpaceServerTest : public testing::SharedServerTest {
 protected:
  static v1::CreateSceneRequest Request(const std::string& id, uint32_t side, uint32_t depth) {
    v1::CreateSceneRequest r;
    r.set_scene_id(id);
    auto* w = r.mutable_window();
    w->set_min_x(0);
    w->set_min_y(0);
    w->set_max_x(4);
    w->set_max_y(4);
    w->set_min_z(-1);
    w->set_max_z(2);
    r.set_width_px(side);
    r.set_height_px(side);
    r.set_depth_px(depth);
    return r;
  }
  static grpc::Status Put(const std::string& scene, const std::vector<v1::Site>& sites,
                          uint64_t* version) {
    v1::UpsertSitesRequest r;
    r.set_scene_id(scene);
    for (const v1::Site& s : sites) *r.add_sites() = s;
    return client_->UpsertSites(r, version);
  }
};

std::vector<Site3> Sites() {
  Site3 heavy{"heavy", PointSite3{{2, 2, 0.5}}};
  heavy.additive = 0.25;
  return {{"p", PointSite3{{0.5, 0.5, 0}}},
          heavy,
          {"s", SegmentSite3{{3.5, 0, -3}, {3.5, 4, 3}}},  // through the box and out of it
          {"t", TriangleSite3{{0, 3, 1}, {2, 4, 1}, {0, 4, 1.5}}},
          {"ball", Placed(Icosphere(2), {1, 2.5, 0}, 0.6)},
          {"ring", Placed(Torus(1, 0.2, 24, 8), {2.5, 1.5, 1}, 0.8)}};
}

double OracleValue(Vec3 q, const Site3& s) {
  return double(oracle3::ToGeometry(q, s.geometry)) * s.multiplicative + s.additive;
}

TEST_F(SpaceServerTest, TenThousandQueriesWithinTheirBoundsAndExact) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("space", 24, 18), &scene).ok());
  EXPECT_EQ(scene.depth_px(), 18u);
  EXPECT_EQ(scene.window().max_z(), 2);
  const std::vector<Site3> sites = Sites();
  std::vector<v1::Site> protos;
  for (const Site3& s : sites) protos.push_back(ToProto3(s));
  uint64_t version = 0;
  ASSERT_TRUE(Put("space", protos, &version).ok());

  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> u(-0.5, 4.5), uz(-1.5, 2.5);
  v1::FindNearestRequest r;
  r.set_scene_id("space");
  r.set_min_version(version);
  std::vector<Vec3> points;
  for (int i = 0; i < 10000; ++i) {
    points.push_back({u(rng), u(rng), uz(rng)});
    for (int k = 0; k < 3; ++k) r.add_xyz(points.back()[k]);
  }
  for (auto f : {v1::NEAREST_FIELD_SITE, v1::NEAREST_FIELD_DISTANCE,
                 v1::NEAREST_FIELD_ERROR_BOUND, v1::NEAREST_FIELD_CLOSEST,
                 v1::NEAREST_FIELD_GRADIENT}) {
    r.add_fields(f);
  }
  for (bool exact : {false, true}) {
    r.set_exact(exact);
    v1::FindNearestResponse response;
    grpc::Status st = client_->FindNearest(r, &response);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const v1::PackedNearest& p = response.packed();
    ASSERT_EQ(p.distance_size(), 10000);
    ASSERT_EQ(p.closest_size(), 30000);
    int failures = 0;
    for (int i = 0; i < 10000 && failures < 10; ++i) {
      const Vec3 q = points[i];
      double best = INFINITY;
      for (const Site3& s : sites) best = std::min(best, OracleValue(q, s));
      const std::string id = testing::Named(p, i);
      const Site3& site = *std::find_if(sites.begin(), sites.end(), [&](const Site3& s) { return s.id == id; });
      const double tol = 1e-9 * (1 + best);
      const Vec3 c(p.closest(3 * i), p.closest(3 * i + 1), p.closest(3 * i + 2));
      const Vec3 g(p.gradient(3 * i), p.gradient(3 * i + 1), p.gradient(3 * i + 2));
      bool ok = std::abs(p.distance(i) - OracleValue(q, site)) <= tol &&
                p.distance(i) - best <= p.error_bound(i) + tol && p.distance(i) >= best - tol &&
                (!exact || p.error_bound(i) == 0) &&
                std::abs(Distance(q, c) - double(oracle3::ToGeometry(q, site.geometry))) <= tol &&
                // the closest point lies on the site, and the gradient points from it to q
                double(oracle3::ToGeometry(c, site.geometry)) <= 1e-9 &&
                Length(g - (q - c) / Distance(q, c)) <= 1e-9;
      if (!ok) {
        ++failures;
        ADD_FAILURE() << (exact ? "exact " : "") << "q " << q.x << "," << q.y << "," << q.z << ": "
                      << id << " at " << p.distance(i) << " bound " << p.error_bound(i)
                      << ", best " << best;
      }
    }
  }
  // A point as a message: its closest point has a z.
  v1::FindNearestRequest one;
  one.set_scene_id("space");
  Set(one.add_points(), {0.5, 0.5, 0.75});
  one.add_fields(v1::NEAREST_FIELD_CLOSEST);
  v1::FindNearestResponse answer;
  ASSERT_TRUE(client_->FindNearest(one, &answer).ok());
  ASSERT_EQ(answer.results_size(), 1);
  EXPECT_EQ(answer.results(0).site_id(), "p");
  EXPECT_NEAR(answer.results(0).closest().z(), 0, 1e-12);
  EXPECT_NEAR(answer.results(0).distance(), 0.75, 1e-12);
  // Picking is by distance alone, weights aside: the heavy point is the nearest object.
  v1::PickRequest pick;
  pick.set_scene_id("space");
  Set(pick.mutable_point(), {2, 2, 0.1});
  v1::PickResponse picked;
  ASSERT_TRUE(client_->Pick(pick, &picked).ok());
  EXPECT_EQ(picked.site_id(), "heavy");
  EXPECT_NEAR(picked.distance(), 0.4, 1e-12);
  EXPECT_NEAR(picked.closest().z(), 0.5, 1e-12);
  EXPECT_NEAR(picked.gradient().z(), -1, 1e-12);
  ASSERT_TRUE(client_->DeleteScene("space").ok());
}

// As in 2D: a read of a version committed but not yet rendered, of at most 64 points in a
// scene of plain sites, is answered through the index at once (the renders are held, so a
// read that waited would outlast the client's deadline), exact, against the oracle over that
// version's sites.
TEST_F(SpaceServerTest, CommittedVersionsAreAnsweredBeforeTheirRender) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("unrendered", 16, 12), &scene).ok());
  std::vector<Site3> sites;
  for (const Site3& s : Sites()) {
    if (s.additive == 0) sites.push_back(s);
  }
  std::vector<v1::Site> protos;
  for (const Site3& s : sites) protos.push_back(ToProto3(s));
  uint64_t version = 0;
  ASSERT_TRUE(Put("unrendered", protos, &version).ok());
  ASSERT_TRUE(testing::WaitForRender(*client_, "unrendered", version));  // rendered once
  testing::HoldRenders hold(*server_);
  v1::FindNearestRequest r;
  v1::FindNearestResponse response;
  std::mt19937_64 rng(43);
  std::uniform_real_distribution<double> u(-0.5, 4.5), uz(-1.5, 2.5);
  for (int round = 0; round < 10; ++round) {
    // The point and the ball move (the ball as a whole mesh).
    sites[0].geometry = PointSite3{{u(rng), u(rng), uz(rng)}};
    sites[3] = {"ball", Placed(Icosphere(2), {u(rng), u(rng), uz(rng)}, 0.6)};
    ASSERT_TRUE(Put("unrendered", {ToProto3(sites[0]), ToProto3(sites[3])}, &version).ok());
    r.Clear();
    r.set_scene_id("unrendered");
    r.set_min_version(version);
    std::vector<Vec3> points;
    for (int i = 0; i < 64; ++i) {
      points.push_back({u(rng), u(rng), uz(rng)});
      Set(r.add_points(), points.back());
    }
    grpc::Status st = client_->FindNearest(r, &response);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(response.version(), version);
    ASSERT_EQ(response.results_size(), 64);
    for (int i = 0; i < 64; ++i) {
      const v1::NearestSite& n = response.results(i);
      double best = INFINITY;
      for (const Site3& s : sites) best = std::min(best, OracleValue(points[i], s));
      const auto named = std::find_if(sites.begin(), sites.end(),
                                      [&](const Site3& s) { return s.id == n.site_id(); });
      ASSERT_NE(named, sites.end()) << n.site_id();
      const double tol = 1e-9 * (1 + best);
      EXPECT_NEAR(n.distance(), OracleValue(points[i], *named), tol) << "round " << round;
      EXPECT_NEAR(n.distance(), best, tol) << "round " << round << " point " << i;
      EXPECT_TRUE(n.exact());
    }
  }
}

// The clearance field of a 3D scene: its own voxels, and a sub-box at a resolution of the
// caller's (reaching outside the scene's box), each sample a lower bound on the oracle's
// distance and within the voxel diagonal of it, its site the nearest within that, and its
// gradient the unit vector from the site's nearest point to the sample.
TEST_F(SpaceServerTest, ClearanceFieldsAreLowerBoundsWithGradientsAndSites) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("field", 16, 12), &scene).ok());
  const std::vector<Site3> sites = Sites();
  std::vector<v1::Site> protos;
  for (const Site3& s : sites) protos.push_back(ToProto3(s));
  uint64_t version = 0;
  ASSERT_TRUE(Put("field", protos, &version).ok());
  const double diagonal = Length(Vec3(4.0 / 16, 4.0 / 16, 3.0 / 12));

  v1::GetClearanceFieldRequest own;
  own.set_scene_id("field");
  own.set_min_version(version);
  own.set_gradients(true);
  own.set_site_indices(true);
  v1::GetClearanceFieldRequest sub = own;
  auto* w = sub.mutable_window();
  w->set_min_x(-1);
  w->set_min_y(1);
  w->set_min_z(0.25);
  w->set_max_x(3);
  w->set_max_y(3.5);
  w->set_max_z(2.75);  // past the scene's box
  sub.set_width_px(9);
  sub.set_height_px(7);
  sub.set_depth_px(5);
  // The scene's voxels whose centres lie in a window that cuts through voxels and reaches
  // past the box: x centres 0.375 to 3.875, y 0.125 to 0.875, z 0.125 and 0.375.
  v1::GetClearanceFieldRequest part = own;
  w = part.mutable_window();
  w->set_min_x(0.3);
  w->set_min_y(-1);
  w->set_min_z(0.1);
  w->set_max_x(5);
  w->set_max_y(1.1);
  w->set_max_z(0.6);
  for (const auto* r : {&own, &sub, &part}) {
    v1::GetClearanceFieldResponse f;
    grpc::Status st = client_->GetClearanceField(*r, &f);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const bool is_own = r == &own;
    const uint32_t nx = is_own ? 16 : r == &sub ? 9 : 15, ny = is_own ? 16 : r == &sub ? 7 : 4,
                   nz = is_own ? 12 : r == &sub ? 5 : 2;
    ASSERT_EQ(f.width_px(), nx);
    ASSERT_EQ(f.height_px(), ny);
    ASSERT_EQ(f.depth_px(), nz);
    const size_t n = size_t{nx} * ny * nz;
    ASSERT_EQ(size_t(f.clearance_size()), n);
    ASSERT_EQ(size_t(f.gradient_size()), 3 * n);
    ASSERT_EQ(size_t(f.ids_size()), n);
    const v1::Window& b = f.window();
    if (is_own) {
      EXPECT_EQ(b.min_z(), -1);
      EXPECT_EQ(b.max_z(), 2);
    } else if (r == &sub) {
      EXPECT_EQ(b.max_z(), 2.75);
    } else {  // the part's voxels, out to their edges
      EXPECT_EQ(b.min_x(), 0.25);
      EXPECT_EQ(b.max_x(), 4);
      EXPECT_EQ(b.min_y(), 0);
      EXPECT_EQ(b.max_y(), 1);
      EXPECT_EQ(b.min_z(), 0);
      EXPECT_EQ(b.max_z(), 0.5);
    }
    int failures = 0;
    for (uint32_t k = 0; k < nz; ++k) {
      for (uint32_t j = 0; j < ny; ++j) {
        for (uint32_t i = 0; i < nx && failures < 10; ++i) {
          const size_t at = (size_t{k} * ny + j) * nx + i;
          const Vec3 q(b.min_x() + (i + 0.5) * (b.max_x() - b.min_x()) / nx,
                       b.min_y() + (j + 0.5) * (b.max_y() - b.min_y()) / ny,
                       b.min_z() + (k + 0.5) * (b.max_z() - b.min_z()) / nz);
          double best = INFINITY;
          for (const Site3& s : sites) best = std::min(best, OracleValue(q, s));
          ASSERT_GT(f.ids(at), 0u);
          const std::string& id = f.site_ids(f.ids(at) - 1);
          const Site3& site =
              *std::find_if(sites.begin(), sites.end(), [&](const Site3& s) { return s.id == id; });
          const double value = OracleValue(q, site);
          const Vec3 g(f.gradient(3 * at), f.gradient(3 * at + 1), f.gradient(3 * at + 2));
          // The unit gradient of the named site's distance points to q from its nearest
          // point: d back along it lands on the site (a float's precision aside).
          const double d = double(oracle3::ToGeometry(q, site.geometry));
          const double off = double(oracle3::ToGeometry(q - d * g, site.geometry));
          const double c = f.clearance(at);
          const bool ok = c <= best && c >= best - diagonal && value - best <= diagonal &&
                          std::abs(Length(g) - 1) <= 1e-6 && off <= 1e-6 * (1 + d);
          if (!ok) {
            ++failures;
            ADD_FAILURE() << (is_own ? "own" : r == &sub ? "sub" : "part") << " sample " << i << "," << j << "," << k
                          << " q " << q.x << "," << q.y << "," << q.z << ": clearance " << c
                          << ", oracle " << best << ", site " << id << " at " << value
                          << ", gradient " << g.x << "," << g.y << "," << g.z << " off " << off;
          }
        }
      }
    }
  }
  // Bad requests, by name.
  v1::GetClearanceFieldRequest bad = sub;
  bad.set_depth_px(0);
  v1::GetClearanceFieldResponse f;
  grpc::Status st = client_->GetClearanceField(bad, &f);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("depth_px is 0"), std::string::npos) << st.error_message();
  bad = sub;
  bad.mutable_window()->set_max_z(NAN);
  st = client_->GetClearanceField(bad, &f);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("window.max_z"), std::string::npos) << st.error_message();
  bad = sub;
  bad.set_width_px(200);
  bad.set_height_px(100);
  bad.set_depth_px(100);
  st = client_->GetClearanceField(bad, &f);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("--max-points-per-query"), std::string::npos)
      << st.error_message();
  bad = sub;
  bad.set_width_px(8192);
  bad.set_height_px(8192);
  bad.set_depth_px(8192);
  st = client_->GetClearanceField(bad, &f);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("--max-voxels-per-scene"), std::string::npos)
      << st.error_message();
  ASSERT_TRUE(client_->DeleteScene("field").ok());
}

// Images of a 3D scene's slices: the slice holding z or named by index, its voxels' sites
// (SITE_INDEX, decoded) and distances (EXR floats) against the oracle at the voxel centres;
// a window of x and y; bad requests refused by name.
TEST_F(SpaceServerTest, SliceImagesShowTheNearestSitesAndTheirDistances) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("slices", 40, 12), &scene).ok());
  const std::vector<Site3> sites = Sites();
  std::vector<v1::Site> protos;
  for (const Site3& s : sites) protos.push_back(ToProto3(s));
  uint64_t version = 0;
  ASSERT_TRUE(Put("slices", protos, &version).ok());
  const double voxel = 4.0 / 40, voxel_z = 3.0 / 12;
  struct Case {
    bool by_z;
    double z;
    uint32_t slice;
  };
  // z 0.6 lies in slice 6 ([0.5, 0.75)); the top face's z (2) in the last slice.
  for (Case c : {Case{true, 0.6, 6}, Case{false, 0, 3}, Case{true, 2, 11}}) {
    v1::RenderImageRequest r;
    r.set_scene_id("slices");
    r.set_min_version(version);
    c.by_z ? r.set_z(c.z) : r.set_slice(c.slice);
    r.set_layer(v1::RenderImageRequest::LAYER_SITE_INDEX);
    r.mutable_window()->set_min_x(0.5);
    r.mutable_window()->set_min_y(1);
    r.mutable_window()->set_max_x(3.9);
    r.mutable_window()->set_max_y(4);
    v1::RenderImageResponse ids;
    grpc::Status st = client_->RenderImage(r, &ids);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(ids.slice(), c.slice);
    const double z = -1 + (c.slice + 0.5) * voxel_z;
    EXPECT_DOUBLE_EQ(ids.slice_z(), z);
    // Voxel columns 5 to 38, rows 10 to 39.
    ASSERT_EQ(ids.width_px(), 34u);
    ASSERT_EQ(ids.height_px(), 30u);
    EXPECT_DOUBLE_EQ(ids.window().min_x(), 5 * voxel);
    EXPECT_DOUBLE_EQ(ids.window().max_y(), 4);
    r.set_layer(v1::RenderImageRequest::LAYER_DISTANCE);
    r.set_format(v1::RenderImageRequest::FORMAT_EXR);
    v1::RenderImageResponse distances;
    st = client_->RenderImage(r, &distances);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const uint32_t w = ids.width_px(), h = ids.height_px();
    testing::Pixels8 decoded;
    std::string error;
    ASSERT_TRUE(testing::ReadPngRgb(ids.image(), &decoded, &error)) << error;
    ASSERT_EQ(decoded.file_channels, 3);
    ASSERT_EQ(decoded.width, int(w));
    ASSERT_EQ(decoded.height, int(h));
    const std::vector<uint8_t>& rgb = decoded.v;
    std::vector<float> depth;
    int depth_w = 0, depth_h = 0;
    std::vector<std::string> depth_channels;
    ASSERT_TRUE(testing::ReadExrChannel(distances.image(), "Z", &depth_w, &depth_h, &depth,
                                        &depth_channels, &error))
        << error;
    ASSERT_EQ(depth_channels, std::vector<std::string>{"Z"});
    ASSERT_EQ(depth_w, int(w));
    ASSERT_EQ(depth_h, int(h));
    int failures = 0;
    for (uint32_t row = 0; row < h && failures < 10; ++row) {
      for (uint32_t col = 0; col < w && failures < 10; ++col) {
        const size_t at = size_t{row} * w + col;
        const Vec3 q((5 + col + 0.5) * voxel, 4 - (row + 0.5) * voxel, z);  // row 0 at the top
        const uint8_t* p = &rgb[at * 3];
        const uint32_t index = uint32_t{p[0]} << 16 | uint32_t{p[1]} << 8 | p[2];
        double best = INFINITY;
        for (const Site3& s : sites) best = std::min(best, OracleValue(q, s));
        const bool named = index >= 1 && index <= uint32_t(ids.site_ids_size());
        double value = INFINITY;
        if (named) {
          const std::string& id = ids.site_ids(int(index - 1));
          value = OracleValue(q, *std::find_if(sites.begin(), sites.end(),
                                               [&](const Site3& s) { return s.id == id; }));
        }
        // The voxel's site is the nearest (ties within float rounding), its value the
        // nearest's in float.
        const bool ok = named && value <= best * (1 + 1e-6) + 1e-9 &&
                        std::abs(double(depth[at]) - best) <= 1e-6 * (1 + best);
        if (!ok) {
          ++failures;
          ADD_FAILURE() << "slice " << c.slice << " pixel " << col << "," << row << ": index "
                        << index << " value " << value << ", depth " << depth[at] << ", oracle "
                        << best;
        }
      }
    }
  }
  // Bad requests, by name.
  struct Bad {
    std::function<void(v1::RenderImageRequest*)> edit;
    const char* says;
  };
  for (const Bad& bad : std::vector<Bad>{
           {[](auto*) {}, "set z or slice"},
           {[](auto* r) { r->set_z(0); r->set_slice(1); }, "set z or slice"},
           {[](auto* r) { r->set_slice(12); }, "slice is 12; the scene has 12"},
           {[](auto* r) { r->set_z(2.5); }, "z is 2.5; it must lie in the box's [-1, 2]"},
           {[](auto* r) { r->set_z(0); r->set_draw_sites(true); }, "draw_sites and polyline are for 2D"}}) {
    v1::RenderImageRequest r;
    r.set_scene_id("slices");
    bad.edit(&r);
    v1::RenderImageResponse image;
    grpc::Status st = client_->RenderImage(r, &image);
    EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << bad.says;
    EXPECT_NE(st.error_message().find(bad.says), std::string::npos) << st.error_message();
  }
  ASSERT_TRUE(client_->DeleteScene("slices").ok());
}

// WatchScene on a 3D scene: an event for each rendered version (its box as the part that may
// have changed, z too), and a last one when the scene is deleted.
TEST_F(SpaceServerTest, WatchingA3DSceneFollowsItsVersionsToItsDeletion) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("watched", 8, 6), &scene).ok());
  std::vector<v1::WatchSceneResponse> events;
  std::mutex mu;
  std::condition_variable cv;
  std::thread watcher([&] {
    v1::WatchSceneRequest r;
    r.set_scene_id("watched");
    grpc::Status st = client_->WatchScene(r, [&](const v1::WatchSceneResponse& e) {
      std::lock_guard<std::mutex> lock(mu);
      events.push_back(e);
      cv.notify_all();
      return true;
    });
    EXPECT_TRUE(st.ok()) << st.error_message();
  });
  auto wait_for = [&](auto&& done) {
    std::unique_lock<std::mutex> lock(mu);
    return cv.wait_for(lock, std::chrono::seconds(30), [&] { return done(); });
  };
  ASSERT_TRUE(wait_for([&] { return !events.empty(); }));
  uint64_t version = 0;
  ASSERT_TRUE(Put("watched", {ToProto3({"a", PointSite3{{1, 1, 0.5}}})}, &version).ok());
  ASSERT_TRUE(wait_for([&] { return events.back().version() >= version; }));
  {
    std::lock_guard<std::mutex> lock(mu);
    const v1::WatchSceneResponse& e = events.back();
    EXPECT_EQ(e.version(), version);
    EXPECT_EQ(e.site_count(), 1u);
    EXPECT_EQ(e.changed().min_z(), -1);
    EXPECT_EQ(e.changed().max_z(), 2);
    EXPECT_EQ(e.changed().max_x(), 4);
  }
  ASSERT_TRUE(client_->DeleteScene("watched").ok());
  ASSERT_TRUE(wait_for([&] { return events.back().deleted(); }));
  watcher.join();
}

TEST_F(SpaceServerTest, Bad3DInputIsRefusedByNameAndChangesNothing) {
  v1::Scene scene;
  ASSERT_TRUE(client_->CreateScene(Request("bad3", 8, 8), &scene).ok());
  uint64_t version = 0;
  ASSERT_TRUE(Put("bad3", {ToProto3({"ok", PointSite3{{1, 1, 1}}})}, &version).ok());
  auto refused = [&](std::vector<v1::Site> sites, StatusCode code, const std::string& says) {
    uint64_t v = 0;
    grpc::Status st = Put("bad3", sites, &v);
    EXPECT_EQ(st.error_code(), code) << st.error_message();
    EXPECT_NE(st.error_message().find(says), std::string::npos) << st.error_message();
  };
  v1::Site mesh = ToProto3({"m", Placed(Icosphere(0), {1, 1, 1}, 0.5)});
  v1::Site past = mesh;
  past.mutable_mesh()->set_triangles(5, 99);
  refused({ToProto3({"fine", PointSite3{{2, 2, 2}}}), past}, StatusCode::INVALID_ARGUMENT,
          "sites[1].mesh.triangles[5] is 99, past the 12 vertices");
  v1::Site nan = mesh;
  nan.mutable_mesh()->set_xyz(4, NAN);
  refused({nan}, StatusCode::INVALID_ARGUMENT, "sites[0].mesh.xyz[4] is nan");
  v1::Site ragged = mesh;
  ragged.mutable_mesh()->add_triangles(0);
  refused({ragged}, StatusCode::INVALID_ARGUMENT, "sites[0].mesh.triangles has 61 indices");
  v1::Site line;
  line.set_id("line");
  line.mutable_polyline()->add_points();
  line.mutable_polyline()->add_points();
  refused({line}, StatusCode::INVALID_ARGUMENT, "sites[0] is a polyline; a 3D scene takes");
  v1::Site inf = ToProto3({"inf", PointSite3{{1, 1, 1}}});
  inf.mutable_point()->set_z(INFINITY);
  refused({inf}, StatusCode::INVALID_ARGUMENT, "sites[0].point.z is inf");
  // Nothing of the refused requests was applied.
  v1::Scene now;
  ASSERT_TRUE(client_->GetScene("bad3", &now).ok());
  EXPECT_EQ(now.version(), version);
  EXPECT_EQ(now.site_count(), 1u);

  // Scenes: a z range that is empty, more voxels than the limit, z in a 2D scene.
  v1::CreateSceneRequest flat_z = Request("z", 8, 8);
  flat_z.mutable_window()->set_max_z(-1);
  grpc::Status st = client_->CreateScene(flat_z, &scene);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("window.min_z -1 must be less than window.max_z -1"), std::string::npos)
      << st.error_message();
  st = client_->CreateScene(Request("huge", 8192, 8192), &scene);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("--max-voxels-per-scene"), std::string::npos) << st.error_message();
  v1::CreateSceneRequest flat = Request("flat2", 8, 8);
  flat.set_depth_px(0);
  st = client_->CreateScene(flat, &scene);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("a z range is for 3D scenes"), std::string::npos) << st.error_message();
  flat.mutable_window()->clear_min_z();
  flat.mutable_window()->clear_max_z();
  ASSERT_TRUE(client_->CreateScene(flat, &scene).ok());
  v1::Site up = ToProto3({"up", PointSite3{{1, 1, 1}}});
  uint64_t v = 0;
  st = Put("flat2", {up}, &v);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("sites[0].point.z is 1; points of a 2D scene have no z"),
            std::string::npos) << st.error_message();
  st = Put("flat2", {mesh}, &v);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("sites[0].mesh is a site of 3D scenes"), std::string::npos)
      << st.error_message();
  // 2D calls on a 3D scene say what it is.
  v1::GetBoundariesRequest boundaries;
  boundaries.set_scene_id("bad3");
  v1::GetBoundariesResponse boundaries_response;
  st = client_->GetBoundaries(boundaries, &boundaries_response);
  EXPECT_EQ(st.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(st.error_message().find("is a 3D scene"), std::string::npos) << st.error_message();
  // Packed 2D points on a 3D scene.
  v1::FindNearestRequest xy;
  xy.set_scene_id("bad3");
  xy.add_xy(1);
  xy.add_xy(1);
  v1::FindNearestResponse r;
  st = client_->FindNearest(xy, &r);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("xy is for 2D scenes"), std::string::npos) << st.error_message();
  // Packed 3D points on a 2D scene.
  v1::FindNearestRequest xyz;
  xyz.set_scene_id("flat2");
  for (int k = 0; k < 3; ++k) xyz.add_xyz(1);
  st = client_->FindNearest(xyz, &r);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("xyz is for 3D scenes"), std::string::npos) << st.error_message();
  ASSERT_TRUE(client_->DeleteScene("bad3").ok());
  ASSERT_TRUE(client_->DeleteScene("flat2").ok());
}

}  // namespace
}  // namespace gvd
