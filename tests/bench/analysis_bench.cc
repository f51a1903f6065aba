// Benchmarks of the diagram's structure and applications beside the references a user would
// pick: Boost.Polygon's exact Voronoi diagram for boundaries, Qhull for Delaunay.
// Run: tests/bench/run.sh (see tests/bench/README.md).
#include <benchmark/benchmark.h>

#include <boost/polygon/voronoi.hpp>
#include <map>
#include <random>

#include "render/analysis/analysis.h"
#include "render/analysis/planning.h"
#include "render/analysis/refine.h"
#include "render/gl/scene_raster.h"
#include "render/gl/zoom.h"
#include "tests/bench/bench_common.h"
#include "tests/support/maze.h"

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace gvd {
namespace {

const Window kUnit{0, 0, 1, 1};

// The frame of n random points at size x size (rendered once per n and size).
std::shared_ptr<const Frame> PointsFrame(size_t n, uint32_t size) {
  static std::map<std::pair<size_t, uint32_t>, std::shared_ptr<const Frame>> frames;
  auto& f = frames[{n, size}];
  if (!f) {
    Grid grid{kUnit, size, size};
    auto r = RenderOnce(*Gl::Get().rasterizer, grid, grid.pixel_size(), 1, RandomSites(n, kUnit, 1));
    if (r.ok()) f = *r;
  }
  return f;
}

std::vector<Vec2> Points(size_t n) {
  std::vector<Vec2> p;
  for (const Site& s : RandomSites(n, kUnit, 1)) p.push_back(std::get<PointSite>(s.geometry).p);
  return p;
}

// Boundaries as polylines at 1024x1024 from a rendered frame: range(0) points, range(1) 0 =
// full scan, 1 = continuation.
void BM_Boundaries(benchmark::State& state) {
  if (!Gl::Get().context) return state.SkipWithError("no EGL context");
  auto frame = PointsFrame(state.range(0), 1024);
  const auto method = state.range(1) ? BoundaryMethod::kContinuation : BoundaryMethod::kFullScan;
  size_t lines = 0;
  for (auto _ : state) {
    IdImage image = IdsOf(*frame, frame->grid().all());
    BoundaryEdges edges = FindBoundaryEdges(image, method);
    lines = TraceBoundaries(image, edges, frame->sites(), Diagram::kNearest).size();
    benchmark::DoNotOptimize(lines);
  }
  state.counters["polylines"] = double(lines);
  state.SetLabel(state.range(1) ? "continuation" : "full scan");
}
BENCHMARK(BM_Boundaries)
    ->ArgsProduct({{1000, 10000}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The exact Voronoi diagram of the same points by Boost.Polygon (integer input, 2^24 per
// unit), counting its finite edges: the reference for boundaries of points.
void BM_BoostPolygonVoronoi(benchmark::State& state) {
  using boost::polygon::point_data;
  std::vector<point_data<int>> pts;
  for (Vec2 p : Points(state.range(0))) pts.emplace_back(int(p.x * (1 << 24)), int(p.y * (1 << 24)));
  size_t finite = 0;
  for (auto _ : state) {
    boost::polygon::voronoi_diagram<double> vd;
    boost::polygon::construct_voronoi(pts.begin(), pts.end(), &vd);
    finite = 0;
    for (const auto& e : vd.edges()) finite += e.is_finite();
    benchmark::DoNotOptimize(finite);
  }
  state.counters["edges"] = double(finite / 2);
}
BENCHMARK(BM_BoostPolygonVoronoi)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond)->UseRealTime();

// Delaunay from a rendered frame at 1024x1024: range(0) points; range(1) 0 = the pixels'
// pairs as they are, 1 = refined by zoom windows and certified.
void BM_Delaunay(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  auto frame = PointsFrame(state.range(0), 1024);
  const std::vector<Vec2> pts = Points(state.range(0));
  ZoomRenderer zoom;
  ZoomFn fn;
  if (state.range(1)) {
    fn = [&](const std::vector<Grid>& grids) {
      return zoom.Render(*gl.rasterizer, *frame, RenderMode::kExact, grids);
    };
  }
  size_t triangles = 0, windows = 0;
  for (auto _ : state) {
    auto r = RefineNeighbors(*frame, frame->grid().all(), fn);
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    for (const auto& [p, c] : r->pairs) edges.push_back({p.first - 1, p.second - 1});
    triangles = TrianglesFromEdges(pts, edges).size();
    windows = r->windows;
    benchmark::DoNotOptimize(triangles);
  }
  state.counters["triangles"] = double(triangles);
  state.counters["zoom_windows"] = double(windows);
  state.SetLabel(state.range(1) ? "refined" : "pixels only");
}
BENCHMARK(BM_Delaunay)
    ->ArgsProduct({{1000, 10000}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Qhull's Delaunay triangulation of the same points ("qhull d Qt Qbb Qc Qz").
void BM_QhullDelaunay(benchmark::State& state) {
  std::vector<coordT> coords;
  for (Vec2 p : Points(state.range(0))) coords.insert(coords.end(), {p.x, p.y});
  size_t triangles = 0;
  for (auto _ : state) {
    qhT qh_qh;
    qhT* qh = &qh_qh;
    qh_zero(qh, stderr);
    char flags[] = "qhull d Qt Qbb Qc Qz";
    if (qh_new_qhull(qh, 2, int(coords.size() / 2), coords.data(), False, flags, nullptr, stderr)) {
      return state.SkipWithError("qhull failed");
    }
    facetT* facet;
    triangles = 0;
    FORALLfacets { triangles += !facet->upperdelaunay; }
    qh_freeqhull(qh, !qh_ALL);
    int curlong, totlong;
    qh_memfreeshort(qh, &curlong, &totlong);
  }
  state.counters["triangles"] = double(triangles);
}
BENCHMARK(BM_QhullDelaunay)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond)->UseRealTime();

// A plan across a maze of range(0) x range(0) cells at 1024x1024, corner to corner, with a
// robot of 90% of the corridors' half width: the clearance field and the path
// (range(1) = 1), or the path alone on a field already made (0).
void BM_PlanMaze(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const int k = state.range(0);
  Grid grid{kUnit, 1024, 1024};
  auto frame = *RenderOnce(*gl.rasterizer, grid, grid.pixel_size(), 1, testing::Maze(k, 7));
  const double half = 0.5 / k;
  // A radius 0.8 of a half corridor: 3.2 pixels of play at 32 cells, beyond the 1.7 pixels
  // a MESH frame's clearance bound gives away (eps and half a pixel diagonal).
  PlanRequest request{{half, half}, {1 - half, 1 - half}, 0.8 * half};
  ClearanceField field = MakeClearanceField(*frame);
  double length = 0;
  for (auto _ : state) {
    if (state.range(1)) field = MakeClearanceField(*frame);
    auto plan = PlanPath(*frame, field, request);
    if (!plan.ok()) return state.SkipWithError(std::string(plan.status().message()).c_str());
    length = plan->length;
  }
  state.counters["length"] = length;
  state.SetLabel(state.range(1) ? "field and path" : "path");
}
BENCHMARK(BM_PlanMaze)->ArgsProduct({{8, 32}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

// Zoom windows of 64x64 pixels (4x4 pixels of the frame at 16 times the resolution) over a
// 10,000-point frame, in batches of 128: the cost of one window.
void BM_ZoomWindows(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  auto frame = PointsFrame(10000, 1024);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1 - 4.0 / 1024);
  std::vector<Grid> grids;
  for (int k = 0; k < 128; ++k) {
    double x = u(rng), y = u(rng);
    grids.push_back({{x, y, x + 4.0 / 1024, y + 4.0 / 1024}, uint32_t(state.range(0)), uint32_t(state.range(0))});
  }
  ZoomRenderer zoom;
  for (auto _ : state) {
    auto frames = zoom.Render(*gl.rasterizer, *frame, RenderMode::kExact, grids);
    benchmark::DoNotOptimize(frames);
  }
  state.SetItemsProcessed(state.iterations() * grids.size());
}
BENCHMARK(BM_ZoomWindows)->Arg(8)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace gvd

BENCHMARK_MAIN();
