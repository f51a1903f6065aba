// Every site kind and diagram variant through the real gvd-server: queries against the
// exact oracle, bad site input refused by name, images, and sites read back.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "gvd/client.h"
#include "render/kernel/exact2.h"
#include "render/kernel/path2.h"
#include "tests/support/image_files.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using grpc::StatusCode;
using testing::IsNearestFeature;
using testing::SetPoint;
using testing::ToProtoSite;

// A scene of every kind, with weights, max_distance and sides.
std::vector<Site> MixedSites(uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto p = [&] { return Vec2{u(-1, 11), u(-1, 11)}; };
  std::vector<Site> sites;
  for (int i = 0; i < 36; ++i) {
    Geometry g;
    Vec2 a = p();
    switch (i < 30 ? i % 6 : 6) {
      case 0: g = PointSite{a}; break;
      case 1: g = SegmentSite{a, {a.x + u(-2, 2), a.y + u(-2, 2)}}; break;
      case 2: g = PolylineSite{{a, {a.x + 1, a.y + u(-1, 1)}, {a.x + 2, a.y + u(-1, 1)}}}; break;
      case 3:
      case 4:
        g = PolygonSite{{a, {a.x + u(0.5, 2), a.y}, {a.x + u(0, 2), a.y + u(0.5, 2)}},
                        i % 12 == 3 ? Side::kOutside : i % 12 == 9 ? Side::kInside : Side::kBoth};
        break;
      case 5:
        g = MakeBezier({a, {a.x + u(-2, 2), a.y + 2}, {a.x + 2, a.y + u(-2, 2)}, p()}, 0.01);
        break;
      default: {  // a rounded square (lines and cubics) with a square hole, or an open hook
        const double r = u(1, 2), k = 0.55 * r / 2;
        Subpath outer{{{a.x + r / 2, a.y}, {a.x + r, a.y}, {a.x + r + k, a.y}, {a.x + 1.5 * r, a.y + r / 2 - k},
                       {a.x + 1.5 * r, a.y + r / 2}, {a.x + 1.5 * r, a.y + r}, {a.x, a.y + r}},
                      {1, 3, 1, 1}, true};
        Subpath hole{{{a.x + 0.5, a.y + 0.2}, {a.x + 0.5, a.y + 0.6}, {a.x + 0.9, a.y + 0.6}, {a.x + 0.9, a.y + 0.2}},
                     {1, 1, 1}, true};
        const Side side = i % 3 == 0 ? Side::kOutside : i % 3 == 1 ? Side::kInside : Side::kBoth;
        if (side == Side::kBoth) hole = {{a, {a.x + 1, a.y + 1}, {a.x + 2, a.y}}, {2}, false};
        g = MakePath({outer, hole}, i % 2 ? FillRule::kEvenOdd : FillRule::kNonZero, side, 0.01);
      }
    }
    Site s{"s" + std::to_string(i), g};
    if (i % 5 == 1) s.additive = u(0, 1);
    if (i % 5 == 2) s.multiplicative = u(0.5, 2);
    if (i % 7 == 3) s.max_distance = u(1, 3);
    sites.push_back(s);
  }
  return sites;
}

class SitesServerTest : public testing::SharedServerTest {
 protected:
  static void Create(const std::string& id, v1::Diagram diagram, v1::RenderMode mode) {
    v1::CreateSceneRequest r;
    r.set_scene_id(id);
    r.mutable_window()->set_max_x(10);
    r.mutable_window()->set_max_y(10);
    r.set_width_px(512);
    r.set_height_px(512);
    r.set_diagram(diagram);
    r.set_render_mode(mode);
    v1::Scene scene;
    ASSERT_TRUE(client_->CreateScene(r, &scene).ok());
  }
};

// The acceptance: a scene mixing all kinds, weights and both diagram directions
// answers FindNearest within its reported bound on 10,000 random queries.
TEST_F(SitesServerTest, MixedScenesAnswerWithinTheirBound) {
  const std::vector<Site> sites = MixedSites(7);
  // The curves' extent, which scales the rounding of measuring them (Bezier in the API).
  double extent = 0;
  for (const Site& s : sites) {
    if (const auto* b = std::get_if<BezierSite>(&s.geometry)) {
      for (Vec2 p : b->control) extent = std::max(extent, s.multiplicative * Length(p));
    }
    if (const auto* path = std::get_if<PathSite>(&s.geometry)) {
      for (const PathPiece& piece : path->pieces) {
        for (int i = 0; piece.degree > 1 && i <= piece.degree; ++i) {
          extent = std::max(extent, s.multiplicative * Length(piece.control[i]));
        }
      }
    }
  }
  ASSERT_GT(extent, 0);
  int scene = 0;
  for (v1::Diagram diagram : {v1::DIAGRAM_NEAREST, v1::DIAGRAM_FARTHEST}) {
    for (v1::RenderMode mode : {v1::RENDER_MODE_MESH, v1::RENDER_MODE_EXACT}) {
      std::string id = "mixed" + std::to_string(scene++);
      Create(id, diagram, mode);
      uint64_t version = Upsert(id, sites);
      std::mt19937_64 rng(scene);
      std::uniform_real_distribution<double> u(0, 10);
      for (bool exact : {false, true}) {
        v1::FindNearestRequest r;
        r.set_scene_id(id);
        r.set_min_version(version);
        r.set_exact(exact);
        std::vector<Vec2> qs;
        for (int k = 0; k < (exact ? 1000 : 10000); ++k) {
          qs.push_back({u(rng), u(rng)});
          SetPoint(qs.back(), r.add_points());
        }
        v1::FindNearestResponse response;
        auto st = client_->FindNearest(r, &response);
        ASSERT_TRUE(st.ok()) << st.error_message();
        ASSERT_EQ(response.results_size(), int(qs.size()));
        const Diagram d = diagram == v1::DIAGRAM_FARTHEST ? Diagram::kFarthest : Diagram::kNearest;
        for (size_t k = 0; k < qs.size(); ++k) {
          const v1::NearestSite& n = response.results(int(k));
          oracle::Best truth = oracle::BestSite(qs[k], sites, d);
          ASSERT_EQ(n.empty(), !truth.found) << id << " query " << k;
          if (n.empty()) continue;
          const Site& s = sites[std::stoi(n.site_id().substr(1))];
          // The API's limit on the rounding of measuring curves.
          const double curves = 0x1p-41 * (std::abs(n.distance()) + extent);
          const double tolerance = oracle::Tolerance(qs[k], n.distance(), s.multiplicative) +
                                   (oracle::CurveRounding(n.distance(), s) > 0 ? curves : 0);
          ASSERT_NEAR(n.distance(), oracle::Value(qs[k], s), tolerance) << id << " query " << k;
          ASSERT_TRUE(IsNearestFeature(qs[k], s.geometry, n.feature_kind(), n.feature_index()))
              << id << " query " << k << " feature " << n.feature_kind() << " "
              << n.feature_index();
          double gap = d == Diagram::kNearest ? n.distance() - truth.value
                                              : truth.value - n.distance();
          ASSERT_GE(gap, -tolerance) << id << " query " << k;
          ASSERT_LE(gap, n.error_bound() + tolerance) << id << " query " << k << (exact ? " exact" : "");
          // Exact answers measure the true curves: certified, their bound the rounding.
          if (exact) {
            ASSERT_LE(n.error_bound(), curves) << id << " query " << k;
            ASSERT_TRUE(n.exact()) << id << " query " << k;
          }
        }
      }
    }
  }
}

TEST_F(SitesServerTest, SitesReadBackAsWritten) {
  Create("readback", v1::DIAGRAM_NEAREST, v1::RENDER_MODE_MESH);
  const std::vector<Site> sites = MixedSites(3);
  Upsert("readback", sites);
  std::vector<v1::Site> listed;
  ASSERT_TRUE(client_->ListAllSites("readback", &listed).ok());
  ASSERT_EQ(listed.size(), sites.size());
  for (const v1::Site& s : listed) {
    v1::Site want = ToProtoSite(sites[std::stoi(s.id().substr(1))]);
    if (want.multiplicative_weight() == 1) want.clear_multiplicative_weight();
    EXPECT_EQ(s.SerializeAsString(), want.SerializeAsString()) << s.DebugString();
  }
}

TEST_F(SitesServerTest, BadSitesAreRefusedByName) {
  Create("bad", v1::DIAGRAM_NEAREST, v1::RENDER_MODE_MESH);
  uint64_t before = Upsert("bad", {{"keep", PointSite{{1, 1}}}});
  auto upsert = [](std::function<void(v1::Site&)> edit) {
    v1::UpsertSitesRequest r;
    r.set_scene_id("bad");
    auto* ok = r.add_sites();
    ok->set_id("fine");
    ok->mutable_point()->set_x(2);
    v1::Site* s = r.add_sites();
    s->set_id("x");
    edit(*s);
    uint64_t version;
    return client_->UpsertSites(r, &version);
  };
  auto pts = [](auto* list, std::vector<Vec2> ps) {
    for (Vec2 p : ps) SetPoint(p, list->Add());
  };
  struct Case {
    grpc::Status status;
    StatusCode code;
    std::string message;
  };
  const double nan = std::nan("");
  std::vector<Case> cases = {
      {upsert([&](auto& s) { pts(s.mutable_polyline()->mutable_points(), {{0, 0}}); }),
       StatusCode::INVALID_ARGUMENT, "sites[1].polyline.points has 1 points; it needs at least 2"},
      {upsert([&](auto& s) { pts(s.mutable_polygon()->mutable_vertices(), {{0, 0}, {1, 1}}); }),
       StatusCode::INVALID_ARGUMENT, "sites[1].polygon.vertices has 2 points"},
      {upsert([&](auto& s) {
         pts(s.mutable_polygon()->mutable_vertices(), {{0, 0}, {1, nan}, {2, 0}});
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].polygon.vertices[1].y is NaN"},
      {upsert([&](auto& s) {
         pts(s.mutable_polygon()->mutable_vertices(), {{0, 0}, {1, 1}, {2, 0}});
         s.mutable_polygon()->set_side(static_cast<v1::Polygon::Side>(7));
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].polygon.side is 7"},
      {upsert([&](auto& s) {
         pts(s.mutable_bezier()->mutable_control_points(), {{0, 0}, {1, 1}, {2, 0}, {3, 1}, {4, 0}});
       }),
       StatusCode::INVALID_ARGUMENT, "has 5 points; a Bezier takes 3 (quadratic) or 4 (cubic)"},
      {upsert([&](auto& s) {
         pts(s.mutable_bezier()->mutable_control_points(), {{0, 0}, {1, 1}, {2, 0}});
         s.mutable_bezier()->set_tolerance(-1);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].bezier.tolerance is -1"},
      {upsert([&](auto& s) { s.mutable_path(); }), StatusCode::INVALID_ARGUMENT,
       "sites[1].path has no subpath"},
      {upsert([&](auto& s) {
         auto* sub = s.mutable_path()->add_subpaths();
         pts(sub->mutable_points(), {{0, 0}, {1, 1}, {2, 0}, {3, 1}});
         sub->add_degrees(1);
         sub->add_degrees(4);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.subpaths[0].degrees[1] is 4"},
      {upsert([&](auto& s) {
         s.mutable_path()->add_subpaths();
         auto* sub = s.mutable_path()->add_subpaths();
         pts(sub->mutable_points(), {{0, 0}, {1, 1}, {2, 0}, {3, 1}});
         sub->add_degrees(3);
         sub->add_degrees(1);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.subpaths[0].points has 0 points"},
      {upsert([&](auto& s) {
         auto* sub = s.mutable_path()->add_subpaths();
         pts(sub->mutable_points(), {{0, 0}, {1, 1}, {2, 0}, {3, 1}});
         sub->add_degrees(3);
         sub->add_degrees(1);
       }),
       StatusCode::INVALID_ARGUMENT,
       "sites[1].path.subpaths[0].points has 4 points; its start and the pieces of its degrees take 5"},
      {upsert([&](auto& s) {
         auto* sub = s.mutable_path()->add_subpaths();
         pts(sub->mutable_points(), {{0, 0}, {1, 1}, {2, 0}});
         s.mutable_path()->set_side(v1::Polygon::SIDE_INSIDE);
       }),
       StatusCode::INVALID_ARGUMENT,
       "sites[1].path: subpath 0 is open; a path restricted to a side has only closed subpaths"},
      {upsert([&](auto& s) {
         pts(s.mutable_path()->add_subpaths()->mutable_points(), {{0, 0}, {1, 1}});
         s.mutable_path()->set_fill_rule(static_cast<v1::Path::FillRule>(9));
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.fill_rule is 9"},
      {upsert([&](auto& s) {
         pts(s.mutable_path()->add_subpaths()->mutable_points(), {{0, 0}, {1, nan}});
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.subpaths[0].points[1].y is NaN"},
      {upsert([&](auto& s) {
         pts(s.mutable_path()->add_subpaths()->mutable_points(), {{0, 0}, {1, 1}});
         s.mutable_path()->set_tolerance(-1);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.tolerance is -1"},
      {upsert([&](auto& s) {
         pts(s.mutable_path()->add_subpaths()->mutable_points(), {{0, 0}, {1, 1}});
         s.mutable_path()->set_approximation_error(nan);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].path.approximation_error is NaN"},
      {upsert([&](auto& s) {
         SetPoint({1, 1}, s.mutable_point());
         s.set_additive_weight(-0.5);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].additive_weight is -0.5"},
      {upsert([&](auto& s) {
         SetPoint({1, 1}, s.mutable_point());
         s.set_multiplicative_weight(1e7);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].multiplicative_weight is 1e+07"},
      {upsert([&](auto& s) {
         SetPoint({1, 1}, s.mutable_point());
         s.set_max_distance(INFINITY);
       }),
       StatusCode::INVALID_ARGUMENT, "sites[1].max_distance is inf"},
      {upsert([&](auto& s) {
         SetPoint({1e308, 0}, s.mutable_segment()->mutable_a());
         SetPoint({-1e308, 0}, s.mutable_segment()->mutable_b());
       }),
       StatusCode::INVALID_ARGUMENT, "overflows a double"},
  };
  // A durability no release has: refused by name, whatever the sites.
  {
    v1::UpsertSitesRequest r;
    r.set_scene_id("bad");
    r.set_durability(static_cast<v1::Durability>(7));
    SetPoint({1, 1}, r.add_sites()->mutable_point());
    r.mutable_sites(0)->set_id("fine");
    uint64_t version;
    cases.push_back({client_->UpsertSites(r, &version), StatusCode::INVALID_ARGUMENT,
                     "durability is 7; it must be DURABILITY_SYNC or DURABILITY_RELAXED"});
    cases.push_back({client_->DeleteSites("bad", {"keep"}, &version,
                                          static_cast<v1::Durability>(9)),
                     StatusCode::INVALID_ARGUMENT, "durability is 9"});
  }
  for (const Case& c : cases) {
    EXPECT_EQ(c.status.error_code(), c.code) << c.message << ": " << c.status.error_message();
    EXPECT_NE(c.status.error_message().find(c.message), std::string::npos)
        << "want \"" << c.message << "\" in \"" << c.status.error_message() << "\"";
  }
  v1::Scene scene;
  ASSERT_TRUE(client_->GetScene("bad", &scene).ok());
  EXPECT_EQ(scene.version(), before);
  EXPECT_EQ(scene.site_count(), 1u);
}

TEST_F(SitesServerTest, RenderImageEncodesLayers) {
  Create("image", v1::DIAGRAM_NEAREST, v1::RENDER_MODE_MESH);
  uint64_t version = Upsert("image", MixedSites(5));
  auto render = [&](v1::RenderImageRequest::Layer layer, v1::RenderImageRequest::Format format,
                    v1::RenderImageResponse* out) {
    v1::RenderImageRequest r;
    r.set_scene_id("image");
    r.set_layer(layer);
    r.set_format(format);
    r.set_min_version(version);
    return client_->RenderImage(r, out);
  };
  v1::RenderImageResponse png, exr, features;
  ASSERT_TRUE(render(v1::RenderImageRequest::LAYER_IDS, v1::RenderImageRequest::FORMAT_PNG, &png).ok());
  EXPECT_EQ(png.image().substr(1, 3), "PNG");
  EXPECT_EQ(png.mime_type(), "image/png");
  EXPECT_EQ(png.width_px(), 512u);
  EXPECT_EQ(png.version(), version);
  ASSERT_TRUE(render(v1::RenderImageRequest::LAYER_DISTANCE, v1::RenderImageRequest::FORMAT_EXR, &exr).ok());
  EXPECT_EQ(exr.image().substr(0, 4), std::string("\x76\x2f\x31\x01", 4));  // OpenEXR magic
  ASSERT_TRUE(render(v1::RenderImageRequest::LAYER_FEATURES, v1::RenderImageRequest::FORMAT_PNG, &features).ok());
  EXPECT_NE(features.image(), png.image());
  v1::RenderImageResponse bad;
  auto st = render(v1::RenderImageRequest::LAYER_IDS, v1::RenderImageRequest::FORMAT_EXR, &bad);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("FORMAT_EXR holds the LAYER_DISTANCE layer only"), std::string::npos);
  v1::RenderImageRequest r;
  r.set_scene_id("image");
  r.mutable_window()->set_min_x(20);
  r.mutable_window()->set_max_x(30);
  r.mutable_window()->set_max_y(1);
  st = client_->RenderImage(r, &bad);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("holds no pixel centre"), std::string::npos);
  r.set_scene_id("nope");
  EXPECT_EQ(client_->RenderImage(r, &bad).error_code(), StatusCode::NOT_FOUND);
}

// SITE_INDEX: each pixel of a window names its site through the response's site_ids, and
// that site is the exact nearest at the pixel's centre (within float arithmetic), also
// beside one-sided polygons, where the frame holds a site that is no candidate.
TEST_F(SitesServerTest, SiteIndexImagesNameEachPixelsNearestSite) {
  std::vector<Site> sites = MixedSites(11);
  for (Site& s : sites) s.max_distance = INFINITY;  // every pixel has a site
  Create("index", v1::DIAGRAM_NEAREST, v1::RENDER_MODE_EXACT);
  const uint64_t version = Upsert("index", sites);
  v1::RenderImageRequest r;
  r.set_scene_id("index");
  r.set_layer(v1::RenderImageRequest::LAYER_SITE_INDEX);
  r.set_min_version(version);
  r.mutable_window()->set_min_x(2.01);
  r.mutable_window()->set_min_y(3);
  r.mutable_window()->set_max_x(8.3);
  r.mutable_window()->set_max_y(7.1);
  v1::RenderImageResponse image;
  auto st = client_->RenderImage(r, &image);
  ASSERT_TRUE(st.ok()) << st.error_message();
  // Pixels of 10/512 whose centres lie in the window: columns 103 to 424, rows 154 to 363.
  const double px = 10.0 / 512;
  EXPECT_EQ(image.width_px(), 322u);
  EXPECT_EQ(image.height_px(), 210u);
  EXPECT_DOUBLE_EQ(image.window().min_x(), 103 * px);
  EXPECT_DOUBLE_EQ(image.window().max_x(), 425 * px);
  EXPECT_DOUBLE_EQ(image.window().min_y(), 154 * px);
  EXPECT_DOUBLE_EQ(image.window().max_y(), 364 * px);

  testing::Pixels8 decoded;
  std::string error;
  ASSERT_TRUE(testing::ReadPngRgb(image.image(), &decoded, &error)) << error;
  ASSERT_EQ(decoded.file_channels, 3);
  ASSERT_EQ(decoded.width, int(image.width_px()));
  ASSERT_EQ(decoded.height, int(image.height_px()));
  const std::vector<uint8_t>& rgb = decoded.v;
  std::set<std::string> named;
  int failures = 0;
  for (uint32_t row = 0; row < image.height_px(); ++row) {
    for (uint32_t col = 0; col < image.width_px(); ++col) {
      const uint8_t* p = &rgb[(size_t{row} * image.width_px() + col) * 3];
      const uint32_t index = uint32_t{p[0]} << 16 | uint32_t{p[1]} << 8 | p[2];
      ASSERT_GE(index, 1u) << col << "," << row;
      ASSERT_LE(index, uint32_t(image.site_ids_size())) << col << "," << row;
      const std::string& id = image.site_ids(int(index - 1));
      named.insert(id);
      // Row 0 is the top of the image.
      const Vec2 q{image.window().min_x() + (col + 0.5) * px,
                   image.window().max_y() - (row + 0.5) * px};
      // The image is the raster's, curves as drawn (their flattenings), but where the site
      // drawn is no candidate (beyond a side or max_distance, within the drawing margin) the
      // exact best site, measured to the true curves.
      const oracle::Best truth = oracle::BestSite(q, sites, Diagram::kNearest, /*drawn=*/true);
      const Site& s = sites[std::stoi(id.substr(1))];
      const double value = oracle::Value(q, s, /*drawn=*/true);
      if (!(value <= truth.value + 1e-5) &&
          !(oracle::Value(q, s) <= oracle::BestSite(q, sites).value + 1e-5) && ++failures < 10) {
        ADD_FAILURE() << "pixel " << col << "," << row << " at (" << q.x << "," << q.y << ") names "
                      << id << " at " << value << "; nearest is s" << truth.index << " at "
                      << truth.value;
      }
    }
  }
  EXPECT_EQ(failures, 0);
  // Each site listed is named by some pixel, once.
  EXPECT_EQ(named.size(), size_t(image.site_ids_size()));

  // A zoom window: the same window rendered at 8 times the scene's resolution names the
  // nearest site at each of its own pixels' centres, finer than the scene's raster can.
  r.set_width_px(8 * 64);
  r.set_height_px(8 * 48);
  r.mutable_window()->set_min_x(103 * px);
  r.mutable_window()->set_max_x(167 * px);
  r.mutable_window()->set_min_y(154 * px);
  r.mutable_window()->set_max_y(202 * px);
  v1::RenderImageResponse zoomed;
  st = client_->RenderImage(r, &zoomed);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(zoomed.width_px(), 8u * 64);
  ASSERT_EQ(zoomed.height_px(), 8u * 48);
  EXPECT_DOUBLE_EQ(zoomed.window().min_x(), 103 * px);
  EXPECT_DOUBLE_EQ(zoomed.window().max_y(), 202 * px);
  testing::Pixels8 zoomed_decoded;
  ASSERT_TRUE(testing::ReadPngRgb(zoomed.image(), &zoomed_decoded, &error)) << error;
  ASSERT_EQ(zoomed_decoded.width, int(zoomed.width_px()));
  ASSERT_EQ(zoomed_decoded.height, int(zoomed.height_px()));
  const std::vector<uint8_t>& zrgb = zoomed_decoded.v;
  const double zpx = px / 8;
  int finer = 0;  // pixels whose site is not the one at the centre of their scene pixel
  for (uint32_t row = 0; row < zoomed.height_px(); ++row) {
    for (uint32_t col = 0; col < zoomed.width_px(); ++col) {
      const uint8_t* p = &zrgb[(size_t{row} * zoomed.width_px() + col) * 3];
      const uint32_t index = uint32_t{p[0]} << 16 | uint32_t{p[1]} << 8 | p[2];
      ASSERT_GE(index, 1u) << col << "," << row;
      ASSERT_LE(index, uint32_t(zoomed.site_ids_size())) << col << "," << row;
      const Site& s = sites[std::stoi(zoomed.site_ids(int(index - 1)).substr(1))];
      const Vec2 q{zoomed.window().min_x() + (col + 0.5) * zpx,
                   zoomed.window().max_y() - (row + 0.5) * zpx};
      const oracle::Best truth = oracle::BestSite(q, sites, Diagram::kNearest, /*drawn=*/true);
      if (!(oracle::Value(q, s, /*drawn=*/true) <= truth.value + 1e-5) &&
          !(oracle::Value(q, s) <= oracle::BestSite(q, sites).value + 1e-5) && ++failures < 10) {
        ADD_FAILURE() << "zoomed pixel " << col << "," << row << " names " << s.id
                      << "; nearest is s" << truth.index;
      }
      const Vec2 coarse{zoomed.window().min_x() + (col / 8 + 0.5) * px,
                        zoomed.window().max_y() - (row / 8 + 0.5) * px};
      if (&s != &sites[oracle::BestSite(coarse, sites, Diagram::kNearest, true).index]) ++finer;
    }
  }
  EXPECT_EQ(failures, 0);
  EXPECT_GT(finer, 200) << "the zoom shows no more than the scene's raster";
  r.clear_width_px();
  r.clear_height_px();

  // Numbers are not pictures: no sites drawn, no EXR.
  r.set_draw_sites(true);
  st = client_->RenderImage(r, &image);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("LAYER_SITE_INDEX takes neither draw_sites nor polyline"), std::string::npos)
      << st.error_message();
  r.set_draw_sites(false);
  r.set_format(v1::RenderImageRequest::FORMAT_EXR);
  st = client_->RenderImage(r, &image);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("FORMAT_EXR holds the LAYER_DISTANCE layer only"), std::string::npos);
}

// Pick returns the site it picked, as stored: a UI outlines it without another call.
TEST_F(SitesServerTest, PickReturnsTheSiteAsStored) {
  const std::vector<Site> sites = MixedSites(5);
  Create("picked", v1::DIAGRAM_NEAREST, v1::RENDER_MODE_MESH);
  Upsert("picked", sites);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 10);
  for (int k = 0; k < 200; ++k) {
    const Vec2 q{u(rng), u(rng)};
    v1::PickRequest r;
    r.set_scene_id("picked");
    SetPoint(q, r.mutable_point());
    v1::PickResponse p;
    ASSERT_TRUE(client_->Pick(r, &p).ok());
    ASSERT_TRUE(p.found());
    const Site& s = sites[std::stoi(p.site_id().substr(1))];
    v1::Site expected = ToProtoSite(s);
    if (expected.multiplicative_weight() == 1) expected.clear_multiplicative_weight();
    EXPECT_EQ(p.site().SerializeAsString(), expected.SerializeAsString())
        << p.site().DebugString() << " vs " << expected.DebugString();
  }
  v1::PickRequest far;
  far.set_scene_id("picked");
  SetPoint({5, 5}, far.mutable_point());
  far.set_max_distance(1e-9);
  v1::PickResponse none;
  ASSERT_TRUE(client_->Pick(far, &none).ok());
  EXPECT_FALSE(none.found());
  EXPECT_FALSE(none.has_site());
}

}  // namespace
}  // namespace gvd
