// Meshes for the tests of 3D code: a closed sphere, a closed torus and an open wavy patch,
// each made through MakeMesh (render/kernel/exact3.h), as a scene's meshes are.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <utility>
#include <vector>

#include "render/kernel/exact3.h"

namespace gvd {

// MakeMesh's mesh of a valid input (the program stops, saying why, on an invalid one).
inline MeshSite3 Mesh(const std::vector<double>& xyz, const std::vector<uint32_t>& triangles) {
  auto mesh = MakeMesh(xyz, triangles, 1 << 22);
  if (!mesh.ok()) {
    std::fprintf(stderr, "bad test mesh: %s\n", mesh.status().ToString().c_str());
    std::abort();
  }
  return *std::move(mesh);
}

// The mesh's vertices scaled by `scale` and moved by `offset`, made anew (with its tree).
inline MeshSite3 Placed(const MeshSite3& m, Vec3 offset, double scale) {
  std::vector<double> xyz;
  for (Vec3 v : m.vertices) {
    const Vec3 w = offset + v * scale;
    xyz.insert(xyz.end(), {w.x, w.y, w.z});
  }
  std::vector<uint32_t> tri;
  for (const auto& t : m.triangles) tri.insert(tri.end(), t.begin(), t.end());
  return Mesh(xyz, tri);
}

// An icosahedron, subdivided `levels` times onto the unit sphere: a closed mesh.
inline MeshSite3 Icosphere(int levels) {
  const double p = (1 + std::sqrt(5.0)) / 2;
  std::vector<double> xyz = {-1, p, 0, 1, p, 0, -1, -p, 0, 1, -p, 0, 0, -1, p, 0, 1, p,
                             0, -1, -p, 0, 1, -p, p, 0, -1, p, 0, 1, -p, 0, -1, -p, 0, 1};
  std::vector<uint32_t> tri = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11,
                               4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6,
                               8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  for (int l = 0; l < levels; ++l) {
    std::vector<uint32_t> next;
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto middle = [&](uint32_t u, uint32_t v) {
      auto key = std::minmax(u, v);
      auto it = mid.find({key.first, key.second});
      if (it != mid.end()) return it->second;
      const uint32_t m = static_cast<uint32_t>(xyz.size() / 3);
      for (int k = 0; k < 3; ++k) xyz.push_back((xyz[3 * u + k] + xyz[3 * v + k]) / 2);
      mid[{key.first, key.second}] = m;
      return m;
    };
    for (size_t t = 0; t < tri.size(); t += 3) {
      const uint32_t a = tri[t], b = tri[t + 1], c = tri[t + 2];
      const uint32_t ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
      next.insert(next.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    tri = std::move(next);
  }
  for (size_t v = 0; v < xyz.size(); v += 3) {
    const double n = std::sqrt(xyz[v] * xyz[v] + xyz[v + 1] * xyz[v + 1] + xyz[v + 2] * xyz[v + 2]);
    for (int k = 0; k < 3; ++k) xyz[v + k] /= n;
  }
  return Mesh(xyz, tri);
}

// A torus around the z axis, radii R (to the tube's centre) and r (the tube's), n x m quads
// split in two: a closed mesh of genus one.
inline MeshSite3 Torus(double R, double r, int n, int m) {
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  const double pi = std::acos(-1.0);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double u = 2 * pi * i / n, v = 2 * pi * j / m;
      xyz.insert(xyz.end(), {(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                             r * std::sin(v)});
    }
  }
  auto at = [&](int i, int j) { return static_cast<uint32_t>((i % n) * m + j % m); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      tri.insert(tri.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      tri.insert(tri.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return Mesh(xyz, tri);
}

// An open patch over [0, 1]^2 of n x n quads split in two, z a gentle wave: a mesh with a
// boundary.
inline MeshSite3 Patch(int n) {
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = double(i) / n, y = double(j) / n;
      xyz.insert(xyz.end(), {x, y, 0.2 * std::sin(3 * x) * std::cos(2 * y)});
    }
  }
  auto at = [&](int i, int j) { return static_cast<uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      tri.insert(tri.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      tri.insert(tri.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return Mesh(xyz, tri);
}

}  // namespace gvd
