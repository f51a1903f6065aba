// The exact render of a 3D scene's volume, slice by slice, on the CPU pool: each voxel centre
// gets the best value among its brick's candidates, each computed exactly in double (the
// compute path of a 3D scene in kExact mode). The candidates come from the 3D coverage
// proof (below), so the work follows the diagram rather than sites x voxels; a change
// re-renders only the bricks it can alter, and the volume of the next version shares every
// slice it leaves unchanged.
//
// The coverage proof, in space (the 2D one's, render/plan/coverage.h, for bricks of voxels).
// Let B be a brick, C the box of its voxel centres, c its centre and r its half-diagonal. In
// kNearest, let s0 be the site nearest to c (by distance, from the index) at d0; if s0 is a
// candidate at every centre of C (d0 + r <= its max_distance) its value there is at most
// U = m0 (d0 + r) + a0, so the best value at every centre of C is at most U. A site s can be
// best at a centre p of C only if m_s d(p, s) + a_s <= U, so only if d(p, s) <= (U - a*) / m*
// (a*, m*: the least weights over the sites), so only if d(c, s) <= (U - a*) / m* + r: the
// index returns a superset of those, and each is kept only if m_s dist(C, box(s)) + a_s <= U
// and dist(C, box(s)) <= its max_distance. When s0 is not a candidate everywhere in C (U is
// infinite), and in kFarthest, every site is a candidate. Per voxel, the candidates are
// scored exactly (a mesh over the whole brick at once, feature by feature, the first time a
// voxel of the brick needs it: render/kernel/mesh_regions.h); the least value wins, ties
// going to the least slot, so that the result is the same whatever the candidate set, as
// long as it holds the best site.
//
// What a change can alter. A voxel's best site changes only if the site it holds was
// removed or replaced, or a site put by the change beats its stored value there. The first
// happens only in bricks where the old site's least possible value is at most the brick's
// greatest stored value (Volume::brick_extreme); within those, the voxels that hold the old
// site say so. The second happens only in bricks where the new site's least possible value
// is at most the brick's greatest stored value. Those bricks, and no others, are re-rendered
// (in kFarthest: every brick, as any change can alter the greatest value anywhere).
#pragma once

#include <cstdint>
#include <memory>

#include "render/kernel/diagram.h"
#include "render/kernel/grid3.h"
#include "render/scene/snapshot.h"
#include "render/scene/volume.h"

namespace gvd {

struct VolumeScanStats {
  uint64_t bricks = 0;     // bricks rendered
  uint64_t voxels = 0;     // voxels rendered
  uint64_t pairs = 0;      // (brick, candidate site) pairs scored
  uint32_t slices = 0;     // slices written (the others shared with the base)
};

// The volume of `sites` on `grid`, every brick rendered. Thread-safe; runs its bricks on the
// process's CPU pool (ParallelFor). CONTRACT: grid is valid (a finite box with min < max on
// every axis, and at least one voxel per axis).
std::shared_ptr<const Volume> ScanVolume(const Grid3& grid, Diagram diagram,
                                         std::shared_ptr<const SiteSnapshot3> sites,
                                         VolumeScanStats* stats = nullptr);

// The volume of `sites`, a later snapshot of the same scene as base's (slots mean the same
// sites), equal voxel for voxel to ScanVolume(base.grid(), base.diagram(), sites): only the
// bricks the change between the two snapshots can alter are rendered, and the slices they
// miss are base's own. A change of more than max(64, sites / 8) slots is rendered whole.
std::shared_ptr<const Volume> UpdateVolume(const Volume& base,
                                           std::shared_ptr<const SiteSnapshot3> sites,
                                           VolumeScanStats* stats = nullptr);

}  // namespace gvd
