#include "render/kernel/mesh_regions.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "render/kernel/exact3.h"

namespace gvd {

namespace {

// The header's thresholds, relative to the coordinates' magnitude.
constexpr double kShortest = 0x1p-20;
constexpr double kMargin = 0x1p-24;

// The largest coordinate's magnitude of the box.
double Magnitude(Vec3 lo, Vec3 hi) {
  const Vec3 m = glm::max(glm::abs(lo), glm::abs(hi));
  return std::max({m.x, m.y, m.z});
}

}  // namespace

MeshRegions::MeshRegions(const MeshSite3& mesh) {
  const auto& vertices = mesh.vertices;
  const auto& triangles = mesh.triangles;
  for (const Vec3& v : vertices) {
    magnitude_ = std::max({magnitude_, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
  }
  const double shortest = kShortest * magnitude_;
  const uint32_t count = static_cast<uint32_t>(triangles.size());
  // Per triangle, whether its face has a region of its own, and the unit normals in its
  // plane of its edges k = (tri[k], tri[k + 1]), pointing into it.
  std::vector<uint8_t> shaped(count, 0);
  std::vector<std::array<Vec3, 3>> inward(count);
  for (uint32_t t = 0; t < count; ++t) {
    const auto& tri = triangles[t];
    const Vec3 a = vertices[tri[0]], b = vertices[tri[1]], c = vertices[tri[2]];
    const Vec3 ab = b - a, ac = c - a, n = glm::cross(ab, ac);
    if (Length(ab) < shortest || Length(ac) < shortest || Length(c - b) < shortest ||
        !(glm::dot(n, n) > 0x1p-40 * glm::dot(ab, ab) * glm::dot(ac, ac))) {
      continue;
    }
    shaped[t] = 1;
    const Vec3 unit = n / Length(n);
    for (int k = 0; k < 3; ++k) {
      const Vec3 u = vertices[tri[k]], v = vertices[tri[(k + 1) % 3]], w = vertices[tri[(k + 2) % 3]];
      Vec3 m = glm::cross(unit, v - u);
      m /= Length(m);
      inward[t][k] = glm::dot(m, w - u) < 0 ? -m : m;
    }
  }
  // Owners, and the triangles naming each edge and the edges at each vertex (CSR).
  const size_t edges = mesh.edges.size();
  std::vector<uint32_t> edge_owner(edges, UINT32_MAX), vertex_owner(vertices.size(), UINT32_MAX);
  std::vector<uint32_t> edge_first(edges + 1, 0), vertex_first(vertices.size() + 1, 0);
  for (uint32_t t = 0; t < count; ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t e = mesh.triangle_edges[t][k], v = triangles[t][k];
      if (edge_owner[e] == UINT32_MAX) edge_owner[e] = t;
      if (vertex_owner[v] == UINT32_MAX) vertex_owner[v] = t;
      ++edge_first[e + 1];
    }
  }
  for (const auto& e : mesh.edges) {
    ++vertex_first[e[0] + 1];
    ++vertex_first[e[1] + 1];
  }
  for (size_t e = 0; e < edges; ++e) edge_first[e + 1] += edge_first[e];
  for (size_t v = 0; v < vertices.size(); ++v) vertex_first[v + 1] += vertex_first[v];
  std::vector<std::pair<uint32_t, int>> edge_sides(edge_first.back());  // (triangle, k)
  std::vector<uint32_t> vertex_edges(vertex_first.back());
  {
    std::vector<uint32_t> fill(edge_first.begin(), edge_first.end() - 1);
    for (uint32_t t = 0; t < count; ++t) {
      for (int k = 0; k < 3; ++k) edge_sides[fill[mesh.triangle_edges[t][k]]++] = {t, k};
    }
    std::vector<uint32_t> at(vertex_first.begin(), vertex_first.end() - 1);
    for (uint32_t e = 0; e < edges; ++e) {
      vertex_edges[at[mesh.edges[e][0]]++] = e;
      vertex_edges[at[mesh.edges[e][1]]++] = e;
    }
  }
  auto add = [&](Vec3 n, Vec3 through) { half_spaces_.push_back({n, -glm::dot(n, through)}); };
  auto feature = [&] { feature_first_.push_back(static_cast<uint32_t>(half_spaces_.size())); };
  for (uint32_t t = 0; t < count; ++t) {
    const auto& tri = triangles[t];
    triangle_first_.push_back(static_cast<uint32_t>(feature_first_.size()));
    // The face's prism (everywhere for a face without a region of its own).
    feature();
    if (shaped[t]) {
      for (int k = 0; k < 3; ++k) add(inward[t][k], vertices[tri[k]]);
    }
    // The wedges of the edges it owns.
    for (int k = 0; k < 3; ++k) {
      const uint32_t e = mesh.triangle_edges[t][k];
      if (edge_owner[e] != t) continue;
      feature();
      const Vec3 u = vertices[mesh.edges[e][0]], v = vertices[mesh.edges[e][1]];
      const double length = Length(v - u);
      if (!(length >= shortest) || length == 0) continue;
      const Vec3 along = (v - u) / length;
      add(along, u);
      add(-along, v);
      for (uint32_t s = edge_first[e]; s < edge_first[e + 1]; ++s) {
        const auto [side, j] = edge_sides[s];
        if (shaped[side]) add(-inward[side][j], u);
      }
    }
    // The cones of the vertices it owns.
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = tri[k];
      if (vertex_owner[v] != t) continue;
      feature();
      for (uint32_t s = vertex_first[v]; s < vertex_first[v + 1]; ++s) {
        const auto& e = mesh.edges[vertex_edges[s]];
        const Vec3 d = vertices[e[0] == v ? e[1] : e[0]] - vertices[v];
        const double length = Length(d);
        if (length >= shortest && length > 0) add(-d / length, vertices[v]);
      }
    }
  }
  triangle_first_.push_back(static_cast<uint32_t>(feature_first_.size()));
  feature();
}

void MeshRegions::Distances(const MeshSite3& mesh, const Grid3& grid, const VoxelBox& box,
                            double* out) {
  const MeshRegions& regions = *mesh.regions;
  const uint32_t nx = box.x1 - box.x0, ny = box.y1 - box.y0;
  std::fill(out, out + box.volume(), INFINITY);
  const Box3 cb = grid.CentreBox(box);
  const Vec3 lo(cb.min_x, cb.min_y, cb.min_z), hi(cb.max_x, cb.max_y, cb.max_z);
  // Every point of the box is within `reach` of the mesh.
  const Vec3 centre = lo * 0.5 + hi * 0.5;
  const double reach =
      (MeshDistance(centre, mesh) + Length(hi - lo) / 2) * (1 + 0x1p-40) + 0x1p-50 * Magnitude(lo, hi);
  const double margin = kMargin * std::max(regions.magnitude_, Magnitude(lo, hi));
  // The features, with the triangle scoring each, whose regions (grown) meet the box.
  thread_local std::vector<std::pair<uint32_t, uint32_t>> live;
  live.clear();
  bool wide = false;
  mesh.tree->WithinBox(lo, hi, reach, [&](uint32_t t) {
    if (wide) return;
    for (uint32_t f = regions.triangle_first_[t]; f < regions.triangle_first_[t + 1]; ++f) {
      bool meets = true;
      for (uint32_t h = regions.feature_first_[f]; h < regions.feature_first_[f + 1] && meets; ++h) {
        const HalfSpace& s = regions.half_spaces_[h];
        const Vec3 far = glm::mix(lo, hi, glm::greaterThan(s.n, Vec3(0)));
        meets = glm::dot(s.n, far) + s.c + margin >= 0;
      }
      if (meets) live.emplace_back(f, t);
    }
    wide = live.size() > kMaxFeatures;
  });
  if (wide) {
    for (uint32_t k = box.z0; k < box.z1; ++k) {
      for (uint32_t j = box.y0; j < box.y1; ++j) {
        for (uint32_t i = box.x0; i < box.x1; ++i) {
          out[((k - box.z0) * ny + (j - box.y0)) * nx + (i - box.x0)] =
              MeshDistance(grid.Center(i, j, k), mesh);
        }
      }
    }
    return;
  }
  const Vec3 size = grid.voxel_size();
  for (const auto& [f, t] : live) {
    for (uint32_t k = box.z0; k < box.z1; ++k) {
      for (uint32_t j = box.y0; j < box.y1; ++j) {
        // The voxels of the row whose centres lie in every half-space (grown): for each,
        // n.x x + rest >= 0 bounds the centre's x = min_x + (i + 0.5) size.x on one side.
        const Vec3 row = grid.Center(box.x0, j, k);
        double first = box.x0, last = box.x1 - 1;
        for (uint32_t h = regions.feature_first_[f]; h < regions.feature_first_[f + 1]; ++h) {
          const HalfSpace& s = regions.half_spaces_[h];
          const double rest = s.n.y * row.y + s.n.z * row.z + s.c + margin;
          if (s.n.x == 0) {
            if (rest < 0) last = -1;
            continue;
          }
          const double at = (-rest / s.n.x - grid.box.min_x) / size.x - 0.5;
          if (s.n.x > 0) {
            first = std::max(first, std::ceil(at));
          } else {
            last = std::min(last, std::floor(at));
          }
        }
        if (!(first <= last)) continue;
        double* line = out + ((k - box.z0) * ny + (j - box.y0)) * nx - box.x0;
        for (uint32_t i = static_cast<uint32_t>(first); i <= static_cast<uint32_t>(last); ++i) {
          line[i] = std::min(line[i], TriangleDistance(grid.Center(i, j, k), mesh, t));
        }
      }
    }
  }
}

}  // namespace gvd
