// A mesh's distance over a box of voxels, feature by feature: the paper's 3D method for a
// polyhedron (Hoff et al., sec. 4.2: a face is drawn over its prism, an edge over its wedge,
// a vertex over its cone), done on the CPU with exact distances. A voxel then scores the two
// or three triangles whose features can hold its nearest point, rather than the tens that a
// search of the mesh's tree meets away from the surface (there the sphere about the voxel
// grazes many triangles at nearly the same distance).
//
// The regions, and why they are enough. Let p be a point, x a point of the mesh nearest to
// p, and T a triangle holding x. Then x is the nearest point of every triangle holding x.
//  - If x lies inside T's face, p lies in T's prism: the closed prism of points whose
//    projection on T's plane falls in T (three half-spaces through T's edges).
//  - If x lies inside an edge e of T, p lies in e's slab (between the planes through its ends
//    normal to it) and, for every triangle T' naming e, beyond e in T''s plane (the
//    half-space bounded by the plane through e normal to T'): e's wedge.
//  - If x is a vertex v, then (p - v).(w - v) <= 0 for every edge vw: v's cone.
// (A degenerate triangle is the union of its edges, so x lies on one of them.) So the
// feature holding x has p in its region, and the mesh's distance at p is the least, over
// the features whose regions hold p, of the distance to a triangle naming the feature: each
// is the distance to a point of the mesh (never below the truth), and the one of the feature
// holding x is the truth.
//
// Rounding. A half-space's unit normal is made only from an edge at least 2^-20 of the
// coordinates' magnitude M long and, for a face or a wedge's side, from a triangle whose
// first corner's angle has a sine of at least 2^-20; so the normal is off by far less than
// 2^-30. Every half-space is tested grown by a margin of 2^-24 of the magnitude of the
// coordinates involved (the mesh's and the query's), far above that error times the
// distances involved and the rounding of the test. A constraint that fails those conditions
// is left out (a region only grows), and a face or an edge with none of its own is a
// candidate everywhere. Grown regions are slower, never wrong.
//
// Which triangle scores which feature. A face is scored by its triangle; an edge and a vertex
// by the first triangle naming them (their owner). Every triangle within distance U of a
// box's points, U the greatest distance from a point of the box to the mesh, is found by
// the tree; the owner of the feature holding a point's nearest x holds x, so lies within U.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "render/kernel/grid3.h"
#include "render/kernel/site3.h"

namespace gvd {

// Immutable once built (by MakeMesh, exact3.h, beside the mesh's tree); queries are safe
// from any thread.
class MeshRegions {
 public:
  // The regions of `mesh`'s features (its vertices, triangles and edge tables filled).
  explicit MeshRegions(const MeshSite3& mesh);

  size_t bytes() const {
    return sizeof(*this) + (triangle_first_.size() + feature_first_.size()) * sizeof(uint32_t) +
           half_spaces_.size() * sizeof(HalfSpace);
  }

  // When the features a box's voxels test exceed this, the box is scored voxel by voxel
  // through the tree (a mesh of slivers or a triangle soup, whose regions are wide).
  static constexpr size_t kMaxFeatures = 96;

  // The mesh's distance at each voxel centre of `box` (not empty), x fastest, then y, then z,
  // into out[0, box.volume()): the least of TriangleDistance (exact3.h) over the triangles
  // whose features' regions hold the centre, which is the least over all the triangles up to
  // a choice among triangles tied within rounding.
  static void Distances(const MeshSite3& mesh, const Grid3& grid, const VoxelBox& box,
                        double* out);

 private:
  struct HalfSpace {
    Vec3 n;    // unit, or 0 for none
    double c;  // a point p lies inside when n.p + c >= 0
  };
  // The half-spaces of feature f: half_spaces_[feature_first_[f], feature_first_[f + 1]).
  // The features triangle t scores: [triangle_first_[t], triangle_first_[t + 1]).
  std::vector<uint32_t> triangle_first_;
  std::vector<uint32_t> feature_first_;
  std::vector<HalfSpace> half_spaces_;
  double magnitude_ = 0;  // the largest coordinate's magnitude among the vertices
};

}  // namespace gvd
