#include "render/analysis/analysis.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <unordered_map>
#include <unordered_set>

namespace gvd {
namespace {

// Marked pixel pairs are numbered: horizontal pair k is k, vertical pair k is H + k.
struct EdgeCodec {
  uint32_t w, h;
  uint64_t horizontal_count() const { return w > 1 ? uint64_t{w - 1} * h : 0; }
  uint64_t H(uint32_t i, uint32_t j) const { return uint64_t{j} * (w - 1) + i; }
  uint64_t V(uint32_t i, uint32_t j) const { return horizontal_count() + uint64_t{j} * w + i; }
  bool is_vertical(uint64_t e) const { return e >= horizontal_count(); }
  // The two pixels of pair e: (i, j) and (i + 1, j) or (i, j + 1).
  void Pixels(uint64_t e, uint32_t* i, uint32_t* j, uint32_t* i2, uint32_t* j2) const {
    if (!is_vertical(e)) {
      *i = static_cast<uint32_t>(e % (w - 1));
      *j = static_cast<uint32_t>(e / (w - 1));
      *i2 = *i + 1;
      *j2 = *j;
    } else {
      uint64_t k = e - horizontal_count();
      *i = static_cast<uint32_t>(k % w);
      *j = static_cast<uint32_t>(k / w);
      *i2 = *i;
      *j2 = *j + 1;
    }
  }
  // Cells are numbered j * (w - 1) + i for the 2x2 block with lower-left pixel (i, j). The
  // cells holding pair e, or kNone.
  static constexpr uint64_t kNone = ~uint64_t{0};
  uint64_t Cell(uint32_t i, uint32_t j) const { return uint64_t{j} * (w - 1) + i; }
  void Cells(uint64_t e, uint64_t out[2]) const {
    uint32_t i, j, i2, j2;
    Pixels(e, &i, &j, &i2, &j2);
    out[0] = out[1] = kNone;
    if (w < 2 || h < 2) return;
    if (!is_vertical(e)) {
      if (j >= 1) out[0] = Cell(i, j - 1);
      if (j + 1 < h) out[1] = Cell(i, j);
    } else {
      if (i >= 1) out[0] = Cell(i - 1, j);
      if (i + 1 < w) out[1] = Cell(i, j);
    }
  }
  // The four pairs around a cell: bottom, top, left, right.
  void Sides(uint64_t cell, uint64_t out[4]) const {
    uint32_t i = static_cast<uint32_t>(cell % (w - 1)), j = static_cast<uint32_t>(cell / (w - 1));
    out[0] = H(i, j);
    out[1] = H(i, j + 1);
    out[2] = V(i, j);
    out[3] = V(i + 1, j);
  }
};

bool Marked(const BoundaryEdges& e, const EdgeCodec& c, uint64_t code) {
  return c.is_vertical(code) ? e.vertical[code - c.horizontal_count()] : e.horizontal[code];
}

void Mark(BoundaryEdges* e, const EdgeCodec& c, uint64_t code) {
  (c.is_vertical(code) ? e->vertical[code - c.horizontal_count()] : e->horizontal[code]) = 1;
  ++e->count;
}

bool Differs(const IdImage& image, const EdgeCodec& c, uint64_t code) {
  uint32_t i, j, i2, j2;
  c.Pixels(code, &i, &j, &i2, &j2);
  return image.at(i, j) != image.at(i2, j2);
}

const PointSite* PlainPoint(const Site* s) {
  return s && s->plain() ? std::get_if<PointSite>(&s->geometry) : nullptr;
}

}  // namespace

IdImage IdsOf(const Frame& frame, PixelRect rect) {
  const Grid& g = frame.grid();
  IdImage image;
  image.grid.window = {g.window.min_x + rect.x0 * g.pixel_width(),
                       g.window.min_y + rect.y0 * g.pixel_height(),
                       g.window.min_x + rect.x1 * g.pixel_width(),
                       g.window.min_y + rect.y1 * g.pixel_height()};
  if (rect.x1 == g.width) image.grid.window.max_x = g.window.max_x;
  if (rect.y1 == g.height) image.grid.window.max_y = g.window.max_y;
  image.grid.width = rect.width();
  image.grid.height = rect.height();
  image.ids.resize(rect.area());
  for (uint32_t j = rect.y0; j < rect.y1; ++j) {
    uint32_t* row = &image.ids[size_t{j - rect.y0} * rect.width()];
    for (uint32_t i = rect.x0; i < rect.x1; ++i) row[i - rect.x0] = frame.id_at(i, j);
  }
  return image;
}

BoundaryEdges FindBoundaryEdges(const IdImage& image, BoundaryMethod method) {
  const uint32_t w = image.width(), h = image.height();
  EdgeCodec c{w, h};
  BoundaryEdges e;
  e.width = w;
  e.height = h;
  e.horizontal.assign(w > 1 ? size_t{w - 1} * h : 0, 0);
  e.vertical.assign(h > 1 ? size_t{w} * (h - 1) : 0, 0);
  if (method == BoundaryMethod::kFullScan) {
    for (uint32_t j = 0; j < h; ++j) {
      for (uint32_t i = 0; i + 1 < w; ++i) {
        if (image.at(i, j) != image.at(i + 1, j)) Mark(&e, c, c.H(i, j));
      }
    }
    for (uint32_t j = 0; j + 1 < h; ++j) {
      for (uint32_t i = 0; i < w; ++i) {
        if (image.at(i, j) != image.at(i, j + 1)) Mark(&e, c, c.V(i, j));
      }
    }
    e.cells_visited = w > 1 && h > 1 ? size_t{w - 1} * (h - 1) : 0;
    return e;
  }
  // Continuation: seeds on the border, then cell by cell.
  std::deque<uint64_t> queue;
  auto seed = [&](uint64_t code) {
    if (!Marked(e, c, code) && Differs(image, c, code)) {
      Mark(&e, c, code);
      queue.push_back(code);
    }
  };
  for (uint32_t i = 0; i + 1 < w; ++i) {
    seed(c.H(i, 0));
    seed(c.H(i, h - 1));
  }
  for (uint32_t j = 0; j + 1 < h; ++j) {
    seed(c.V(0, j));
    seed(c.V(w - 1, j));
  }
  std::vector<uint8_t> visited(w > 1 && h > 1 ? size_t{w - 1} * (h - 1) : 0, 0);
  while (!queue.empty()) {
    uint64_t code = queue.front();
    queue.pop_front();
    uint64_t cells[2];
    c.Cells(code, cells);
    for (uint64_t cell : cells) {
      if (cell == EdgeCodec::kNone || visited[cell]) continue;
      visited[cell] = 1;
      ++e.cells_visited;
      uint64_t sides[4];
      c.Sides(cell, sides);
      for (uint64_t s : sides) seed(s);
    }
  }
  return e;
}

Vec2 BoundaryCrossing(Vec2 p, Vec2 q, const Site* a, const Site* b, Diagram diagram) {
  const Vec2 mid = 0.5 * (p + q);
  const PointSite *pa = PlainPoint(a), *pb = PlainPoint(b);
  if (pa && pb) {
    // |x - a| = |x - b| on x = p + t (q - p): linear in t.
    Vec2 d = q - p, ab = pb->p - pa->p;
    double den = 2 * glm::dot(d, ab);
    double num = glm::dot(p - pb->p, p - pb->p) - glm::dot(p - pa->p, p - pa->p);
    if (den == 0) return mid;
    double t = num / den;
    if (!(t >= 0 && t <= 1)) return mid;
    return p + t * d;
  }
  // Whether A is best at x against B (a site with an infinite value is no candidate).
  auto a_wins = [&](Vec2 x) {
    double va = a ? SiteValue(x, *a) : INFINITY, vb = b ? SiteValue(x, *b) : INFINITY;
    if (!std::isfinite(va)) return false;
    if (!std::isfinite(vb)) return true;
    return diagram == Diagram::kNearest ? va <= vb : va >= vb;
  };
  if (!a_wins(p) || a_wins(q)) return mid;
  double lo = 0, hi = 1;
  for (int k = 0; k < 40; ++k) {
    double m = (lo + hi) / 2;
    (a_wins(p + m * (q - p)) ? lo : hi) = m;
  }
  return p + ((lo + hi) / 2) * (q - p);
}

std::vector<BoundaryPolyline> TraceBoundaries(const IdImage& image, const BoundaryEdges& edges,
                                              const SlotTable& sites, Diagram diagram) {
  const uint32_t w = image.width(), h = image.height();
  EdgeCodec c{w, h};
  std::vector<BoundaryPolyline> out;
  if (edges.count == 0) return out;

  auto site = [&](uint32_t id) { return id == 0 ? nullptr : sites.get(id - 1); };
  auto crossing = [&](uint64_t code) {
    uint32_t i, j, i2, j2;
    c.Pixels(code, &i, &j, &i2, &j2);
    return BoundaryCrossing(image.grid.Center(i, j), image.grid.Center(i2, j2),
                            site(image.at(i, j)), site(image.at(i2, j2)), diagram);
  };
  auto marked_sides = [&](uint64_t cell, uint64_t out_sides[4]) {
    uint64_t sides[4];
    c.Sides(cell, sides);
    int n = 0;
    for (uint64_t s : sides) {
      if (Marked(edges, c, s)) out_sides[n++] = s;
    }
    return n;
  };
  std::unordered_map<uint64_t, Vec2> junctions;
  auto junction = [&](uint64_t cell) {
    auto it = junctions.find(cell);
    if (it != junctions.end()) return it->second;
    uint64_t sides[4];
    int n = marked_sides(cell, sides);
    Vec2 sum;
    for (int k = 0; k < n; ++k) sum = sum + crossing(sides[k]);
    return junctions[cell] = (1.0 / n) * sum;
  };

  // Every marked pair, in scan order.
  std::vector<uint64_t> list;
  list.reserve(edges.count);
  for (uint64_t k = 0; k < edges.horizontal.size(); ++k) {
    if (edges.horizontal[k]) list.push_back(k);
  }
  for (uint64_t k = 0; k < edges.vertical.size(); ++k) {
    if (edges.vertical[k]) list.push_back(c.horizontal_count() + k);
  }
  std::vector<uint8_t> done_mask(c.horizontal_count() + edges.vertical.size(), 0);
  auto done = [&](uint64_t e) { return done_mask[e] != 0; };
  // Walks from `from` (a cell, or kNone) across pair e and on, appending to `poly`.
  auto walk = [&](BoundaryPolyline& poly, uint64_t from, uint64_t e) {
    const uint64_t start = e;
    uint32_t i, j, i2, j2;
    c.Pixels(e, &i, &j, &i2, &j2);
    uint32_t ia = image.at(i, j), ib = image.at(i2, j2);
    poly.a = std::min(ia, ib);
    poly.b = std::max(ia, ib);
    poly.points.push_back(crossing(e));
    done_mask[e] = 1;
    while (true) {
      uint64_t cells[2];
      c.Cells(e, cells);
      uint64_t next = cells[0] == from ? cells[1] : cells[0];
      if (next == EdgeCodec::kNone || next == from) return;
      uint64_t sides[4];
      int n = marked_sides(next, sides);
      if (n != 2) {
        poly.points.push_back(junction(next));
        return;
      }
      uint64_t e2 = sides[0] == e ? sides[1] : sides[0];
      if (done(e2)) {
        poly.closed = e2 == start;
        return;
      }
      poly.points.push_back(crossing(e2));
      done_mask[e2] = 1;
      from = next;
      e = e2;
    }
  };
  // 1. From each junction, along each of its pairs.
  for (uint64_t e : list) {
    uint64_t cells[2];
    c.Cells(e, cells);
    for (uint64_t cell : cells) {
      if (cell == EdgeCodec::kNone) continue;
      uint64_t sides[4];
      if (marked_sides(cell, sides) < 3 || done(e)) continue;
      BoundaryPolyline poly;
      poly.points.push_back(junction(cell));
      walk(poly, cell, e);
      out.push_back(std::move(poly));
    }
  }
  // 2. From the image's border.
  for (uint64_t e : list) {
    if (done(e)) continue;
    uint64_t cells[2];
    c.Cells(e, cells);
    if (cells[0] != EdgeCodec::kNone && cells[1] != EdgeCodec::kNone) continue;
    BoundaryPolyline poly;
    walk(poly, EdgeCodec::kNone, e);
    out.push_back(std::move(poly));
  }
  // 3. What is left closes on itself.
  for (uint64_t e : list) {
    if (done(e)) continue;
    uint64_t cells[2];
    c.Cells(e, cells);
    BoundaryPolyline poly;
    walk(poly, cells[0], e);
    out.push_back(std::move(poly));
  }
  return out;
}

NeighborCounts NeighborPairs(const IdImage& image, const BoundaryEdges& edges) {
  NeighborCounts counts;
  const uint32_t w = image.width(), h = image.height();
  auto add = [&](uint32_t a, uint32_t b) {
    if (a == 0 || b == 0) return;
    ++counts[{std::min(a, b), std::max(a, b)}];
  };
  for (uint32_t j = 0; j < h; ++j) {
    for (uint32_t i = 0; i + 1 < w; ++i) {
      if (edges.h(i, j)) add(image.at(i, j), image.at(i + 1, j));
    }
  }
  for (uint32_t j = 0; j + 1 < h; ++j) {
    for (uint32_t i = 0; i < w; ++i) {
      if (edges.v(i, j)) add(image.at(i, j), image.at(i, j + 1));
    }
  }
  return counts;
}

bool GeometryMeetsBox(const Geometry& g, const Window& box) {
  bool meets = false;
  ForEachSegment(g, [&](Vec2 a, Vec2 b) {
    if (meets) return;
    // Liang-Barsky: clip a + t (b - a), t in [0, 1], to the box.
    double t0 = 0, t1 = 1;
    Vec2 d = b - a;
    auto clip = [&](double p, double q) {  // p t <= q
      if (p == 0) return q >= 0;
      double r = q / p;
      if (p < 0) {
        if (r > t1) return false;
        t0 = std::max(t0, r);
      } else {
        if (r < t0) return false;
        t1 = std::min(t1, r);
      }
      return true;
    };
    meets = clip(-d.x, a.x - box.min_x) && clip(d.x, box.max_x - a.x) &&
            clip(-d.y, a.y - box.min_y) && clip(d.y, box.max_y - a.y) && t0 <= t1;
  });
  return meets;
}

std::vector<uint32_t> HiddenSites(const IdImage& image, const SlotTable& sites) {
  std::vector<uint8_t> present(sites.size(), 0);
  for (uint32_t id : image.ids) {
    if (id != 0 && id - 1 < present.size()) present[id - 1] = 1;
  }
  std::vector<uint32_t> hidden;
  for (uint32_t s = 0; s < sites.size(); ++s) {
    const Site* site = sites.get(s);
    if (site && !present[s] && GeometryMeetsBox(site->geometry, image.grid.window)) {
      hidden.push_back(s);
    }
  }
  return hidden;
}

std::vector<std::array<uint32_t, 3>> TrianglesFromEdges(
    const std::vector<Vec2>& points, const std::vector<std::pair<uint32_t, uint32_t>>& edges) {
  std::vector<std::vector<uint32_t>> around(points.size());
  std::unordered_set<uint64_t> is_edge;
  auto key = [](uint32_t a, uint32_t b) {
    return (uint64_t{std::min(a, b)} << 32) | std::max(a, b);
  };
  for (auto [a, b] : edges) {
    if (a == b || !is_edge.insert(key(a, b)).second) continue;
    around[a].push_back(b);
    around[b].push_back(a);
  }
  std::vector<std::array<uint32_t, 3>> out;
  for (uint32_t a = 0; a < points.size(); ++a) {
    auto& nb = around[a];
    if (nb.size() < 2) continue;
    const Vec2 pa = points[a];
    std::sort(nb.begin(), nb.end(), [&](uint32_t x, uint32_t y) {
      return std::atan2(points[x].y - pa.y, points[x].x - pa.x) <
             std::atan2(points[y].y - pa.y, points[y].x - pa.x);
    });
    for (size_t k = 0; k < nb.size(); ++k) {
      uint32_t b = nb[k], c = nb[(k + 1) % nb.size()];
      if (b == c || b < a || c < a) continue;
      Vec2 u = points[b] - pa, v = points[c] - pa;
      if (u.x * v.y - u.y * v.x <= 0) continue;  // not a counter-clockwise turn below pi
      if (!is_edge.count(key(b, c))) continue;
      out.push_back({a, b, c});
    }
  }
  return out;
}

}  // namespace gvd
