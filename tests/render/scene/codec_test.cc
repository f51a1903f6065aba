// The stored byte form of sites, settings and packs (render/scene/codec.h), byte for byte:
// stores written by any release must read the same, so the layout is pinned here. The
// oracle is the format as documented, written out field by field with a little-endian
// builder of this file's own, not the codec's writer.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "render/scene/codec.h"

namespace gvd {
namespace {

// The expected bytes, appended field by field.
class Bytes {
 public:
  Bytes& U8(uint8_t v) { return Raw(&v, 1); }
  Bytes& U32(uint32_t v) {
    for (int i = 0; i < 4; ++i) U8(static_cast<uint8_t>(v >> (8 * i)));
    return *this;
  }
  Bytes& F64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, 8);
    for (int i = 0; i < 8; ++i) U8(static_cast<uint8_t>(bits >> (8 * i)));
    return *this;
  }
  Bytes& Str(const std::string& s) {
    U32(static_cast<uint32_t>(s.size()));
    return Raw(s.data(), s.size());
  }
  Bytes& Points(const std::vector<Vec2>& points) {
    U32(static_cast<uint32_t>(points.size()));
    for (Vec2 p : points) F64(p.x).F64(p.y);
    return *this;
  }
  Bytes& P3(Vec3 p) { return F64(p.x).F64(p.y).F64(p.z); }
  // A site's header: format 1, its id, additive, multiplicative, max_distance.
  template <class S>
  Bytes& Header(const S& site) {
    return U8(1).Str(site.id).F64(site.additive).F64(site.multiplicative).F64(site.max_distance);
  }
  const std::string& str() const { return out_; }

 private:
  Bytes& Raw(const void* p, size_t n) {
    out_.append(static_cast<const char*>(p), n);
    return *this;
  }
  std::string out_;
};

Site Weighted(std::string id, Geometry g) {
  Site s{std::move(id), std::move(g)};
  s.additive = 0.25;
  s.multiplicative = 1.5;
  s.max_distance = 3.0;
  return s;
}

TEST(Codec, EachSiteKindIsItsDocumentedBytes) {
  const Site point = Weighted("p", PointSite{{1.5, -2.25}});
  EXPECT_EQ(EncodeSite(point), Bytes().Header(point).U8(1).F64(1.5).F64(-2.25).str());

  Site segment{"a segment id longer than a short string's buffer", SegmentSite{{0, 1}, {2, 3}}};
  EXPECT_EQ(EncodeSite(segment),
            Bytes().Header(segment).U8(2).F64(0).F64(1).F64(2).F64(3).str());
  EXPECT_TRUE(std::isinf(segment.max_distance));  // written as the infinity it is

  const Site polyline{"l", PolylineSite{{{0, 0}, {1, 0}, {1, 1}}}};
  EXPECT_EQ(EncodeSite(polyline),
            Bytes().Header(polyline).U8(3).Points({{0, 0}, {1, 0}, {1, 1}}).str());

  const Site polygon{"g", PolygonSite{{{0, 0}, {4, 0}, {0, 3}}, Side::kInside}};
  EXPECT_EQ(EncodeSite(polygon), Bytes()
                                     .Header(polygon)
                                     .U8(4)
                                     .U8(static_cast<uint8_t>(Side::kInside))
                                     .Points({{0, 0}, {4, 0}, {0, 3}})
                                     .str());

  const Site bezier{"b", BezierSite{{{0, 0}, {1, 2}, {2, 0}}, 0.125, {{0, 0}, {1, 1}, {2, 0}}}};
  EXPECT_EQ(EncodeSite(bezier), Bytes()
                                    .Header(bezier)
                                    .U8(5)
                                    .F64(0.125)
                                    .Points({{0, 0}, {1, 2}, {2, 0}})
                                    .Points({{0, 0}, {1, 1}, {2, 0}})
                                    .str());
}

TEST(Codec, SpaceSitesAreTheirDocumentedBytes) {
  Site3 point{"q", PointSite3{{1, 2, 3}}};
  EXPECT_EQ(EncodeSite(point), Bytes().Header(point).U8(6).P3({1, 2, 3}).str());

  Site3 segment{"s", SegmentSite3{{0, 0, 0}, {1, 1, 1}}};
  EXPECT_EQ(EncodeSite(segment), Bytes().Header(segment).U8(7).P3({0, 0, 0}).P3({1, 1, 1}).str());

  Site3 triangle{"t", TriangleSite3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  EXPECT_EQ(EncodeSite(triangle),
            Bytes().Header(triangle).U8(8).P3({0, 0, 0}).P3({1, 0, 0}).P3({0, 1, 0}).str());

  // A mesh: its vertices and triangles as arrays (a count, then the values), nothing else.
  MeshSite3 mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.triangles = {{0, 1, 2}, {0, 1, 3}};
  Site3 site{"m", mesh};
  Bytes expected;
  expected.Header(site).U8(9).U32(4);
  for (Vec3 v : mesh.vertices) expected.P3(v);
  expected.U32(2);
  for (const auto& t : mesh.triangles) expected.U32(t[0]).U32(t[1]).U32(t[2]);
  EXPECT_EQ(EncodeSite(site), expected.str());
}

TEST(Codec, APackIsEachSitesIdThenItsBytesAndReadsBackInOrder) {
  const Site a = Weighted("first", PointSite{{1, 2}});
  const Site b{"2", PolylineSite{{{0, 0}, {5, 5}}}};  // a one-byte id and an array
  std::string pack;
  AppendToPack(a, &pack);
  AppendToPack(b, &pack);
  const std::string a_bytes = Bytes().Header(a).U8(1).F64(1).F64(2).str();
  const std::string b_bytes = Bytes().Header(b).U8(3).Points({{0, 0}, {5, 5}}).str();
  EXPECT_EQ(pack, Bytes().Str("first").Str(a_bytes).Str("2").Str(b_bytes).str());

  auto entries = PackEntries(pack);
  ASSERT_TRUE(entries.ok()) << entries.status();
  ASSERT_EQ(entries->size(), 2u);
  EXPECT_EQ((*entries)[0].id, "first");
  EXPECT_EQ((*entries)[0].site, a_bytes);
  EXPECT_EQ((*entries)[1].id, "2");
  EXPECT_EQ((*entries)[1].site, b_bytes);
  auto decoded = DecodeSite<Site>((*entries)[1].site);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(std::get<PolylineSite>(decoded->geometry).points.size(), 2u);
}

TEST(Codec, SettingsAreTheirDocumentedBytes) {
  SceneSettings s;
  s.id = "scene";
  s.grid.window = {-1, -2, 3, 4};
  s.grid.width = 640;
  s.grid.height = 480;
  s.eps = 0.5;
  s.cone_triangles = 32;
  s.mode = RenderMode::kExact;
  s.diagram = Diagram::kFarthest;
  const std::string plane = Bytes()
                                .U8(1)
                                .Str("scene")
                                .F64(-1)
                                .F64(-2)
                                .F64(3)
                                .F64(4)
                                .U32(640)
                                .U32(480)
                                .F64(0.5)
                                .U32(32)
                                .U8(1)
                                .U8(1)
                                .str();
  EXPECT_EQ(EncodeSettings(s), plane);

  // A 3D scene's: format 2, the same fields, then its depth and z range.
  s.depth = 16;
  s.min_z = -5;
  s.max_z = 5;
  EXPECT_EQ(EncodeSettings(s), Bytes().U8(2).str() + plane.substr(1) +
                                   Bytes().U32(16).F64(-5).F64(5).str());
}

}  // namespace
}  // namespace gvd
