#include "render/analysis/clearance3.h"

#include <algorithm>
#include <cmath>

#include "render/kernel/exact3.h"
#include "render/scene/cpu_pool.h"

namespace gvd {

void ClearanceField3(const Volume& volume, const ClearanceSamples3& at, float* clearance,
                     float* gradient, uint32_t* slots) {
  const ErrorModel& error = volume.error();
  const uint32_t rows = at.height * at.depth;
  ParallelFor(rows, 4, [&](size_t begin, size_t end) {
    for (size_t row = begin; row < end; ++row) {
      const uint32_t j = static_cast<uint32_t>(row % at.height);
      const uint32_t k = static_cast<uint32_t>(row / at.height);
      for (uint32_t i = 0; i < at.width; ++i) {
        const size_t s = row * at.width + i;
        const Vec3 q = at.At(i, j, k);
        uint32_t slot = 0;  // + 1
        double lower = INFINITY;
        if (at.own) {
          slot = volume.id_at(at.first[0] + i, at.first[1] + j, at.first[2] + k);
          if (slot != 0) {
            lower = error.LowerBound(
                volume.distance_at(at.first[0] + i, at.first[1] + j, at.first[2] + k));
          }
        } else if (auto answer = volume.Nearest(q); answer && answer->found) {
          slot = answer->site_index + 1;
          lower = answer->distance - answer->error_bound;
        }
        if (slots != nullptr) slots[s] = slot;
        if (gradient != nullptr) {
          const Vec3 g =
              slot == 0 ? Vec3(0)
                        : UnitGradient(
                              q, NearestFeature(q, volume.sites().get(slot - 1)->geometry).closest);
          for (int a = 0; a < 3; ++a) gradient[3 * s + a] = static_cast<float>(g[a]);
        }
        if (slot == 0) {
          clearance[s] = INFINITY;
          continue;
        }
        // A lower bound in float: rounded down from the double one.
        lower = std::max(0.0, lower);
        float f = static_cast<float>(lower);
        if (double{f} > lower) f = std::nextafter(f, -INFINITY);
        clearance[s] = f;
      }
    }
  });
}

}  // namespace gvd
