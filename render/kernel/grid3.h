// Space as the 3D kernel samples it: a box (site3.h) sampled at the centres of
// width x height x depth voxels, one slice per z (Hoff et al., sec. 4.2), and boxes of voxels.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "render/kernel/site3.h"
#include "render/kernel/vec.h"

namespace gvd {

// The voxels [x0, x1) x [y0, y1) x [z0, z1).
struct VoxelBox {
  uint32_t x0 = 0, y0 = 0, z0 = 0, x1 = 0, y1 = 0, z1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1 || z0 >= z1; }
  uint64_t volume() const { return empty() ? 0 : uint64_t{x1 - x0} * (y1 - y0) * (z1 - z0); }
  bool operator==(const VoxelBox&) const = default;
};

// Voxel (i, j, k) covers [min_x + i*vx, min_x + (i+1)*vx) x ... ; slice k = 0 is at min_z.
struct Grid3 {
  Box3 box;
  uint32_t width = 0;
  uint32_t height = 0;
  uint32_t depth = 0;

  Vec3 voxel_size() const {
    return {(box.max_x - box.min_x) / width, (box.max_y - box.min_y) / height,
            (box.max_z - box.min_z) / depth};
  }
  double voxel_diagonal() const { return Length(voxel_size()); }
  uint64_t voxel_count() const { return uint64_t{width} * height * depth; }
  uint64_t slice_size() const { return uint64_t{width} * height; }
  VoxelBox all() const { return {0, 0, 0, width, height, depth}; }

  Vec3 Center(uint32_t i, uint32_t j, uint32_t k) const {
    const Vec3 s = voxel_size();
    return {box.min_x + (i + 0.5) * s.x, box.min_y + (j + 0.5) * s.y, box.min_z + (k + 0.5) * s.z};
  }
  // The z of slice k's voxel centres.
  double SliceZ(uint32_t k) const { return box.min_z + (k + 0.5) * voxel_size().z; }
  // Continuous voxel coordinates of p: voxel centres sit at integer + 0.5.
  Vec3 ToVoxel(Vec3 p) const {
    const Vec3 s = voxel_size();
    return {(p.x - box.min_x) / s.x, (p.y - box.min_y) / s.y, (p.z - box.min_z) / s.z};
  }
  // The box spanned by the voxel centres of `b` (not empty).
  Box3 CentreBox(const VoxelBox& b) const {
    const Vec3 lo = Center(b.x0, b.y0, b.z0), hi = Center(b.x1 - 1, b.y1 - 1, b.z1 - 1);
    return {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z};
  }
};

// The distance from p to the nearest point of the box (0 inside).
inline double BoxDistance(const Box3& b, Vec3 p) {
  const Vec3 d(std::max({b.min_x - p.x, p.x - b.max_x, 0.0}),
               std::max({b.min_y - p.y, p.y - b.max_y, 0.0}),
               std::max({b.min_z - p.z, p.z - b.max_z, 0.0}));
  return Length(d);
}
// The distance between the nearest points of two boxes (0 when they meet).
inline double BoxDistance(const Box3& a, const Box3& b) {
  const Vec3 d(std::max({a.min_x - b.max_x, b.min_x - a.max_x, 0.0}),
               std::max({a.min_y - b.max_y, b.min_y - a.max_y, 0.0}),
               std::max({a.min_z - b.max_z, b.min_z - a.max_z, 0.0}));
  return Length(d);
}

}  // namespace gvd
