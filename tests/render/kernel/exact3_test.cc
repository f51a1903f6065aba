// The 3D kernel's exact functions (render/kernel/exact3.h) against the tests' own oracle
// (tests/support/oracle3.h), on random and adversarial input: points on the sites and on
// their planes, degenerate triangles and zero-length segments, huge and tiny coordinates,
// closed and open meshes. Each nearest point is checked for what it claims: its distance, that
// it lies on the feature it names, and that the feature is where the distance is attained.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

#include "render/kernel/exact3.h"
#include "render/scene/site_index.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"

namespace gvd {
namespace {

using oracle3::Real;

// The corners of a triangle (or a segment's ends, repeated) that a feature names.
struct Feature {
  std::vector<Vec3> corners;  // 1: a vertex, 2: an edge, 3: a face
};

Feature FeatureOf(const Geometry3& g, const Hit3& h) {
  auto corners = [&](std::vector<Vec3> all, const std::vector<std::vector<int>>& edges) {
    if (h.kind == FeatureKind::kVertex) return Feature{{all.at(h.index)}};
    if (h.kind == FeatureKind::kEdge) {
      const auto& e = edges.at(h.index);
      return Feature{{all[e[0]], all[e[1]]}};
    }
    EXPECT_EQ(h.index, 0u);
    return Feature{all};
  };
  if (const auto* p = std::get_if<PointSite3>(&g)) return corners({p->p}, {});
  if (const auto* s = std::get_if<SegmentSite3>(&g)) return corners({s->a, s->b}, {{0, 1}});
  if (const auto* t = std::get_if<TriangleSite3>(&g)) {
    return corners({t->a, t->b, t->c}, {{0, 1}, {1, 2}, {2, 0}});
  }
  const auto& m = std::get<MeshSite3>(g);
  if (h.kind == FeatureKind::kVertex) return {{m.vertices.at(h.index)}};
  if (h.kind == FeatureKind::kEdge) {
    const auto& e = m.edges.at(h.index);
    return {{m.vertices[e[0]], m.vertices[e[1]]}};
  }
  const auto& t = m.triangles.at(h.index);
  return {{m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]}};
}

// Checks one answer against the oracle; `scale` is the size of the configuration, which the
// tolerance follows.
void Check(Vec3 q, const Geometry3& g, double scale) {
  SCOPED_TRACE(::testing::Message() << "q = (" << q.x << ", " << q.y << ", " << q.z << ")");
  const Hit3 h = NearestFeature(q, g);
  const Real want = oracle3::ToGeometry(q, g);
  const Real tol = 1e-12L * scale;
  ASSERT_NEAR(h.distance, want, tol);
  EXPECT_EQ(ExactDistance(q, g), h.distance);
  // The closest point is where it says: at that distance from q, on the site, on its feature.
  EXPECT_NEAR(oracle3::Norm(oracle3::Sub(oracle3::Of(q), oracle3::Of(h.closest))), want, tol);
  EXPECT_NEAR(oracle3::ToGeometry(h.closest, g), 0, tol);
  const Feature f = FeatureOf(g, h);
  const oracle3::P toward = oracle3::Sub(oracle3::Of(q), oracle3::Of(h.closest));
  if (f.corners.size() == 1) {
    EXPECT_EQ(h.closest, f.corners[0]);
  } else if (f.corners.size() == 2) {
    EXPECT_NEAR(oracle3::ToSegment(h.closest, f.corners[0], f.corners[1]), 0, tol);
    // The edge's interior: q - closest is normal to the edge.
    const oracle3::P e = oracle3::Sub(oracle3::Of(f.corners[1]), oracle3::Of(f.corners[0]));
    EXPECT_NEAR(oracle3::Dot(toward, e) / oracle3::Norm(e), 0, tol);
  } else {
    EXPECT_NEAR(oracle3::ToTriangle(h.closest, f.corners[0], f.corners[1], f.corners[2]), 0, tol);
    // The face's interior: q - closest is normal to the face.
    const oracle3::P n = oracle3::Cross(oracle3::Sub(oracle3::Of(f.corners[1]), oracle3::Of(f.corners[0])),
                                        oracle3::Sub(oracle3::Of(f.corners[2]), oracle3::Of(f.corners[0])));
    EXPECT_NEAR(oracle3::Norm(oracle3::Cross(toward, n)) / oracle3::Norm(n), 0, tol);
  }
  // The gradient: unit, pointing from the closest point to q (so it is (q - closest) / d).
  // For a convex site (a point, a segment, a triangle) the distance then grows along it at
  // rate 1 however far q goes, as q's nearest point stays where it is.
  if (h.distance > 0) {
    EXPECT_NEAR(Length(h.gradient), 1, 1e-12);
    EXPECT_NEAR(glm::dot(h.gradient, q - h.closest), h.distance, tol);
    if (!std::holds_alternative<MeshSite3>(g)) {
      const Vec3 further = q + h.gradient * (0.5 * h.distance);
      EXPECT_NEAR(oracle3::ToGeometry(further, g), 1.5L * want, 4 * tol);
    }
  } else {
    EXPECT_EQ(h.gradient, Vec3(0));
  }
}

Vec3 Random(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return {u(rng), u(rng), u(rng)};
}

// Query points for a set of corners: random ones around them, the corners themselves, points
// of the edges and the face, points on the plane outside, and points straight above edges.
std::vector<Vec3> Queries(std::mt19937_64& rng, const std::vector<Vec3>& corners, double scale) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> qs;
  for (int i = 0; i < 30; ++i) qs.push_back(Random(rng, -2 * scale, 2 * scale));
  for (Vec3 c : corners) qs.push_back(c);
  for (size_t i = 0; i < corners.size(); ++i) {
    const Vec3 a = corners[i], b = corners[(i + 1) % corners.size()];
    const double t = u(rng);
    qs.push_back(a + t * (b - a));                         // on an edge
    qs.push_back(a + 1.5 * (b - a));                       // beyond a corner, on the edge's line
    qs.push_back(a + t * (b - a) + Random(rng, -scale, scale) * 1e-9);  // a hair off it
  }
  if (corners.size() == 3) {
    const Vec3 n = glm::cross(corners[1] - corners[0], corners[2] - corners[0]);
    const double w1 = u(rng), w2 = u(rng) * (1 - w1);
    const Vec3 inside = corners[0] + w1 * (corners[1] - corners[0]) + w2 * (corners[2] - corners[0]);
    qs.push_back(inside);
    if (Length(n) > 0) {
      qs.push_back(inside + n / Length(n) * scale * 0.3);
      qs.push_back(inside - n / Length(n) * scale * 1e-7);
    }
    // On the plane, outside the triangle.
    qs.push_back(corners[0] + 2.0 * (corners[1] - corners[0]) + 2.0 * (corners[2] - corners[0]));
    qs.push_back(corners[0] - (corners[1] - corners[0]) * 0.5 - (corners[2] - corners[0]) * 0.5);
  }
  return qs;
}

TEST(Exact3, TrianglesSegmentsAndPointsAgainstTheOracle) {
  std::mt19937_64 rng(303);
  for (double scale : {1.0, 1e-150, 1e150}) {
    for (int trial = 0; trial < 300; ++trial) {
      const Vec3 a = Random(rng, -scale, scale), b = Random(rng, -scale, scale),
                 c = Random(rng, -scale, scale);
      for (Vec3 q : Queries(rng, {a, b, c}, scale)) {
        Check(q, TriangleSite3{a, b, c}, scale);
        Check(q, SegmentSite3{a, b}, scale);
        Check(q, PointSite3{a}, scale);
      }
    }
  }
}

TEST(Exact3, DegenerateTrianglesAndSegments) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 a = Random(rng, -1, 1), b = Random(rng, -1, 1);
    const double t = std::uniform_real_distribution<double>(-1, 2)(rng);
    const std::vector<TriangleSite3> degenerate = {
        {a, b, a + t * (b - a)},  // collinear
        {a, a, b},                // two corners at one place
        {a, b, b},
        {a, a, a},                // one point
        {a, b, a + (b - a) * 0.5 + Random(rng, -1, 1) * 1e-13},  // a sliver
    };
    for (const auto& tri : degenerate) {
      for (Vec3 q : Queries(rng, {tri.a, tri.b, tri.c}, 1)) Check(q, tri, 1);
    }
    for (Vec3 q : Queries(rng, {a, a}, 1)) Check(q, SegmentSite3{a, a}, 1);
  }
}

TEST(Exact3, MeshesClosedAndOpen) {
  for (int levels : {0, 1, 2}) {
    const MeshSite3 sphere = Icosphere(levels);
    // Euler: V - E + F = 2 for a closed genus-0 mesh; each edge is named by two faces.
    const size_t v = sphere.vertices.size(), e = sphere.edges.size(), f = sphere.triangles.size();
    EXPECT_EQ(v + f, e + 2) << levels;
    std::multiset<uint32_t> named;
    for (const auto& te : sphere.triangle_edges) named.insert(te.begin(), te.end());
    for (uint32_t i = 0; i < e; ++i) EXPECT_EQ(named.count(i), 2u) << "edge " << i;
  }
  std::mt19937_64 rng(11);
  const MeshSite3 sphere = Icosphere(2);
  for (int i = 0; i < 400; ++i) {
    Vec3 q = Random(rng, -2, 2);
    if (i % 4 == 0) q = sphere.vertices[rng() % sphere.vertices.size()] * 1.3;  // above a vertex
    if (i % 4 == 1) q *= 1e-3;                                                  // deep inside
    Check(q, sphere, 2);
  }
  // An open mesh: a bumpy 6x6 grid patch, a triangle of it repeated, one edge left out of
  // every triangle's neighbour (the outer rim).
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 6; ++x) xyz.insert(xyz.end(), {double(x), double(y), std::sin(x * 1.3 + y)});
  }
  for (uint32_t y = 0; y < 5; ++y) {
    for (uint32_t x = 0; x < 5; ++x) {
      const uint32_t i = y * 6 + x;
      tri.insert(tri.end(), {i, i + 1, i + 7, i, i + 7, i + 6});
    }
  }
  tri.insert(tri.end(), {0, 1, 7});  // a face twice
  auto patch = MakeMesh(xyz, tri, 1000);
  ASSERT_TRUE(patch.ok()) << patch.status();
  EXPECT_EQ(patch->triangles.size(), 51u);
  EXPECT_EQ(patch->edges.size(), 5u * 6 * 2 + 25u);  // rows, columns and diagonals
  for (int i = 0; i < 400; ++i) Check(Random(rng, -2, 7), *patch, 8);
}

TEST(Exact3, BadMeshesAreRefusedByName) {
  const std::vector<double> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  auto status = [](const absl::StatusOr<MeshSite3>& m) { return m.status().ToString(); };
  EXPECT_TRUE(MakeMesh(xyz, {0, 1, 2}, 1).ok());
  EXPECT_EQ(status(MakeMesh(xyz, {0, 1, 3}, 1)),
            "INVALID_ARGUMENT: triangles[2] is 3, past the 3 vertices");
  EXPECT_EQ(status(MakeMesh({0, 0, 0, 1, 0, NAN, 0, 1, 0}, {0, 1, 2}, 1)),
            "INVALID_ARGUMENT: xyz[5] is nan");
  EXPECT_EQ(status(MakeMesh(xyz, {0, 1, 2, 2, 1, 0}, 1)),
            "INVALID_ARGUMENT: triangles holds 2 triangles, over the limit of 1");
  EXPECT_EQ(status(MakeMesh(xyz, {}, 1)),
            "INVALID_ARGUMENT: triangles has 0 indices; it must hold three a triangle, at least one");
  EXPECT_EQ(status(MakeMesh({0, 0}, {0, 1, 2}, 1)),
            "INVALID_ARGUMENT: xyz has 2 values; it must hold three a vertex");
}

TEST(Exact3, BoxesAndFarthestDistances) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  const MeshSite3 sphere = Icosphere(1);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 lo = Random(rng, -3, 3);
    const Vec3 hi = lo + Random(rng, 0.01, 2);
    const Box3 box{lo.x, lo.y, lo.z, hi.x, hi.y, hi.z};
    const Vec3 a = Random(rng, -3, 3), b = Random(rng, -3, 3), c = Random(rng, -3, 3);
    for (const Geometry3& g :
         std::vector<Geometry3>{PointSite3{a}, SegmentSite3{a, b}, TriangleSite3{a, b, c}, sphere}) {
      // Every point of the box, its corners included, is within the bound.
      const double bound = FarthestDistance(box, g);
      for (int i = 0; i < 40; ++i) {
        const Vec3 q = i < 8 ? Vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z)
                             : lo + (hi - lo) * Vec3(u(rng), u(rng), u(rng));
        EXPECT_LE(oracle3::ToGeometry(q, g), bound * (1 + 1e-15));
      }
      // The box around the site holds it, and touches it on every face.
      const Box3 around = BoundingBox(g);
      for (Vec3 q : Queries(rng, {a, b, c}, 3)) {
        const Hit3 h = NearestFeature(q, g);
        EXPECT_TRUE(around.Contains(h.closest));
      }
    }
    // For a point, the bound is the farthest corner's distance.
    Real far = 0;
    for (int i = 0; i < 8; ++i) {
      const Vec3 corner(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
      far = std::max(far, oracle3::ToGeometry(corner, PointSite3{a}));
    }
    EXPECT_NEAR(FarthestDistance(box, PointSite3{a}), far, 1e-14);
  }
}

TEST(Exact3, SiteValuesFollowTheWeights) {
  Site3 site{"s", TriangleSite3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, 2, 3, 0.5};
  EXPECT_EQ(SiteValue({0.25, 0.25, 0.25}, site), 3 * 0.25 + 2);
  EXPECT_EQ(SiteValue({0.25, 0.25, 0.75}, site), INFINITY);  // beyond max_distance
  EXPECT_FALSE(site.plain());
  EXPECT_TRUE((Site3{"p", PointSite3{}}.plain()));
}

// The slot table and the spatial index on the 3D kernel: the exact nearest site of a changing
// set of points, segments, triangles and meshes, against a scan with the oracle.
TEST(SiteIndex3, NearestAgainstAScanThroughChanges) {
  std::mt19937_64 rng(99);
  const MeshSite3 sphere = Icosphere(1);
  auto random_site = [&](int i) {
    Site3 s;
    s.id = std::to_string(i);
    const Vec3 a = Random(rng, 0, 10);
    switch (rng() % 4) {
      case 0: s.geometry = PointSite3{a}; break;
      case 1: s.geometry = SegmentSite3{a, a + Random(rng, -1, 1)}; break;
      case 2: s.geometry = TriangleSite3{a, a + Random(rng, -1, 1), a + Random(rng, -1, 1)}; break;
      default: {
        s.geometry = Placed(sphere, a, 0.5);
      }
    }
    return s;
  };
  SlotTable3 table;
  std::vector<uint32_t> all;
  for (int i = 0; i < 300; ++i) {
    table.Set(static_cast<uint32_t>(i), std::make_shared<const Site3>(random_site(i)));
    all.push_back(static_cast<uint32_t>(i));
  }
  SiteIndex3 index = SiteIndex3::Build(table);
  for (int round = 0; round < 6; ++round) {
    for (int i = 0; i < 200; ++i) {
      const Vec3 q = Random(rng, -2, 12);
      Real best = INFINITY;
      for (uint32_t s = 0; s < table.size(); ++s) {
        if (const Site3* site = table.get(s)) best = std::min(best, oracle3::ToGeometry(q, site->geometry));
      }
      const ExactNearest n = index.Nearest(q);
      ASSERT_TRUE(n.found());
      EXPECT_NEAR(n.distance, best, 1e-12);
      EXPECT_NEAR(oracle3::ToGeometry(q, table.get(n.index)->geometry), best, 1e-12);
    }
    // Move, replace and free some slots, and carry the index along.
    std::vector<uint32_t> changed;
    for (int k = 0; k < 40; ++k) {
      const uint32_t s = static_cast<uint32_t>(rng() % 300);
      table.Set(s, k % 5 == 0 ? std::shared_ptr<const Site3>()
                              : std::make_shared<const Site3>(random_site(1000 + k)));
      changed.push_back(s);
    }
    index = index.Update(table, changed);
  }
}

}  // namespace
}  // namespace gvd
