#include "render/plan/volume_renderer.h"

#include <chrono>
#include <utility>

#include "render/scene/cpu_pool.h"

namespace gvd {
namespace {

// A volume render's figures as the seam reports them: the voxels rendered, and the mean
// candidate list a voxel scanned (each voxel of a brick scans the brick's list).
RenderStats StatsOf(const VolumeScanStats& scan, bool full) {
  RenderStats stats;
  stats.full = full;
  stats.computed = true;
  stats.pixels = scan.voxels;
  stats.candidates_per_pixel =
      scan.bricks == 0 ? 0 : static_cast<double>(scan.pairs) / static_cast<double>(scan.bricks);
  return stats;
}

}  // namespace

VolumeRenderer::VolumeRenderer(RenderObserver* observer)
    : observer_(observer), thread_([this] { Run(); }) {}

VolumeRenderer::~VolumeRenderer() { Stop(); }

void VolumeRenderer::MarkDirty(std::shared_ptr<Scene3> scene) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!stopping_) {
      if (dirty_.Push(std::move(scene))) cv_.notify_one();
      return;
    }
  }
  scene->FailWaiters(absl::UnavailableError("the server is stopping; no more 3D renders"));
}

absl::StatusOr<std::vector<std::shared_ptr<const Volume>>> VolumeRenderer::RenderWindows(
    std::shared_ptr<const Volume> base, RenderMode, std::vector<Grid3> grids) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_) return absl::UnavailableError("the server is stopping; no more 3D renders");
  }
  std::vector<std::shared_ptr<const Volume>> out;
  out.reserve(grids.size());
  for (const Grid3& grid : grids) {
    out.push_back(ScanVolume(grid, base->diagram(), base->snapshot_ptr()));
  }
  return out;
}

absl::StatusOr<std::shared_ptr<const Volume>> VolumeRenderer::RenderSites(
    std::shared_ptr<const SiteSnapshot3> sites, Grid3 grid, double, RenderMode, Diagram diagram) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_) return absl::UnavailableError("the server is stopping; no more 3D renders");
  }
  return ScanVolume(grid, diagram, std::move(sites));
}

void VolumeRenderer::Stop() {
  std::deque<std::shared_ptr<Scene3>> left;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_ && !thread_.joinable()) return;
    stopping_ = true;
    left = dirty_.TakeAll();
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (auto& scene : left) {
    scene->FailWaiters(absl::UnavailableError("the server is stopping; no more 3D renders"));
  }
}

void VolumeRenderer::RenderNow(Scene3& scene, RenderObserver* observer) {
  const auto started = std::chrono::steady_clock::now();
  auto snapshot = scene.snapshot();
  auto base = scene.frame();
  if (base->version() >= snapshot->version()) return;  // rendered already
  VolumeScanStats stats;
  // A first render, from a volume of no sites, is a full one; later ones follow the change.
  const bool full = base->empty();
  auto volume = full ? ScanVolume(base->grid(), base->diagram(), snapshot, &stats)
                     : UpdateVolume(*base, snapshot, &stats);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  scene.AddRenderSeconds(seconds);
  if (observer) {
    observer->Rendered(scene.id(), volume->version(), snapshot->size(), StatsOf(stats, full),
                       seconds);
  }
  scene.Publish(std::move(volume));
}

void VolumeRenderer::Run() {
  // Calls come before renders, as in the 2D render loop.
  CpuPool::BecomeRenderThread();
  CpuPool::RenderInBackground();
  for (;;) {
    std::shared_ptr<Scene3> scene;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !dirty_.empty(); });
      if (stopping_) return;
      scene = dirty_.TakeFirst([](const Scene3*) { return true; });
    }
    // A scene deleted meanwhile is not rendered; its waiters were failed by its deletion.
    if (!scene->deleted()) RenderNow(*scene, observer_);
    std::lock_guard<std::mutex> lock(mu_);
    dirty_.Rendered(scene.get());
  }
}

}  // namespace gvd
