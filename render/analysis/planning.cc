#include "render/analysis/planning.h"

#include <algorithm>
#include <cmath>
#include <queue>

#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

// A polygon that the robot cannot enter: restricted to its inside, it is a boundary (a room,
// a maze's outer wall) whose inside is free; otherwise it is solid.
const PolygonSite* SolidPolygon(const Site& s) {
  const auto* poly = std::get_if<PolygonSite>(&s.geometry);
  return poly && poly->side != Side::kInside ? poly : nullptr;
}

// Sets the clearance of the pixel centres inside the polygon (even-odd, as InsidePolygon) to 0.
void FillSolid(const PolygonSite& poly, ClearanceField* field) {
  const Grid& g = field->grid;
  Window b = BoundingBox(poly);
  PixelRect rows = g.CentresIn({b.min_x, b.min_y}, {b.max_x, b.max_y});
  const auto& v = poly.vertices;
  std::vector<double> xs;
  for (uint32_t j = rows.y0; j < rows.y1; ++j) {
    const double y = g.Center(0, j).y;
    xs.clear();
    for (size_t k = 0; k < v.size(); ++k) {
      Vec2 a = v[k], c = v[(k + 1) % v.size()];
      if ((a.y > y) != (c.y > y)) xs.push_back(a.x + (y - a.y) / (c.y - a.y) * (c.x - a.x));
    }
    std::sort(xs.begin(), xs.end());
    for (size_t k = 0; k + 1 < xs.size(); k += 2) {
      PixelRect span = g.CentresIn({xs[k], y}, {xs[k + 1], y});
      for (uint32_t i = span.x0; i < span.x1; ++i) {
        Vec2 p = g.Center(i, j);
        if (p.x > xs[k] && p.x < xs[k + 1]) field->clearance[size_t{j} * g.width + i] = 0;
      }
    }
  }
}

// A proven lower bound on the clearance along the segment between two points whose
// clearances are at least ca and cb.
double StepBound(double ca, double cb, double length, double lipschitz) {
  return std::min({ca, cb, (ca + cb - lipschitz * length) / 2});
}

std::string Pt(Vec2 p) { return absl::StrCat("(", p.x, ", ", p.y, ")"); }

}  // namespace

ClearanceField MakeClearanceField(const Frame& frame) {
  ClearanceField field;
  const Grid& g = frame.grid();
  field.grid = g;
  field.lipschitz = frame.error().lipschitz;
  const size_t n = g.pixel_count();
  field.clearance.resize(n);
  field.site.resize(n);
  field.feature.resize(n);
  const ErrorModel& e = frame.error();
  ParallelFor(g.height, 64, [&](size_t j0, size_t j1) {
    for (uint32_t j = static_cast<uint32_t>(j0); j < j1; ++j) {
      for (uint32_t i = 0; i < g.width; ++i) {
        const size_t k = size_t{j} * g.width + i;
        const uint32_t id = frame.id_at(i, j);
        field.site[k] = id;
        if (id == 0) {
          field.clearance[k] = INFINITY;
          field.feature[k] = 0;
          continue;
        }
        field.clearance[k] = static_cast<float>(std::max(0.0, e.LowerBound(frame.distance_at(i, j))));
        const Site& s = *frame.sites().get(id - 1);
        if (std::holds_alternative<PointSite>(s.geometry)) {
          field.feature[k] = 0;
        } else {
          FeatureHit f = NearestFeature(g.Center(i, j), s);
          field.feature[k] = (f.index << 2) | static_cast<uint32_t>(f.kind);
        }
      }
    }
  });
  for (uint32_t s = 0; s < frame.sites().size(); ++s) {
    const Site* site = frame.sites().get(s);
    if (const PolygonSite* poly = site ? SolidPolygon(*site) : nullptr) FillSolid(*poly, &field);
  }
  return field;
}

absl::StatusOr<Plan> PlanPath(const Frame& frame, const ClearanceField& field,
                              const PlanRequest& request) {
  const Grid& g = field.grid;
  const double r = request.radius;
  if (!(r >= 0) || !std::isfinite(r)) {
    return absl::InvalidArgumentError(absl::StrCat("robot_radius is ", r, "; it must be finite and at least 0"));
  }
  for (auto [name, p] : {std::pair{"start", request.start}, std::pair{"goal", request.goal}}) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !g.window.Contains(p)) {
      return absl::InvalidArgumentError(absl::StrCat(name, " ", Pt(p), " lies outside the scene's window"));
    }
  }
  const double L = field.lipschitz;
  // The clearance at the start and the goal themselves: the frame's bounded answer, or 0
  // inside a solid polygon.
  auto clearance_at = [&](Vec2 q, std::string* nearest) -> double {
    auto a = frame.Nearest(q);
    if (!a || !a->found) return INFINITY;
    *nearest = frame.sites().get(a->site_index)->id;
    std::vector<uint32_t> around;
    frame.snapshot().index().Within(q, 0, &around);
    for (uint32_t s : around) {
      const PolygonSite* poly = SolidPolygon(*frame.sites().get(s));
      if (poly && InsidePolygon(q, poly->vertices)) {
        *nearest = frame.sites().get(s)->id;
        return 0;
      }
    }
    return std::max(0.0, a->distance - a->error_bound);
  };
  std::string near_start, near_goal;
  const double c_start = clearance_at(request.start, &near_start);
  const double c_goal = clearance_at(request.goal, &near_goal);
  for (auto [name, p, c, site] : {std::tuple{"start", request.start, c_start, &near_start},
                                  std::tuple{"goal", request.goal, c_goal, &near_goal}}) {
    if (!(c > 0) || c < r) {
      return absl::NotFoundError(absl::StrCat(name, " ", Pt(p), " is within robot_radius ", r,
                                              " of site \"", *site, "\" (clearance at least ", c,
                                              ")"));
    }
  }

  Plan plan;
  const uint32_t w = g.width, h = g.height;
  auto index = [&](uint32_t i, uint32_t j) { return size_t{j} * w + i; };
  auto centre = [&](size_t k) { return g.Center(static_cast<uint32_t>(k % w), static_cast<uint32_t>(k / w)); };
  // The roadmap: pixels beside a boundary between sites or between features of one site,
  // pixels no site reaches, and the window's border.
  std::vector<uint8_t> node(g.pixel_count(), 0);
  for (uint32_t j = 0; j < h; ++j) {
    for (uint32_t i = 0; i < w; ++i) {
      const size_t k = index(i, j);
      // The window's own border closes the roadmap: climbing the clearance can end there.
      bool on = field.site[k] == 0 || i == 0 || j == 0 || i + 1 == w || j + 1 == h;
      auto differs = [&](size_t o) {
        return field.site[o] != field.site[k] || field.feature[o] != field.feature[k];
      };
      if (i > 0 && differs(k - 1)) on = true;
      if (i + 1 < w && differs(k + 1)) on = true;
      if (j > 0 && differs(k - w)) on = true;
      if (j + 1 < h && differs(k + w)) on = true;
      node[k] = on;
      plan.roadmap_pixels += on;
    }
  }
  // Joins: climb the clearance from the pixel nearest a point until the roadmap.
  auto join = [&](Vec2 p) {
    uint32_t i, j;
    frame.PixelOf(p, &i, &j);
    size_t k = index(i, j);
    while (!node[k]) {
      node[k] = 1;
      size_t best = k;
      const uint32_t ci = static_cast<uint32_t>(k % w), cj = static_cast<uint32_t>(k / w);
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          int x = int(ci) + di, y = int(cj) + dj;
          if (x < 0 || y < 0 || x >= int(w) || y >= int(h)) continue;
          size_t o = index(x, y);
          if (field.clearance[o] > field.clearance[best]) best = o;
        }
      }
      if (best == k) break;  // a local maximum off the roadmap: it stays a node
      k = best;
      if (node[k]) break;
    }
    uint32_t i0, j0;
    frame.PixelOf(p, &i0, &j0);
    return index(i0, j0);
  };
  const size_t s0 = join(request.start), g0 = join(request.goal);
  auto step = [&](size_t a, size_t b) {
    return StepBound(field.clearance[a], field.clearance[b], Distance(centre(a), centre(b)), L);
  };
  const double start_step = StepBound(c_start, field.clearance[s0], Distance(request.start, centre(s0)), L);
  const double goal_step = StepBound(field.clearance[g0], c_goal, Distance(centre(g0), request.goal), L);
  auto neighbours = [&](size_t k, auto&& f) {
    const uint32_t ci = static_cast<uint32_t>(k % w), cj = static_cast<uint32_t>(k / w);
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        if (di == 0 && dj == 0) continue;
        int x = int(ci) + di, y = int(cj) + dj;
        if (x < 0 || y < 0 || x >= int(w) || y >= int(h)) continue;
        size_t o = index(x, y);
        if (node[o]) f(o);
      }
    }
  };

  // 1. The widest passage: the path from s0 to g0 whose least step is largest.
  std::vector<float> wide(g.pixel_count(), -INFINITY);
  {
    std::priority_queue<std::pair<float, size_t>> queue;
    wide[s0] = static_cast<float>(start_step);
    queue.push({wide[s0], s0});
    while (!queue.empty()) {
      const float b = queue.top().first;
      const size_t k = queue.top().second;
      queue.pop();
      if (b < wide[k]) continue;
      if (k == g0) break;
      neighbours(k, [&](size_t o) {
        float nb = std::min(b, static_cast<float>(step(k, o)));
        if (nb > wide[o]) {
          wide[o] = nb;
          queue.push({nb, o});
        }
      });
    }
  }
  double best = std::min<double>(wide[g0], goal_step);
  const double direct = StepBound(c_start, c_goal, Distance(request.start, request.goal), L);
  const bool same_pixel = s0 == g0;
  if (same_pixel) best = std::max(best, direct);
  plan.best_clearance = best;
  if (!(best > 0) || best < r) {
    return absl::NotFoundError(absl::StrCat(
        "no path from ", Pt(request.start), " to ", Pt(request.goal), " keeps robot_radius ", r,
        " from every site: the widest passage along the Voronoi boundaries has clearance ",
        std::max(0.0, best)));
  }
  if (same_pixel && direct >= best) {
    plan.path = {request.start, request.goal};
    plan.min_clearance = direct;
    plan.length = Distance(request.start, request.goal);
    return plan;
  }

  // 2. The shortest path whose every step keeps the threshold.
  const float threshold = static_cast<float>(
      request.prefer == PathPreference::kMaxClearance ? std::min<double>(wide[g0], best) : r);
  std::vector<double> dist(g.pixel_count(), INFINITY);
  std::vector<size_t> parent(g.pixel_count(), SIZE_MAX);
  {
    using Item = std::pair<double, size_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    dist[s0] = 0;
    queue.push({0, s0});
    while (!queue.empty()) {
      const double d = queue.top().first;
      const size_t k = queue.top().second;
      queue.pop();
      if (d > dist[k]) continue;
      if (k == g0) break;
      neighbours(k, [&](size_t o) {
        double s = step(k, o);
        if (!(s > 0) || static_cast<float>(s) < threshold) return;
        double nd = d + Distance(centre(k), centre(o));
        if (nd < dist[o]) {
          dist[o] = nd;
          parent[o] = k;
          queue.push({nd, o});
        }
      });
    }
  }
  if (!std::isfinite(dist[g0])) {
    return absl::InternalError("the shortest path search lost the widest passage");
  }
  std::vector<size_t> pixels;
  for (size_t k = g0; k != SIZE_MAX; k = parent[k]) pixels.push_back(k);
  std::reverse(pixels.begin(), pixels.end());
  // The polyline through every pixel centre, with a proven bound on each of its segments.
  std::vector<Vec2> points = {request.start};
  std::vector<double> bounds = {start_step};
  for (size_t n = 0; n < pixels.size(); ++n) {
    points.push_back(centre(pixels[n]));
    if (n > 0) bounds.push_back(step(pixels[n - 1], pixels[n]));
  }
  points.push_back(request.goal);
  bounds.push_back(goal_step);
  const double unsimplified = *std::min_element(bounds.begin(), bounds.end());
  // A proven lower bound on the clearance along the straight segment ab: samples every
  // quarter pixel, each bounded by its nearest pixel centre's clearance less L times the
  // distance to it (at start and goal: their own clearance), and between two samples the
  // step bound.
  const double quarter = g.pixel_size() / 4;
  auto sampled = [&](Vec2 a, Vec2 b) {
    const int n = std::max(1, static_cast<int>(std::ceil(Distance(a, b) / quarter)));
    const double spacing = Distance(a, b) / n;
    double least = INFINITY, last = 0;
    for (int k = 0; k <= n; ++k) {
      Vec2 x = a + (double(k) / n) * (b - a);
      uint32_t i, j;
      frame.PixelOf(x, &i, &j);
      double c = field.at(i, j) - L * Distance(x, g.Center(i, j));
      if (k == 0 && a.x == request.start.x && a.y == request.start.y) c = std::max(c, c_start);
      if (k == n && b.x == request.goal.x && b.y == request.goal.y) c = std::max(c, c_goal);
      if (k > 0) least = std::min(least, StepBound(last, c, spacing, L));
      last = c;
    }
    return least;
  };
  // Simplified within a pixel (Douglas-Peucker), keeping only shortcuts whose proven
  // clearance stays within a pixel of the path's and at least the robot's radius: the
  // staircase of pixel steps goes, the bound holds.
  const double keep = std::max(r, unsimplified - g.pixel_size());
  std::vector<size_t> kept = {0};
  std::vector<double> kept_bounds;
  std::vector<std::pair<size_t, size_t>> todo = {{0, points.size() - 1}};
  while (!todo.empty()) {
    auto [i, j] = todo.back();
    todo.pop_back();
    if (j == i + 1) {
      kept.push_back(j);
      kept_bounds.push_back(bounds[i]);
      continue;
    }
    size_t far = i + 1;
    double worst = -1;
    for (size_t k = i + 1; k < j; ++k) {
      double d = SegmentDistance(points[k], points[i], points[j]);
      if (d > worst) {
        worst = d;
        far = k;
      }
    }
    double chord = worst <= g.pixel_size() ? sampled(points[i], points[j]) : -INFINITY;
    if (chord >= keep) {
      kept.push_back(j);
      kept_bounds.push_back(chord);
      continue;
    }
    if (worst <= g.pixel_size()) far = (i + j) / 2;  // straight enough, but too close
    todo.push_back({far, j});  // the stack takes the first half next
    todo.push_back({i, far});
  }
  plan.min_clearance = *std::min_element(kept_bounds.begin(), kept_bounds.end());
  for (size_t k : kept) plan.path.push_back(points[k]);
  for (size_t n = 1; n < plan.path.size(); ++n) plan.length += Distance(plan.path[n - 1], plan.path[n]);
  return plan;
}

}  // namespace gvd
