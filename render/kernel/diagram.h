// The diagram variants: which site a diagram picks at a point (paper sec. 8). The same in
// every dimension.
#pragma once

#include <cstdint>

namespace gvd {

// Which sites a diagram picks at a point: the least value, or the greatest (paper sec. 8).
enum class Diagram : uint8_t { kNearest, kFarthest };

// Whether value a beats b in the diagram.
inline bool Beats(Diagram diagram, double a, double b) {
  return diagram == Diagram::kNearest ? a < b : a > b;
}

}  // namespace gvd
