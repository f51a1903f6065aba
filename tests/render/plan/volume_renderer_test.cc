// 3D scenes (Scene3: render/scene/scene.h on the 3D kernel) rendered by the volume render
// thread (render/plan/volume_renderer.h): writes publish snapshots, the thread publishes
// volumes equal to full renders of them, waiters get the version they wait for, and exact
// answers and picks agree with the tests' own oracle (tests/support/oracle3.h).
#include <gtest/gtest.h>

#include <future>
#include <random>
#include <string>
#include <vector>

#include "render/plan/volume_renderer.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"

namespace gvd {
namespace {

using oracle3::Real;

SceneSettings Settings3() {
  SceneSettings s;
  s.id = "space";
  s.grid = {{0, 0, 8, 6}, 16, 12};
  s.depth = 10;
  s.min_z = -1;
  s.max_z = 4;
  return s;
}

// Waits for the scene's volume of at least `version`.
std::shared_ptr<const Volume> Await(Scene3& scene, uint64_t version) {
  std::promise<absl::StatusOr<std::shared_ptr<const Volume>>> got;
  scene.WhenRendered(version, [&](absl::StatusOr<std::shared_ptr<const Volume>> v) {
    got.set_value(std::move(v));
  });
  auto v = got.get_future().get();
  EXPECT_TRUE(v.ok()) << v.status();
  return v.ok() ? *v : nullptr;
}

void ExpectSameVoxels(const Volume& a, const Volume& b) {
  const Grid3& g = a.grid();
  int differ = 0;
  for (uint32_t k = 0; k < g.depth; ++k) {
    for (uint32_t j = 0; j < g.height; ++j) {
      for (uint32_t i = 0; i < g.width; ++i) {
        differ += a.id_at(i, j, k) != b.id_at(i, j, k) || a.distance_at(i, j, k) != b.distance_at(i, j, k);
      }
    }
  }
  EXPECT_EQ(differ, 0);
}

TEST(Scene3, RendersEachVersionAndAnswersExactly) {
  // What the renderer reports through the render seam.
  struct Reports final : RenderObserver {
    void Rendered(const std::string&, uint64_t, size_t, const RenderStats& stats,
                  double) override {
      std::lock_guard<std::mutex> lock(mu);
      renders.push_back(stats);
    }
    void Failed(const std::string&, uint64_t, const absl::Status&) override {}
    std::mutex mu;
    std::vector<RenderStats> renders;
  } reports;
  std::vector<RenderStats>& renders = reports.renders;
  std::mutex& mu = reports.mu;
  VolumeRenderer renderer(&reports);
  auto scene = std::make_shared<Scene3>(Settings3());
  EXPECT_EQ(scene->settings().grid3().voxel_count(), 16u * 12 * 10);
  std::vector<Site3> sites = {
      {"a", PointSite3{{1, 1, 0}}},
      {"b", SegmentSite3{{5, 1, -2}, {5, 5, 6}}},  // through the box and out of it
      {"c", TriangleSite3{{0, 6, 1}, {8, 6, 1}, {4, 3, 1.25}}},
      {"ball", Placed(Icosphere(2), {6, 4, 2}, 0.8)},
  };
  auto v1 = scene->Upsert(sites, 100);
  ASSERT_TRUE(v1.ok()) << v1.status();
  renderer.MarkDirty(scene);
  auto volume = Await(*scene, *v1);
  ASSERT_NE(volume, nullptr);
  EXPECT_EQ(volume->version(), *v1);
  ExpectSameVoxels(*volume, *ScanVolume(scene->settings().grid3(), Diagram::kNearest, scene->snapshot()));

  // A small move re-renders a part of the volume, equal to a full render of the version.
  auto v2 = scene->Upsert({{"a", PointSite3{{1.2, 1, 0}}}}, 100);
  ASSERT_TRUE(v2.ok());
  renderer.MarkDirty(scene);
  volume = Await(*scene, *v2);
  ExpectSameVoxels(*volume, *ScanVolume(scene->settings().grid3(), Diagram::kNearest, scene->snapshot()));
  {
    std::lock_guard<std::mutex> lock(mu);
    ASSERT_EQ(renders.size(), 2u);
    EXPECT_TRUE(renders[0].full);
    EXPECT_FALSE(renders[1].full);
    EXPECT_EQ(renders[0].pixels, scene->settings().grid3().voxel_count());
    EXPECT_LT(renders[1].pixels, renders[0].pixels);
  }

  // A box of space at a resolution of its own (a zoom window): each voxel centre holds the
  // value of the best site there, as the oracle measures it.
  const Grid3 zoom{{1, 1, 0, 5, 4, 2}, 8, 6, 4};
  auto windows = renderer.RenderWindows(volume, RenderMode::kExact, {zoom});
  ASSERT_TRUE(windows.ok()) << windows.status();
  ASSERT_EQ(windows->size(), 1u);
  const Volume& window = *(*windows)[0];
  EXPECT_EQ(window.version(), *v2);
  const std::vector<Site3> moved = {{"a", PointSite3{{1.2, 1, 0}}}, sites[1], sites[2], sites[3]};
  auto expect_oracle = [&](const Volume& v) {
    for (uint32_t k = 0; k < zoom.depth; ++k) {
      for (uint32_t j = 0; j < zoom.height; ++j) {
        for (uint32_t i = 0; i < zoom.width; ++i) {
          const Vec3 c = zoom.Center(i, j, k);
          Real best = INFINITY;
          for (const Site3& s : moved) best = std::min(best, oracle3::ToGeometry(c, s.geometry));
          ASSERT_NE(v.id_at(i, j, k), 0u);
          EXPECT_NEAR(v.distance_at(i, j, k), double(best), 1e-5 * (1 + double(best)));
        }
      }
    }
  };
  expect_oracle(window);
  // The same sites as no scene's, rendered whole over that box: the same values.
  auto whole = renderer.RenderSites(SiteSnapshot3::Of(1, moved), zoom, 0, RenderMode::kExact,
                                    Diagram::kNearest);
  ASSERT_TRUE(whole.ok()) << whole.status();
  expect_oracle(**whole);

  // Exact answers at 3D points, inside the box and out of it, with their features.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-3, 10);
  std::vector<Vec3> points;
  for (int i = 0; i < 500; ++i) points.push_back({u(rng), u(rng), u(rng) * 0.5});
  std::vector<Scene3::ExactAnswer> answers;
  EXPECT_EQ(scene->NearestExact(points, &answers), *v2);
  std::vector<Site3> now = {{"a", PointSite3{{1.2, 1, 0}}}, sites[1], sites[2], sites[3]};
  for (size_t i = 0; i < points.size(); ++i) {
    Real best = INFINITY;
    for (const Site3& s : now) best = std::min(best, oracle3::ToGeometry(points[i], s.geometry));
    ASSERT_TRUE(answers[i].found);
    EXPECT_NEAR(answers[i].distance, double(best), 1e-9);
    EXPECT_NEAR(Distance(answers[i].closest, points[i]), double(best), 1e-9);
    const Scene3::Picked p = scene->Pick(points[i], INFINITY);
    ASSERT_TRUE(p.found);
    EXPECT_NEAR(p.distance, double(best), 1e-9);
    EXPECT_EQ(p.site->id, answers[i].site_id);
  }

  // Deleting every site empties the volume.
  auto v3 = scene->Delete({"a", "b", "c", "ball"});
  ASSERT_TRUE(v3.ok());
  renderer.MarkDirty(scene);
  volume = Await(*scene, *v3);
  EXPECT_TRUE(volume->empty());
  EXPECT_FALSE(volume->Nearest({1, 1, 1}).has_value());
}

TEST(Scene3, StoppingFailsTheWaiters) {
  auto scene = std::make_shared<Scene3>(Settings3());
  VolumeRenderer renderer;
  renderer.Stop();
  auto v = scene->Upsert({{"a", PointSite3{{1, 1, 1}}}}, 10);
  ASSERT_TRUE(v.ok());
  std::promise<absl::Status> got;
  scene->WhenRendered(*v, [&](absl::StatusOr<std::shared_ptr<const Volume>> r) { got.set_value(r.status()); });
  renderer.MarkDirty(scene);
  EXPECT_EQ(got.get_future().get().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(renderer.RenderSites(SiteSnapshot3::Of(1, {}), Settings3().grid3(), 0,
                                 RenderMode::kExact, Diagram::kNearest)
                .status()
                .code(),
            absl::StatusCode::kUnavailable);
}

}  // namespace
}  // namespace gvd
