// Benchmarks of the render core and the query paths. Run: build/tests/bench/gvd_bench
// (see tests/bench/README.md for recorded results and the commands that produced them).
#include <benchmark/benchmark.h>
#include <grpcpp/grpcpp.h>

#include <random>

#include "gvd/client.h"
#include "render/context.h"
#include "render/raster.h"
#include "render/scene_raster.h"
#include "server/render_loop.h"
#include "server/service.h"

namespace gvd {
namespace {

SiteTable RandomSites(size_t n, const Window& w, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
  SiteTable sites;
  for (size_t i = 0; i < n; ++i) sites.push_back({std::to_string(i), PointSite{{ux(rng), uy(rng)}}});
  return sites;
}

// One GL context for the whole run, current on the main thread.
struct Gl {
  std::unique_ptr<GlContext> context;
  std::unique_ptr<Rasterizer> rasterizer;
  static Gl& Get() {
    static Gl gl = [] {
      Gl g;
      auto c = GlContext::Create(DevicePreference::kAuto);
      if (!c.ok()) return g;
      g.context = std::move(*c);
      g.rasterizer = std::move(*Rasterizer::Create());
      return g;
    }();
    return gl;
  }
};

// Full render of N random points on a size x size grid, one pixel of error, readback included.
void BM_Render(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) {
    state.SkipWithError("no EGL context");
    return;
  }
  const size_t n = state.range(0);
  const uint32_t size = state.range(1);
  Grid grid{{0, 0, 1, 1}, size, size};
  auto sites = RandomSites(n, grid.window, 1);
  RenderStats stats;
  for (auto _ : state) {
    auto frame = gl.rasterizer->Render(grid, grid.pixel_size(), 1, sites, &stats);
    benchmark::DoNotOptimize(frame);
  }
  state.counters["coverage_ms"] = stats.coverage_seconds * 1e3;
  state.counters["draw_ms"] = stats.draw_seconds * 1e3;
  state.counters["fill"] = stats.fill_ratio;
  state.counters["tile_px"] = stats.tile_px;
  state.counters["readback_ms"] = stats.readback_seconds * 1e3;
  state.counters["triangles_per_cone"] = stats.cone_segments;
  state.SetLabel(gl.context->info().gl_renderer);
}
BENCHMARK(BM_Render)
    ->ArgsProduct({{1000, 10000, 100000, 1000000}, {1024, 2048}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

// One-site add (range 0 = 0), move (1) and delete (2) in a scene of 100,000 points at
// 1024 x 1024: the time until the new frame is made (publishing it is a pointer swap).
void BM_UpdateOneSite(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) {
    state.SkipWithError("no EGL context");
    return;
  }
  Grid grid{{0, 0, 1, 1}, 1024, 1024};
  auto scene = std::move(*SceneRaster::Create(grid, grid.pixel_size()));
  SiteTable sites = RandomSites(100000, grid.window, 6);
  std::vector<SiteChange> all;
  for (const Site& s : sites) all.push_back({s.id, s.geometry});
  uint64_t version = 1;
  (void)scene->Apply(*gl.rasterizer, ++version, all);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const int kind = state.range(0);
  RenderStats stats;
  uint64_t pixels = 0, drawn = 0;
  int next = 0;
  for (auto _ : state) {
    std::vector<SiteChange> change;
    if (kind == 0) {
      change.push_back({"new" + std::to_string(next++), PointSite{{u(rng), u(rng)}}});
    } else if (kind == 1) {
      change.push_back({sites[rng() % sites.size()].id, PointSite{{u(rng), u(rng)}}});
    } else {
      change.push_back({sites[next++].id, std::nullopt});
    }
    auto frame = scene->Apply(*gl.rasterizer, ++version, std::move(change), &stats);
    if (!frame.ok()) state.SkipWithError("render failed");
    pixels += stats.pixels;
    drawn += stats.sites_drawn;
  }
  state.counters["pixels"] = double(pixels) / state.iterations();
  state.counters["sites_drawn"] = double(drawn) / state.iterations();
  state.SetLabel(kind == 0 ? "add" : kind == 1 ? "move" : "delete");
}
BENCHMARK(BM_UpdateOneSite)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// In-process lookups: Frame::Nearest on a 1024 x 1024 frame of 10,000 sites.
void BM_FrameNearest(benchmark::State& state) {
  Gl& gl = Gl::Get();
  if (!gl.context) {
    state.SkipWithError("no EGL context");
    return;
  }
  Grid grid{{0, 0, 1, 1}, 1024, 1024};
  static std::shared_ptr<const Frame> frame =
      *gl.rasterizer->Render(grid, grid.pixel_size(), 1, RandomSites(10000, grid.window, 2));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec2> q(1 << 16);
  for (auto& p : q) p = {u(rng), u(rng)};
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(frame->Nearest(q[i++ & (q.size() - 1)]));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrameNearest);

// FindNearest over loopback gRPC against an in-process server, batch size = range(0).
void BM_GrpcFindNearest(benchmark::State& state) {
  static RenderLoop* renderer = nullptr;
  static VoronoiService* service = nullptr;
  static std::unique_ptr<grpc::Server> server;
  static std::unique_ptr<Client> client;
  static int port = 0;
  if (!server) {
    renderer = new RenderLoop();
    if (!renderer->Start(DevicePreference::kAuto).ok()) {
      state.SkipWithError("no EGL context");
      return;
    }
    service = new VoronoiService(renderer, ServerLimits{});
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.SetMaxReceiveMessageSize(256 << 20);
    builder.SetMaxSendMessageSize(256 << 20);
    builder.RegisterService(service);
    server = builder.BuildAndStart();
    client = Client::Connect("127.0.0.1:" + std::to_string(port));
    v1::CreateSceneRequest c;
    c.set_scene_id("bench");
    c.mutable_window()->set_max_x(1);
    c.mutable_window()->set_max_y(1);
    c.set_width_px(1024);
    c.set_height_px(1024);
    v1::Scene scene;
    (void)client->CreateScene(c, &scene);
    v1::UpsertSitesRequest u;
    u.set_scene_id("bench");
    for (const Site& s : RandomSites(10000, {0, 0, 1, 1}, 4)) {
      auto* site = u.add_sites();
      site->set_id(s.id);
      site->mutable_point()->set_x(std::get<PointSite>(s.geometry).p.x);
      site->mutable_point()->set_y(std::get<PointSite>(s.geometry).p.y);
    }
    uint64_t version;
    (void)client->UpsertSites(u, &version);
    v1::FindNearestRequest warm;
    warm.set_scene_id("bench");
    warm.set_min_version(version);
    warm.add_points();
    v1::FindNearestResponse r;
    (void)client->FindNearest(warm, &r);  // waits for the first render
  }
  const int batch = state.range(0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  v1::FindNearestRequest request;
  request.set_scene_id("bench");
  for (int i = 0; i < batch; ++i) {
    auto* p = request.add_points();
    p->set_x(u(rng));
    p->set_y(u(rng));
  }
  v1::FindNearestResponse response;
  for (auto _ : state) {
    grpc::Status s = client->FindNearest(request, &response);
    if (!s.ok()) state.SkipWithError(s.error_message().c_str());
  }
  state.SetItemsProcessed(state.iterations() * batch);
}
BENCHMARK(BM_GrpcFindNearest)->Arg(1)->Arg(1000)->Arg(100000)->UseRealTime();

}  // namespace
}  // namespace gvd

BENCHMARK_MAIN();
