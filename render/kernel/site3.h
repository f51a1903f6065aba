// The 3D kernel's sites (render/kernel/kernel3.h): an id, a geometry of one of space's kinds,
// weights and a reach, beside the plane's (site2.h). A 3D scene samples a box of space slice
// by slice (Hoff et al., sec. 4.2); its sites are points, segments, triangles and triangle
// meshes, each made of features: faces, edges and vertices.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "render/kernel/site2.h"
#include "render/kernel/triangle_tree.h"
#include "render/kernel/vec.h"

namespace gvd {

class MeshRegions;  // mesh_regions.h

// An axis-aligned box of space; valid when min < max on every axis and all values are
// finite.
struct Box3 {
  double min_x = 0, min_y = 0, min_z = 0;
  double max_x = 0, max_y = 0, max_z = 0;

  bool Contains(Vec3 p) const {
    return p.x >= min_x && p.x <= max_x && p.y >= min_y && p.y <= max_y && p.z >= min_z &&
           p.z <= max_z;
  }
  bool operator==(const Box3&) const = default;
};

struct PointSite3 {
  Vec3 p;
};

// A closed segment; a == b is allowed (it is then a point).
struct SegmentSite3 {
  Vec3 a, b;
};

// A closed triangle; degenerate ones (collinear or coincident corners) are allowed, and are
// then the segments or the point they span.
struct TriangleSite3 {
  Vec3 a, b, c;
};

// A triangle mesh: the union of its closed triangles, each three indices into `vertices`.
// Its features are its faces (triangle i), its edges (each undirected edge once, numbered in
// the order the triangles first name them: a triangle (u, v, w) names (u, v), (v, w), (w, u))
// and its vertices (by index; a vertex that no triangle uses is no part of the mesh).
// Made by MakeMesh (exact3.h), which checks it and fills the edge tables.
struct MeshSite3 {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  // Filled by MakeMesh: the mesh's edges (lower vertex index first), and for triangle i the
  // edges it names, in the order above.
  std::vector<std::array<uint32_t, 2>> edges;
  std::vector<std::array<uint32_t, 3>> triangle_edges;
  // Filled by MakeMesh: the triangles' hierarchy of boxes, shared by the mesh's copies.
  std::shared_ptr<const TriangleTree> tree;
  // Filled by MakeMesh: its features' regions (mesh_regions.h), shared likewise.
  std::shared_ptr<const MeshRegions> regions;
};

// Every 3D site kind.
using Geometry3 = std::variant<PointSite3, SegmentSite3, TriangleSite3, MeshSite3>;

struct Site3 {
  std::string id;
  Geometry3 geometry;
  // As in 2D (site2.h): the site's value at q is multiplicative * d + additive; beyond
  // max_distance (in d) it has no influence.
  // CONTRACT: additive >= 0 and multiplicative > 0, both finite; max_distance > 0.
  double additive = 0;
  double multiplicative = 1;
  double max_distance = INFINITY;

  bool weighted() const { return additive != 0 || multiplicative != 1; }
  // Whether the site is a candidate everywhere at its plain distance.
  bool plain() const { return !weighted() && !std::isfinite(max_distance); }
};

}  // namespace gvd
