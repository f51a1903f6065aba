// Qhull (libqhull-dev, reentrant) as the reference Delaunay triangulation of the tests.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <set>
#include <utility>
#include <vector>

#include "render/kernel/grid2.h"

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace gvd::testing {

// Qhull's Delaunay edges of the points (indices into pts).
inline std::set<std::pair<uint32_t, uint32_t>> QhullEdges(const std::vector<Vec2>& pts,
                                                   std::vector<std::array<uint32_t, 3>>* tris) {
  std::vector<coordT> coords;
  for (Vec2 p : pts) coords.insert(coords.end(), {p.x, p.y});
  qhT qh_qh;
  qhT* qh = &qh_qh;
  qh_zero(qh, stderr);
  char flags[] = "qhull d Qt Qbb Qc Qz";
  std::set<std::pair<uint32_t, uint32_t>> edges;
  int code = qh_new_qhull(qh, 2, static_cast<int>(pts.size()), coords.data(), False, flags,
                          nullptr, stderr);
  EXPECT_EQ(code, 0);
  if (code == 0) {
    facetT* facet;
    vertexT *vertex, **vertexp;
    FORALLfacets {
      if (facet->upperdelaunay) continue;
      std::vector<uint32_t> v;
      FOREACHvertex_(facet->vertices) v.push_back(qh_pointid(qh, vertex->point));
      if (v.size() != 3) continue;
      tris->push_back({v[0], v[1], v[2]});
      for (int a = 0; a < 3; ++a) {
        uint32_t x = v[a], y = v[(a + 1) % 3];
        if (x < uint32_t(pts.size()) && y < uint32_t(pts.size())) {
          edges.insert({std::min(x, y), std::max(x, y)});
        }
      }
    }
  }
  qh_freeqhull(qh, !qh_ALL);
  int curlong, totlong;
  qh_memfreeshort(qh, &curlong, &totlong);
  return edges;
}

}  // namespace gvd::testing
