// 3D volumes rendered exactly on the CPU (render/plan/volume_scan.h) and queried, beside the
// references users would pick: nanoflann's 3D kd-tree for nearest points; scipy's 3D
// distance_transform_edt is timed on the same inputs by volume_bench.py in the same run.
#include <benchmark/benchmark.h>
#include <nanoflann.hpp>
#ifdef GVD_BENCH_EMBREE
#include <embree3/rtcore.h>
#endif

#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "render/plan/volume_scan.h"
#include "tests/support/meshes3.h"

namespace gvd {
namespace {

const Box3 kBox{0, 0, 0, 1, 1, 1};

std::vector<Site3> RandomPoints3(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site3> sites;
  sites.reserve(n);
  for (size_t i = 0; i < n; ++i) sites.push_back({std::to_string(i), PointSite3{{u(rng), u(rng), u(rng)}}});
  return sites;
}

// Scene 0: 100,000 random points; scene 1: a torus of 10,000 triangles across the box.
std::shared_ptr<const SiteSnapshot3> Scene(int scene) {
  if (scene == 0) return SiteSnapshot3::Of(1, RandomPoints3(100000, 1));
  return SiteSnapshot3::Of(1, {{"torus", Placed(Torus(0.3, 0.1, 100, 50), {0.5, 0.5, 0.5}, 1)}});
}

Grid3 GridOf(uint32_t n) { return {kBox, n, n, n}; }

// A full render: args (scene, voxels a side).
void BM_ScanVolume(benchmark::State& state) {
  auto sites = Scene(static_cast<int>(state.range(0)));
  const Grid3 grid = GridOf(static_cast<uint32_t>(state.range(1)));
  VolumeScanStats stats;
  for (auto _ : state) {
    stats = {};
    benchmark::DoNotOptimize(ScanVolume(grid, Diagram::kNearest, sites, &stats));
  }
  state.counters["voxels"] = static_cast<double>(grid.voxel_count());
  state.counters["pairs_per_brick"] = static_cast<double>(stats.pairs) / stats.bricks;
  state.SetItemsProcessed(state.iterations() * grid.voxel_count());
}
BENCHMARK(BM_ScanVolume)->Args({0, 128})->Args({1, 128})->Args({0, 256})->Args({1, 256})
    ->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

// One object moved until its volume is made: a point of scene 0, or a small sphere beside
// scene 1's torus, moved back and forth; args as BM_ScanVolume's.
void BM_UpdateVolume(benchmark::State& state) {
  const int scene = static_cast<int>(state.range(0));
  auto sites = Scene(scene);
  std::vector<uint32_t> free_slots;
  auto make = [&](double x) {
    return scene == 0 ? Site3{"7", PointSite3{{x, 0.5, 0.5}}}
                      : Site3{"ball", Placed(Icosphere(2), {x, 0.5, 0.9}, 0.03)};
  };
  sites = Advance(sites, {SiteChange3("x", make(0.3))}, &free_slots);
  const Grid3 grid = GridOf(static_cast<uint32_t>(state.range(1)));
  auto volume = ScanVolume(grid, Diagram::kNearest, sites);
  VolumeScanStats stats;
  int step = 0;
  for (auto _ : state) {
    const Site3 s = make(step++ % 2 ? 0.3 : 0.32);
    sites = Advance(sites, {SiteChange3(s.id, s)}, &free_slots);
    stats = {};
    volume = UpdateVolume(*volume, sites, &stats);
  }
  state.counters["bricks"] = static_cast<double>(stats.bricks);
  state.counters["slices"] = static_cast<double>(stats.slices);
}
BENCHMARK(BM_UpdateVolume)->Args({0, 128})->Args({1, 128})->Args({0, 256})->Args({1, 256})
    ->Unit(benchmark::kMillisecond)->UseRealTime();

std::vector<Vec3> Queries(size_t n) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> q(n);
  for (Vec3& p : q) p = {u(rng), u(rng), u(rng)};
  return q;
}

// Nearest site of one point from the volume (raster answer with its bound; arg 1: refined to
// the exact answer with the nearest point and gradient), scene 0 at 128^3, one thread.
void BM_VolumeNearest(benchmark::State& state) {
  static auto volume = ScanVolume(GridOf(128), Diagram::kNearest, Scene(0));
  const bool exact = state.range(0) == 1;
  auto q = Queries(1 << 16);
  size_t i = 0;
  for (auto _ : state) {
    const Vec3 p = q[i++ & (q.size() - 1)];
    auto a = volume->Nearest(p);
    if (exact) {
      const NearestAnswer r = volume->Refine(p, *a);
      benchmark::DoNotOptimize(NearestFeature(p, volume->sites().get(r.site_index)->geometry));
    }
    benchmark::DoNotOptimize(a);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_VolumeNearest)->Arg(0)->Arg(1);

// The reference: nanoflann's 3D kd-tree over scene 0's points, one thread.
struct Cloud3 {
  std::vector<Vec3> pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  double kdtree_get_pt(size_t i, size_t d) const { return pts[i][static_cast<int>(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using Tree3 = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud3>, Cloud3, 3>;
struct PointTree3 {
  Cloud3 cloud;
  std::unique_ptr<Tree3> tree;
  PointTree3() {
    for (const Site3& s : RandomPoints3(100000, 1)) cloud.pts.push_back(std::get<PointSite3>(s.geometry).p);
    tree = std::make_unique<Tree3>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree->buildIndex();
  }
};
void BM_Nanoflann3Nearest(benchmark::State& state) {
  const PointTree3 points;
  const Tree3& tree = *points.tree;
  auto q = Queries(1 << 16);
  size_t i = 0;
  for (auto _ : state) {
    const Vec3& p = q[i++ & (q.size() - 1)];
    double query[3] = {p.x, p.y, p.z};
    unsigned index;
    double d2;
    tree.knnSearch(query, 1, &index, &d2);
    benchmark::DoNotOptimize(index);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Nanoflann3Nearest);

// A batch of 1,000,000 random points in the box, answered on one thread as FindNearest
// answers a 3D scene's batch with closest points and gradients: args (scene, exact). Raster
// (exact 0): the volume's answer with its bound, then the site's nearest point and gradient;
// exact (1): that answer refined to the exact best site, then the same. Scene 1 is the torus
// at 128^3, beside Embree's closest-point query on the same triangles (BM_EmbreeClosestPoint).
void BM_Batch3(benchmark::State& state) {
  const int scene = static_cast<int>(state.range(0));
  const bool exact = state.range(1) == 1;
  auto volume = ScanVolume(GridOf(128), Diagram::kNearest, Scene(scene));
  const std::vector<Vec3> q = Queries(1000000);
  double sum = 0;
  for (auto _ : state) {
    for (const Vec3& p : q) {
      // As FindNearest answers: the feature comes with the raster answer, and is found anew
      // only when refining changes the site.
      Hit3 hit;
      NearestAnswer a = *volume->Nearest(p, &hit);
      if (exact) {
        const uint32_t before = a.site_index;
        a = volume->Refine(p, a);
        if (a.site_index != before) hit = NearestFeature(p, volume->sites().get(a.site_index)->geometry);
      }
      sum += a.distance + hit.closest.x + hit.gradient.x;
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * q.size());
}
BENCHMARK(BM_Batch3)->Args({0, 0})->Args({0, 1})->Args({1, 0})->Args({1, 1})
    ->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

void BM_Nanoflann3Batch(benchmark::State& state) {
  const PointTree3 points;
  const Tree3& tree = *points.tree;
  const std::vector<Vec3> q = Queries(1000000);
  double sum = 0;
  for (auto _ : state) {
    for (const Vec3& p : q) {
      double query[3] = {p.x, p.y, p.z};
      unsigned index;
      double d2;
      tree.knnSearch(query, 1, &index, &d2);
      sum += d2 + points.cloud.pts[index].x;
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * q.size());
}
BENCHMARK(BM_Nanoflann3Batch)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

#ifdef GVD_BENCH_EMBREE
// Embree's closest-point query (rtcPointQuery, after its closest_point tutorial) over the
// torus's triangles, one thread, 1,000,000 points: each triangle met is scored by the same
// double-precision closest point as ours (NearestOnTriangle), the query's radius shrinking
// to the best so far.
struct EmbreeClosest {
  const MeshSite3* mesh;
  Vec3 q;
  Hit3 best{INFINITY, Vec3(0), FeatureKind::kVertex, 0, Vec3(0)};
};
bool EmbreeScore(RTCPointQueryFunctionArguments* args) {
  auto* c = static_cast<EmbreeClosest*>(args->userPtr);
  const auto& t = c->mesh->triangles[args->primID];
  const Hit3 h = NearestOnTriangle(c->q, c->mesh->vertices[t[0]], c->mesh->vertices[t[1]],
                                   c->mesh->vertices[t[2]]);
  if (h.distance < c->best.distance) {
    c->best = h;
    args->query->radius = static_cast<float>(h.distance);
    return true;
  }
  return false;
}
void BM_EmbreeClosestPoint(benchmark::State& state) {
  const auto sites = Scene(1);
  const MeshSite3& mesh = std::get<MeshSite3>(sites->sites().get(0)->geometry);
  RTCDevice device = rtcNewDevice("threads=1");
  RTCScene scene = rtcNewScene(device);
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
      RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    v[3 * i] = static_cast<float>(mesh.vertices[i].x);
    v[3 * i + 1] = static_cast<float>(mesh.vertices[i].y);
    v[3 * i + 2] = static_cast<float>(mesh.vertices[i].z);
  }
  auto* t = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0,
      RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.triangles.size()));
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) t[3 * i + k] = mesh.triangles[i][k];
  }
  rtcSetGeometryPointQueryFunction(geometry, EmbreeScore);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene);
  const std::vector<Vec3> q = Queries(1000000);
  double sum = 0;
  for (auto _ : state) {
    for (const Vec3& p : q) {
      RTCPointQuery query;
      query.x = static_cast<float>(p.x);
      query.y = static_cast<float>(p.y);
      query.z = static_cast<float>(p.z);
      query.time = 0;
      query.radius = std::numeric_limits<float>::infinity();
      RTCPointQueryContext context;
      rtcInitPointQueryContext(&context);
      EmbreeClosest c{&mesh, p};
      rtcPointQuery(scene, &query, &context, nullptr, &c);
      sum += c.best.distance + c.best.closest.x + c.best.gradient.x;
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * q.size());
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
}
BENCHMARK(BM_EmbreeClosestPoint)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
#endif

}  // namespace
}  // namespace gvd

BENCHMARK_MAIN();
