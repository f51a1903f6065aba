// 3D volumes rendered exactly on the CPU (render/plan/volume_scan.h) and queried, beside the
// references users would pick: nanoflann's 3D kd-tree for nearest points; scipy's 3D
// distance_transform_edt is timed on the same inputs by volume_bench.py in the same run.
#include <benchmark/benchmark.h>
#include <nanoflann.hpp>

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
void BM_Nanoflann3Nearest(benchmark::State& state) {
  Cloud3 cloud;
  for (const Site3& s : RandomPoints3(100000, 1)) cloud.pts.push_back(std::get<PointSite3>(s.geometry).p);
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud3>,
                                                   Cloud3, 3>;
  Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
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

}  // namespace
}  // namespace gvd

BENCHMARK_MAIN();
