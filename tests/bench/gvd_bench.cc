// Benchmarks of gvd beside the references a user would pick: OpenCV's labelled distance
// transform for whole diagrams, nanoflann's kd-tree for nearest-site queries.
// Run: tests/bench/run.sh (prints one table; see tests/bench/README.md).
#include <benchmark/benchmark.h>
#include <grpcpp/grpcpp.h>

#include <atomic>
#include <cstdio>
#include <nanoflann.hpp>
#include <random>
#include <set>
#include <thread>

#include "absl/cleanup/cleanup.h"
#include "absl/synchronization/mutex.h"
#include "gvd/client.h"
#include "tests/bench/bench_common.h"
#include "render/gl/context.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"
#include "render/gl/render_loop.h"
#include "render/kernel/path2.h"
#include "server/app/registry.h"
#include "server/grpc/server.h"
#include "server/store/sqlite_store.h"
#include "tests/support/stored_sites.h"

#ifdef GVD_BENCH_OPENCV
#include <opencv2/imgproc.hpp>
#endif

namespace gvd {
namespace {

std::vector<Vec2> RandomPoints(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec2> q(n);
  for (auto& p : q) p = {u(rng), u(rng)};
  return q;
}

const Window kUnit{0, 0, 1, 1};

// 1. Full render of N random points on a size x size grid, one pixel of error, readback and
// frame included; range(2): 0 = mesh mode, meshes drawn (as on a GPU), 1 = exact mode,
// computed (as every nearest diagram on a software rasterizer).
void BM_Render(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const size_t n = state.range(0);
  const uint32_t size = state.range(1);
  const RenderMode mode = state.range(2) ? RenderMode::kExact : RenderMode::kMesh;
  Grid grid{kUnit, size, size};
  auto sites = RandomSites(n, kUnit, 1);
  RenderStats stats;
  for (auto _ : state) {
    auto frame = RenderOnce(*gl.rasterizer, grid, grid.pixel_size(), 1, sites, &stats, mode,
                            Diagram::kNearest,
                            state.range(2) ? FullRender::kAuto : FullRender::kRaster);
    benchmark::DoNotOptimize(frame);
  }
  state.counters["coverage_ms"] = stats.coverage_seconds * 1e3;
  state.counters["draw_ms"] = stats.draw_seconds * 1e3;
  state.counters["readback_ms"] = stats.readback_seconds * 1e3;
  state.counters["fill"] = stats.fill_ratio;
  state.counters["candidates_px"] = stats.candidates_per_pixel;
  state.SetLabel(gl.context->info().gl_renderer);
}
BENCHMARK(BM_Render)
    ->ArgsProduct({{1000, 10000, 100000, 1000000}, {1024, 2048}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1)
    ->UseRealTime();

// 1''. Full render at 1024x1024 of 1,000 sites of one kind; range(0): 0 segment, 1 polyline
// (8 points), 2 polygon (6 vertices), 3 polygon inside only, 4 cubic Bezier (tolerance
// 1/4 pixel), 5 points with weights and max_distance, 6 points in a FARTHEST diagram (100
// sites), 7 polylines of 5,000 random points each across the whole window (20 sites: 100,000
// long segments crossing one another); range(1): 0 mesh, 1 exact. Each site of kinds 0 to 6
// spans about 5% of the window.
void BM_RenderKind(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const int kind = static_cast<int>(state.range(0));
  const RenderMode mode = state.range(1) ? RenderMode::kExact : RenderMode::kMesh;
  Grid grid{kUnit, 1024, 1024};
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1), d(-0.025, 0.025);
  auto near = [&](Vec2 c) { return Vec2{c.x + d(rng), c.y + d(rng)}; };
  SiteTable sites;
  const int n = kind == 6 ? 100 : kind == 7 ? 20 : 1000;
  for (int i = 0; i < n; ++i) {
    Vec2 c{u(rng), u(rng)};
    Site s{std::to_string(i), PointSite{c}};
    switch (kind) {
      case 0: s.geometry = SegmentSite{near(c), near(c)}; break;
      case 1: {
        PolylineSite l;
        for (int k = 0; k < 8; ++k) l.points.push_back(near(c));
        s.geometry = l;
        break;
      }
      case 2:
      case 3: {
        PolygonSite poly;
        for (int k = 0; k < 6; ++k) {
          double t = 2 * M_PI * k / 6, r = 0.01 + 0.015 * u(rng);
          poly.vertices.push_back({c.x + r * std::cos(t), c.y + r * std::sin(t)});
        }
        if (kind == 3) poly.side = Side::kInside;
        s.geometry = poly;
        break;
      }
      case 4: s.geometry = MakeBezier({near(c), near(c), near(c), near(c)}, grid.pixel_size() / 4); break;
      case 7: {
        PolylineSite l;
        for (int k = 0; k < 5000; ++k) l.points.push_back({u(rng), u(rng)});
        s.geometry = l;
        break;
      }
      case 5:
        s.multiplicative = 0.5 + u(rng);
        s.additive = 0.01 * u(rng);
        s.max_distance = 0.05;
        break;
      default: break;
    }
    sites.push_back(s);
  }
  const Diagram diagram = kind == 6 ? Diagram::kFarthest : Diagram::kNearest;
  RenderStats stats;
  for (auto _ : state) {
    auto frame = RenderOnce(*gl.rasterizer, grid, grid.pixel_size(), 1, sites, &stats, mode, diagram,
                            state.range(1) ? FullRender::kAuto : FullRender::kRaster);
    benchmark::DoNotOptimize(frame);
  }
  static const char* kNames[] = {"segment",      "polyline8", "polygon6", "polygon6-inside",
                                 "cubic-bezier", "weighted-bounded-point", "farthest-point",
                                 "polyline5000-across"};
  state.counters["coverage_ms"] = stats.coverage_seconds * 1e3;
  state.counters["fill"] = stats.fill_ratio;
  state.counters["candidates_px"] = stats.candidates_per_pixel;
  state.SetLabel(std::string(kNames[kind]) + " " + gl.context->info().gl_renderer);
}
BENCHMARK(BM_RenderKind)
    ->ArgsProduct({{0, 1, 2, 3, 4, 5, 6, 7}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(0.5)
    ->UseRealTime();

#ifdef GVD_BENCH_OPENCV
// 1'. OpenCV's Voronoi: cv::distanceTransform with labels (DIST_LABEL_PIXEL, L2, 5x5 mask)
// over the same sites snapped to pixels.
void BM_OpenCVDistanceTransform(benchmark::State& state) {
  cv::setNumThreads(1);
  const size_t n = state.range(0);
  const int size = static_cast<int>(state.range(1));
  cv::Mat src(size, size, CV_8U, cv::Scalar(255)), dist, labels;
  for (const Site& s : RandomSites(n, kUnit, 1)) {
    const auto& p = std::get<PointSite>(s.geometry).p;
    src.at<uint8_t>(std::min(size - 1, int(p.y * size)), std::min(size - 1, int(p.x * size))) = 0;
  }
  for (auto _ : state) {
    cv::distanceTransform(src, dist, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    benchmark::DoNotOptimize(labels.data);
  }
}
BENCHMARK(BM_OpenCVDistanceTransform)
    ->ArgsProduct({{1000, 10000, 100000, 1000000}, {1024, 2048}})
    ->Args({1000000, 4096})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
#endif

// 1'''. The GPU rows (tests/bench/gpu.sh; run.sh leaves them out): 1,000,000 points at
// 4096x4096, range(0): 0 mesh, 1 exact (computed), 2 exact drawn as quads.
void BM_Large4096(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const int path = static_cast<int>(state.range(0));
  Grid grid{kUnit, 4096, 4096};
  auto sites = RandomSites(1000000, kUnit, 1);
  RenderStats stats;
  for (auto _ : state) {
    auto frame = RenderOnce(*gl.rasterizer, grid, grid.pixel_size(), 1, sites, &stats,
                            path ? RenderMode::kExact : RenderMode::kMesh, Diagram::kNearest,
                            path == 2 ? FullRender::kRaster : FullRender::kAuto);
    benchmark::DoNotOptimize(frame);
  }
  state.counters["coverage_ms"] = stats.coverage_seconds * 1e3;
  state.counters["fill"] = stats.fill_ratio;
  state.counters["candidates_px"] = stats.candidates_per_pixel;
  state.SetLabel(gl.context->info().gl_renderer);
}
BENCHMARK(BM_Large4096)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();

// 2. One-site add (0), move (1) and delete (2) in a scene of 100,000 points at 1024 x 1024:
// the time until the new frame exists (publishing it is a pointer swap). range(1) sites
// change at once (the changes a render finds gathered while it was busy). range(2): 1 the
// windows computed on the CPU (Rasterizer::native_scan, a software device's default), 0
// drawn into the target and read back.
void BM_UpdateOneSite(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const bool native = gl.rasterizer->native_scan();
  gl.rasterizer->set_native_scan(state.range(2) == 1);
  absl::Cleanup restore = [&] { gl.rasterizer->set_native_scan(native); };
  Grid grid{kUnit, 1024, 1024};
  auto scene = std::move(*SceneRaster::Create(grid, grid.pixel_size()));
  SiteTable sites = RandomSites(100000, kUnit, 6);
  std::vector<SiteChange> all;
  for (const Site& s : sites) all.push_back({s.id, s.geometry});
  auto snapshot = SiteSnapshot::Empty(1);
  std::vector<uint32_t> free_slots;
  snapshot = Advance(snapshot, std::move(all), &free_slots);
  (void)scene->Apply(*gl.rasterizer, snapshot);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const int kind = state.range(0);
  RenderStats stats;
  uint64_t pixels = 0, drawn = 0;
  double coverage = 0, draw = 0, readback = 0;
  int next = 0;
  const int count = static_cast<int>(state.range(1));
  for (auto _ : state) {
    std::vector<SiteChange> change;
    std::set<std::string> changed;
    while (static_cast<int>(change.size()) < count) {
      if (kind == 0) {
        change.push_back({"new" + std::to_string(next++), PointSite{{u(rng), u(rng)}}});
      } else if (kind == 1) {
        const std::string& id = sites[rng() % sites.size()].id;
        if (changed.insert(id).second) change.push_back({id, PointSite{{u(rng), u(rng)}}});
      } else {
        change.push_back({sites[next++ % sites.size()].id, std::nullopt});
      }
    }
    snapshot = Advance(snapshot, std::move(change), &free_slots);
    auto frame = scene->Apply(*gl.rasterizer, snapshot, &stats);
    if (!frame.ok()) return state.SkipWithError("render failed");
    pixels += stats.pixels;
    drawn += stats.sites_drawn;
    coverage += stats.coverage_seconds;
    draw += stats.draw_seconds;
    readback += stats.readback_seconds;
  }
  state.counters["pixels"] = double(pixels) / state.iterations();
  state.counters["sites_drawn"] = double(drawn) / state.iterations();
  state.counters["coverage_ms"] = coverage * 1e3 / state.iterations();
  state.counters["draw_ms"] = draw * 1e3 / state.iterations();
  state.counters["readback_ms"] = readback * 1e3 / state.iterations();
  state.SetLabel(std::string(kind == 0 ? "add" : kind == 1 ? "move" : "delete") +
                 (stats.computed ? ", computed" : ", drawn"));
}
BENCHMARK(BM_UpdateOneSite)
    ->ArgsProduct({{0, 1, 2}, {1}, {0, 1}})
    ->ArgsProduct({{1}, {64, 256, 1024}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// 2'. Objects of lines and curves, each one path site (range(0) 0) or each piece its own
// site (1: the lines segments, the curves Beziers), 1,000 at 1024 x 1024, computed: rounded
// rectangles (four lines, four cubic corners) around a rounded hole (four quadratics), 12
// pieces each. range(1): 0 a full render, 1 one object moved (its sites removed and added
// again elsewhere, the frame updated), 2 a certified query (Frame::Nearest, then Refine).
std::vector<Subpath> RoundedFrame(Vec2 c, double w, double h) {
  const double r = std::min(w, h) / 3, k = 0.5523 * r, q = r / 2;
  const double x0 = c.x - w / 2, x1 = c.x + w / 2, y0 = c.y - h / 2, y1 = c.y + h / 2;
  Subpath outer{{{x0 + r, y0}, {x1 - r, y0}, {x1 - r + k, y0}, {x1, y0 + r - k}, {x1, y0 + r},
                 {x1, y1 - r}, {x1, y1 - r + k}, {x1 - r + k, y1}, {x1 - r, y1},
                 {x0 + r, y1}, {x0 + r - k, y1}, {x0, y1 - r + k}, {x0, y1 - r},
                 {x0, y0 + r}, {x0, y0 + r - k}, {x0 + r - k, y0}, {x0 + r, y0}},
                {1, 3, 1, 3, 1, 3, 1, 3}, true};
  Subpath hole{{{c.x + q, c.y}, {c.x + q, c.y - q}, {c.x, c.y - q}, {c.x - q, c.y - q},
                {c.x - q, c.y}, {c.x - q, c.y + q}, {c.x, c.y + q}, {c.x + q, c.y + q}, {c.x + q, c.y}},
               {2, 2, 2, 2}, true};
  return {outer, hole};
}

// The object's sites: one path, or its pieces.
std::vector<Site> ObjectSites(const std::string& id, Vec2 c, double w, double h, bool pieces,
                              double tolerance) {
  const PathSite path = MakePath(RoundedFrame(c, w, h), FillRule::kNonZero, Side::kBoth, tolerance);
  if (!pieces) return {Site{id, path}};
  std::vector<Site> out;
  for (size_t k = 0; k < path.pieces.size(); ++k) {
    const PathPiece& p = path.pieces[k];
    Site s{id + "/" + std::to_string(k), SegmentSite{p.control[0], p.control[1]}};
    if (p.degree > 1) {
      s.geometry = MakeBezier({p.control.begin(), p.control.begin() + p.degree + 1}, tolerance);
    }
    out.push_back(std::move(s));
  }
  return out;
}

void BM_PathObjects(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) return state.SkipWithError("no EGL context");
  const bool pieces = state.range(0) == 1;
  const int what = static_cast<int>(state.range(1));
  Grid grid{kUnit, 1024, 1024};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1), size(0.02, 0.04);
  const double tolerance = grid.pixel_size() / 4;
  constexpr int kObjects = 1000;
  SiteTable sites;
  std::vector<SiteChange> all;
  for (int i = 0; i < kObjects; ++i) {
    for (Site& s : ObjectSites(std::to_string(i), {u(rng), u(rng)}, size(rng), size(rng), pieces, tolerance)) {
      all.push_back({s.id, s.geometry});
      sites.push_back(std::move(s));
    }
  }
  if (what == 0) {
    for (auto _ : state) {
      auto frame = RenderOnce(*gl.rasterizer, grid, grid.pixel_size(), 1, sites, nullptr,
                              RenderMode::kExact);
      if (!frame.ok()) return state.SkipWithError("render failed");
    }
    state.counters["sites"] = static_cast<double>(sites.size());
    return;
  }
  auto scene = std::move(*SceneRaster::Create(grid, grid.pixel_size(), RenderMode::kExact));
  auto snapshot = SiteSnapshot::Empty(1);
  std::vector<uint32_t> free_slots;
  snapshot = Advance(snapshot, std::move(all), &free_slots);
  auto frame = scene->Apply(*gl.rasterizer, snapshot);
  if (!frame.ok()) return state.SkipWithError("render failed");
  if (what == 1) {
    int next = 0;
    for (auto _ : state) {
      const std::string id = std::to_string(next++ % kObjects);
      std::vector<SiteChange> change;
      for (Site& s : ObjectSites(id, {u(rng), u(rng)}, size(rng), size(rng), pieces, tolerance)) {
        change.push_back({s.id, std::move(s.geometry)});
      }
      snapshot = Advance(snapshot, std::move(change), &free_slots);
      frame = scene->Apply(*gl.rasterizer, snapshot);
      if (!frame.ok()) return state.SkipWithError("render failed");
    }
    return;
  }
  auto q = RandomPoints(1 << 12, 3);
  size_t i = 0;
  for (auto _ : state) {
    const Vec2 p = q[i++ & (q.size() - 1)];
    auto a = (*frame)->Nearest(p);
    benchmark::DoNotOptimize((*frame)->Refine(p, *a));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PathObjects)
    ->ArgsProduct({{0, 1}, {0, 1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// 3. Queries on 100,000 sites at 1024 x 1024.
constexpr size_t kQuerySites = 100000;

std::shared_ptr<const Frame> QueryFrame() {
  static std::shared_ptr<const Frame> frame = [] {
    Grid grid{kUnit, 1024, 1024};
    return *RenderOnce(*Gl::Get().rasterizer, grid, grid.pixel_size(), 1, RandomSites(kQuerySites, kUnit, 2));
  }();
  return frame;
}

// In process: Frame::Nearest (raster answer with its bound), one thread.
void BM_FrameNearest(benchmark::State& state) {
  if (!Gl::Get().context) return state.SkipWithError("no EGL context");
  auto frame = QueryFrame();
  auto q = RandomPoints(1 << 16, 3);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(frame->Nearest(q[i++ & (q.size() - 1)]));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrameNearest);

// One point's distance to a Bezier curve (random control points and query points in the unit
// square): Arg 0 the curve's own (ExactDistance, render/kernel/bezier.h), Arg 1 its
// flattening's as drawn at the default tolerance (a thousandth of the control polygon:
// DrawnDistance), the measure answers used before; 3 or 4 control points.
void BM_BezierDistance(benchmark::State& state) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site> curves;
  std::vector<Vec2> q;
  for (int k = 0; k < 1024; ++k) {
    std::vector<Vec2> control;
    for (int i = 0; i < state.range(1); ++i) control.push_back({u(rng), u(rng)});
    Site s{"c", MakeBezier(control, 0)};
    IndexSegments(s);
    curves.push_back(std::move(s));
    q.push_back({u(rng), u(rng)});
  }
  const bool drawn = state.range(0) == 1;
  size_t i = 0;
  for (auto _ : state) {
    const size_t k = i++ & 1023;
    benchmark::DoNotOptimize(drawn ? DrawnDistance(q[k], curves[k]) : ExactDistance(q[k], curves[k]));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_BezierDistance)->ArgsProduct({{0, 1}, {3, 4}});

// The reference: nanoflann's kd-tree, nearest neighbour of one point, one thread.
struct Cloud {
  std::vector<Vec2> pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  double kdtree_get_pt(size_t i, size_t d) const { return d == 0 ? pts[i].x : pts[i].y; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
void BM_NanoflannNearest(benchmark::State& state) {
  Cloud cloud;
  for (const Site& s : RandomSites(kQuerySites, kUnit, 2)) cloud.pts.push_back(std::get<PointSite>(s.geometry).p);
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>,
                                                   Cloud, 2>;
  Tree tree(2, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  auto q = RandomPoints(1 << 16, 3);
  size_t i = 0;
  for (auto _ : state) {
    const Vec2& p = q[i++ & (q.size() - 1)];
    double query[2] = {p.x, p.y};
    unsigned index;
    double d2;
    tree.knnSearch(query, 1, &index, &d2);
    benchmark::DoNotOptimize(index);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_NanoflannNearest);

// A gvd-server in this process on a loopback port, its store in `dir` (":memory:" or a
// directory), holding one scene over the unit square, `px` pixels a side, of `points` random
// points named by their index.
struct InProcessServer {
  RenderLoop renderer;
  std::unique_ptr<SqliteStore> store;
  std::unique_ptr<SceneRegistry> registry;
  std::unique_ptr<Service> core;
  std::unique_ptr<GrpcServer> server;
  std::string address;
  uint64_t version = 0;  // the scene's, once it holds the points (and has rendered them)

  ~InProcessServer() {
    if (server) server->Shutdown(std::chrono::system_clock::now());
    renderer.Stop();
  }

  // False when no EGL context or store could be made.
  bool Start(const std::string& dir, const std::string& scene_id, uint32_t px, size_t points,
             uint64_t seed) {
    absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);  // as gvd-server does
    if (!renderer.Start(DevicePreference::kAuto).ok()) return false;
    auto opened = SqliteStore::Open(dir);
    if (!opened.ok()) return false;
    store = std::move(*opened);
    registry = std::make_unique<SceneRegistry>(store.get(), Renderers{&renderer}, ServerLimits{});
    (void)registry->Load();
    core = std::make_unique<Service>(registry.get());
    GrpcOptions options;
    options.max_message_bytes = 256 << 20;
    auto started = GrpcServer::Start(std::move(options), core.get());
    if (!started.ok()) return false;
    server = std::move(*started);
    address = "127.0.0.1:" + std::to_string(server->port());
    auto client = Client::Connect(address);
    v1::CreateSceneRequest c;
    c.set_scene_id(scene_id);
    c.mutable_window()->set_max_x(1);
    c.mutable_window()->set_max_y(1);
    c.set_width_px(px);
    c.set_height_px(px);
    v1::Scene scene;
    if (!client->CreateScene(c, &scene).ok()) return false;
    version = scene.version();
    if (points == 0) return true;
    v1::UpsertSitesRequest u;
    u.set_scene_id(scene_id);
    for (const Site& s : RandomSites(points, kUnit, seed)) {
      auto* site = u.add_sites();
      site->set_id(s.id);
      site->mutable_point()->set_x(std::get<PointSite>(s.geometry).p.x);
      site->mutable_point()->set_y(std::get<PointSite>(s.geometry).p.y);
    }
    if (!client->UpsertSites(u, &version).ok()) return false;
    v1::FindNearestRequest warm;
    warm.set_scene_id(scene_id);
    warm.set_min_version(version);
    warm.add_points();
    v1::FindNearestResponse r;
    return client->FindNearest(warm, &r).ok();  // waits for the first render
  }
};

// The 100,000-site scene "bench" at 1024 x 1024, its store in memory, shared by the
// benchmarks that only read it (and BM_LatencyUnderWriter's writer).
struct LoopbackServer {
  static InProcessServer* Get() {
    static InProcessServer* s = [] {
      auto* server = new InProcessServer();
      return server->Start(":memory:", "bench", 1024, kQuerySites, 2) ? server : nullptr;
    }();
    return s;
  }
};

// Over loopback gRPC: batch size = range(0), packed points; range(1) = exact.
void BM_GrpcFindNearest(benchmark::State& state) {
  InProcessServer* ls = LoopbackServer::Get();
  if (!ls) return state.SkipWithError("no EGL context");
  auto client = Client::Connect(ls->address);
  const size_t batch = state.range(0);
  v1::FindNearestRequest request;
  request.set_scene_id("bench");
  request.set_exact(state.range(1) != 0);
  for (const Vec2& p : RandomPoints(batch, 5)) {
    request.add_xy(p.x);
    request.add_xy(p.y);
  }
  v1::FindNearestResponse response;
  for (auto _ : state) {
    grpc::Status s = client->FindNearest(request, &response);
    if (!s.ok()) return state.SkipWithError(s.error_message().c_str());
  }
  state.SetItemsProcessed(state.iterations() * batch);
  state.SetLabel(state.range(1) ? "exact" : "raster");
}
BENCHMARK(BM_GrpcFindNearest)
    ->ArgsProduct({{1, 1000, 1000000}, {0, 1}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// Pick over loopback (paper sec. 7.2, selection under a cursor): one point per call, exact,
// in the 100,000-site scene.
void BM_GrpcPick(benchmark::State& state) {
  InProcessServer* ls = LoopbackServer::Get();
  if (!ls) return state.SkipWithError("no EGL context");
  auto client = Client::Connect(ls->address);
  std::vector<Vec2> points = RandomPoints(4096, 8);
  v1::PickRequest request;
  request.set_scene_id("bench");
  v1::PickResponse response;
  size_t k = 0;
  for (auto _ : state) {
    request.mutable_point()->set_x(points[k % points.size()].x);
    request.mutable_point()->set_y(points[k++ % points.size()].y);
    grpc::Status s = client->Pick(request, &response);
    if (!s.ok()) return state.SkipWithError(s.error_message().c_str());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_GrpcPick)->Unit(benchmark::kMicrosecond)->UseRealTime();

// Durability's cost: one-site upserts over loopback, one at a time, each acknowledged once
// committed, to a store in memory (range 0) or on disk (WAL): SYNC (range 1, synced before
// the answer) or RELAXED (range 2, synced within 100 ms).
void BM_GrpcUpsert(benchmark::State& state) {
  const int mode = static_cast<int>(state.range(0));
  testing::TempDir dir;  // the store on disk goes in dir/store
  InProcessServer server;
  if (!server.Start(mode == 0 ? ":memory:" : dir.path() + "/store", "durable", 256, 0, 0)) {
    return state.SkipWithError("no EGL context or store");
  }
  auto client = Client::Connect(server.address);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  v1::UpsertSitesRequest r;
  r.set_scene_id("durable");
  r.set_durability(mode == 2 ? v1::DURABILITY_RELAXED : v1::DURABILITY_SYNC);
  auto* site = r.add_sites();
  double commit = 0;
  for (auto _ : state) {
    site->set_id(std::to_string(rng() % 1000));
    site->mutable_point()->set_x(u(rng));
    site->mutable_point()->set_y(u(rng));
    uint64_t v;
    if (!client->UpsertSites(r, &v).ok()) return state.SkipWithError("upsert failed");
    commit += server.store->last_commit_seconds();
  }
  state.counters["commit_us"] = commit / state.iterations() * 1e6;
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(mode == 0 ? "memory" : mode == 1 ? "disk, SYNC" : "disk, RELAXED");
}
BENCHMARK(BM_GrpcUpsert)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

// The store's part of a bulk load: one change set putting 100,000 points into a new scene
// of a store on disk (WAL, SYNC), from the commit's start until it is durable. Their ids are
// the points' indices in decimal (range 0, as the bench's loads name them) or 32 random hex
// digits (range 1, as UUIDs would). The commit writes them as one pack; fold_ms is the time
// the store's folder then takes, off the acknowledgement's path, to make them site rows.
void BM_StoreBulkCommit(benchmark::State& state) {
  const bool random_ids = state.range(0) == 1;
  testing::TempDir dir;
  auto opened = SqliteStore::Open(dir.path() + "/store");
  if (!opened.ok()) return state.SkipWithError("no store");
  std::unique_ptr<SqliteStore> store = std::move(*opened);
  SqliteStore::Packing packing;
  packing.fold_after = std::chrono::hours(1);  // folded below, timed apart
  store->set_packing(packing);
  double fold = 0;
  std::mt19937_64 rng(5);
  std::vector<std::shared_ptr<const Site>> put;
  for (const Site& s : RandomSites(100000, kUnit, 5)) {
    Site site = s;
    if (random_ids) {
      char hex[33];
      std::snprintf(hex, sizeof hex, "%016llx%016llx", static_cast<unsigned long long>(rng()),
                    static_cast<unsigned long long>(rng()));
      site.id = hex;
    }
    put.push_back(std::make_shared<const Site>(std::move(site)));
  }
  int scenes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    SceneSettings settings;
    settings.id = "load" + std::to_string(scenes++);
    settings.grid = {kUnit, 1024, 1024};
    settings.eps = 1e-3;
    if (!store->CreateScene(settings, 1).ok()) return state.SkipWithError("no scene");
    state.ResumeTiming();
    ChangeSet change{settings.id, 2, put, {}};
    if (!store->Commit(change).ok()) return state.SkipWithError("commit failed");
    state.PauseTiming();
    const auto fold_start = std::chrono::steady_clock::now();
    if (!store->FoldPacks().ok()) return state.SkipWithError("fold failed");
    fold += std::chrono::duration<double>(std::chrono::steady_clock::now() - fold_start).count();
    // Each iteration's scene is dropped: the next one meets an empty table.
    if (!store->DeleteScene(settings.id).ok()) return state.SkipWithError("no delete");
    state.ResumeTiming();
  }
  state.counters["fold_ms"] = fold / state.iterations() * 1e3;
  state.SetItemsProcessed(state.iterations() * put.size());
  state.SetLabel(random_ids ? "random hex ids" : "decimal ids");
}
BENCHMARK(BM_StoreBulkCommit)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// A one-site move until a query sees it, over loopback from the C++ client, in a scene of
// 100,000 points at 1024 x 1024 stored on disk: UpsertSites of one point, SYNC (range 0) or
// RELAXED (range 1), then FindNearest at its new position with the version it returned.
void BM_GrpcMove(benchmark::State& state) {
  const bool relaxed = state.range(0) != 0;
  testing::TempDir dir;  // the store on disk goes in dir/store
  InProcessServer server;
  if (!server.Start(dir.path() + "/store", "moves", 1024, kQuerySites, 4)) {
    return state.SkipWithError("no EGL context or store");
  }
  auto client = Client::Connect(server.address);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  v1::UpsertSitesRequest move;
  move.set_scene_id("moves");
  move.set_durability(relaxed ? v1::DURABILITY_RELAXED : v1::DURABILITY_SYNC);
  auto* site = move.add_sites();
  site->set_id(RandomSites(1, kUnit, 4)[0].id);
  v1::FindNearestRequest ask;
  ask.set_scene_id("moves");
  auto* at = ask.add_points();
  v1::FindNearestResponse answer;
  std::vector<double> micros;
  for (auto _ : state) {
    const double x = u(rng), y = u(rng);
    auto t0 = std::chrono::steady_clock::now();
    site->mutable_point()->set_x(x);
    site->mutable_point()->set_y(y);
    uint64_t v;
    if (!client->UpsertSites(move, &v).ok()) return state.SkipWithError("upsert failed");
    ask.set_min_version(v);
    at->set_x(x);
    at->set_y(y);
    if (!client->FindNearest(ask, &answer).ok()) return state.SkipWithError("query failed");
    micros.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(micros.begin(), micros.end());
  state.counters["p50_us"] = micros[micros.size() / 2];
  state.counters["p99_us"] = micros[micros.size() * 99 / 100];
  state.SetLabel(relaxed ? "RELAXED" : "SYNC");
}
BENCHMARK(BM_GrpcMove)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->UseRealTime();

// 4. Single-point FindNearest latency over loopback while another client moves one site
// after another: as fast as the server takes them (range 0 = 0), or range(0) moves a second
// (1: next to no writer; a drag in a user interface sends 60 to 120).
void BM_LatencyUnderWriter(benchmark::State& state) {
  const int64_t per_second = state.range(0);
  InProcessServer* ls = LoopbackServer::Get();
  if (!ls) return state.SkipWithError("no EGL context");
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> moves{0};
  std::thread writer([&] {
    auto client = Client::Connect(ls->address);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0, 1);
    v1::UpsertSitesRequest r;
    r.set_scene_id("bench");
    auto* site = r.add_sites();
    auto next = std::chrono::steady_clock::now();
    while (!stop) {
      if (per_second > 0) {
        next += std::chrono::microseconds(1000000 / per_second);
        std::this_thread::sleep_until(next);
      }
      site->set_id(std::to_string(rng() % kQuerySites));
      site->mutable_point()->set_x(u(rng));
      site->mutable_point()->set_y(u(rng));
      uint64_t v;
      if (client->UpsertSites(r, &v).ok()) ++moves;
    }
  });
  auto client = Client::Connect(ls->address);
  auto q = RandomPoints(1 << 12, 13);
  v1::FindNearestRequest request;
  request.set_scene_id("bench");
  auto* p = request.add_points();
  v1::FindNearestResponse response;
  std::vector<double> micros;
  size_t i = 0;
  auto start = std::chrono::steady_clock::now();
  for (auto _ : state) {
    p->set_x(q[i & (q.size() - 1)].x);
    p->set_y(q[i++ & (q.size() - 1)].y);
    auto t0 = std::chrono::steady_clock::now();
    grpc::Status s = client->FindNearest(request, &response);
    micros.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    if (!s.ok()) state.SkipWithError(s.error_message().c_str());
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop = true;
  writer.join();
  std::sort(micros.begin(), micros.end());
  state.counters["p50_us"] = micros[micros.size() / 2];
  state.counters["p99_us"] = micros[micros.size() * 99 / 100];
  state.counters["moves_per_s"] = moves / seconds;
}
BENCHMARK(BM_LatencyUnderWriter)->Arg(0)->Arg(1)->Arg(120)->Iterations(20000)->UseRealTime();

}  // namespace
}  // namespace gvd

BENCHMARK_MAIN();
