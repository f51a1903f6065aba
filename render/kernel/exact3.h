// Exact distance functions of the 3D kernel in double precision: distances, closest points,
// gradients and nearest features of the sites of site3.h, and the boxes around them.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "render/kernel/site3.h"

namespace gvd {

// The point of a site nearest to a query point q, and what it lies on.
// Features: a point is vertex 0; a segment's ends are vertices 0 (a) and 1 (b), its interior
// edge 0; a triangle's corners are vertices 0, 1, 2 (a, b, c), its edges 0 (ab), 1 (bc) and
// 2 (ca), its interior face 0; a mesh's are numbered as site3.h says. A degenerate triangle's
// nearest point is named by the edge or corner it lies on (it has no face).
struct Hit3 {
  double distance = 0;  // |q - closest|
  Vec3 closest;
  FeatureKind kind = FeatureKind::kVertex;
  uint32_t index = 0;
  // The unit gradient of the distance at q: UnitGradient(q, closest) (vec.h).
  Vec3 gradient;
};

// The nearest point of the closed segment ab (a == b allowed) to q.
Hit3 NearestOnSegment(Vec3 q, Vec3 a, Vec3 b);
// The nearest point of the closed triangle abc (degenerate ones allowed) to q.
Hit3 NearestOnTriangle(Vec3 q, Vec3 a, Vec3 b, Vec3 c);

// The nearest point of the geometry to q, and its feature (ties: the least feature, a mesh's
// triangles in order). A mesh's is found through its tree: O(log triangles) for a mesh of
// triangles of even size. `within`: only a mesh's features within that distance of q are
// looked for; when none is, the hit's distance is +inf (other sites' hits are exact).
Hit3 NearestFeature(Vec3 q, const Geometry3& g, double within = INFINITY);
double ExactDistance(Vec3 q, const Geometry3& g, double within = INFINITY);
// ExactDistance of a mesh; and the distance from q to its triangle t, as those score it.
double MeshDistance(Vec3 q, const MeshSite3& mesh, double within = INFINITY);
double TriangleDistance(Vec3 q, const MeshSite3& mesh, uint32_t t);
inline double ExactDistance(Vec3 q, const Site3& site) { return ExactDistance(q, site.geometry); }

// The site's value at q: multiplicative * d + additive, or +infinity beyond its max_distance.
double SiteValue(Vec3 q, const Site3& site);

// The smallest box holding the geometry (a mesh's: its triangles').
Box3 BoundingBox(const Geometry3& g);

// An upper bound on the distance from the geometry to any point of the box, exact for a
// point: the least, over the geometry's vertices, of the distance from the vertex to the
// box's farthest corner (every point of the box is within that of the vertex, a point of the
// site).
double FarthestDistance(const Box3& box, const Geometry3& g);

// A mesh from packed coordinates (x, y, z per vertex) and three vertex indices per triangle,
// with its edge tables filled; or INVALID_ARGUMENT naming the field and the value
// ("xyz[7] is nan", "triangles[5] is 12, past the 4 vertices", ...). A mesh needs at least
// one triangle, finite coordinates, and at most `max_triangles` triangles.
absl::StatusOr<MeshSite3> MakeMesh(const std::vector<double>& xyz,
                                   const std::vector<uint32_t>& triangles, size_t max_triangles);

}  // namespace gvd
