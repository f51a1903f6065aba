// The clearance field of a 3D scene (paper sec. 7.1, in space): at samples of a box, a proven
// lower bound on the distance to the nearest site, with its unit gradient and its site when
// asked, read off the scene's volume. The 2D field is planning.h's MakeClearanceField. Pure CPU
// work on the process's CPU pool; thread-safe.
#pragma once

#include <cstdint>

#include "render/kernel/grid3.h"
#include "render/scene/volume.h"

namespace gvd {

// Where a 3D clearance field is sampled: width x height x depth samples, sample (i, j, k) the
// centre of voxel first + (i, j, k) of `cells`, which is the scene's own grid (`own`: the
// volume's voxels, read as they are) or the grid of `box` at the samples' counts.
struct ClearanceSamples3 {
  Box3 box;  // the part of space the samples' cells cover
  uint32_t width = 0, height = 0, depth = 0;
  bool own = false;
  Grid3 cells;
  uint32_t first[3] = {0, 0, 0};
  uint64_t count() const { return uint64_t{width} * height * depth; }
  Vec3 At(uint32_t i, uint32_t j, uint32_t k) const {
    return cells.Center(first[0] + i, first[1] + j, first[2] + k);
  }
};

// Writes, for each sample in x, then y, then z order, the clearance into clearance[s]: the
// scene's voxels as they are (a stored value less its rounding slack bounds the distance
// from below, the render being exact per voxel), or each sample's answer from the volume less
// its bound (exact outside the box), rounded down to float; +infinity where no site is a
// candidate. Where given (non-null), also the unit gradient of the distance from the
// sample's site's nearest point (three floats a sample; zero where no site is) and the site
// (slot + 1, 0 for none).
// CONTRACT: the volume's diagram is kNearest; each output holds count() (gradient 3 count())
// values.
void ClearanceField3(const Volume& volume, const ClearanceSamples3& at, float* clearance,
                     float* gradient, uint32_t* slots);

}  // namespace gvd
