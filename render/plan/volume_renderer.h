// The render thread of 3D scenes, the CPU side of the render seam (render/scene/renderer.h):
// it drains a queue of scenes marked dirty by updates, renders each at its latest version
// into a volume (volume_scan.h: from the scene's last volume, re-rendering only what the
// change can alter; whole for a first render) and publishes it. Bursts of updates to one
// scene coalesce into one render. The voxels are computed on the process's CPU pool
// (ParallelFor); no GL is involved.
#pragma once

#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "render/plan/volume_scan.h"
#include "render/scene/renderer.h"
#include "render/scene/scene.h"

namespace gvd {

// Thread-safe: MarkDirty may come from any thread and never waits for a render.
class VolumeRenderer final : public Renderer3 {
 public:
  // `observer` (may be null) hears of every render; it must outlive the renderer.
  explicit VolumeRenderer(RenderObserver* observer = nullptr);
  ~VolumeRenderer() override;  // Stop()
  VolumeRenderer(const VolumeRenderer&) = delete;
  VolumeRenderer& operator=(const VolumeRenderer&) = delete;

  // Queues a render of the scene at its latest version.
  void MarkDirty(std::shared_ptr<Scene3> scene) override;
  // Each box of `grids` scanned exactly from `base`'s sites, on the calling thread (and the
  // CPU pool): a volume is exact per voxel whatever `mode` asks.
  absl::StatusOr<std::vector<std::shared_ptr<const Volume>>> RenderWindows(
      std::shared_ptr<const Volume> base, RenderMode mode, std::vector<Grid3> grids) override;
  // The box of `grid` scanned exactly from `sites`, on the calling thread (and the CPU pool).
  absl::StatusOr<std::shared_ptr<const Volume>> RenderSites(
      std::shared_ptr<const SiteSnapshot3> sites, Grid3 grid, double eps, RenderMode mode,
      Diagram diagram) override;
  // Finishes the render under way, fails the waiters of the scenes still queued
  // (UNAVAILABLE) and joins the thread. Later MarkDirty calls fail their scene's waiters.
  void Stop() override;

  // Renders the scene's latest version and publishes it, on the calling thread: what the
  // render thread does for each scene it takes (and what a test without one calls).
  static void RenderNow(Scene3& scene, RenderObserver* observer = nullptr);

 private:
  void Run();

  RenderObserver* const observer_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  DirtyQueue<Scene3> dirty_;
  std::thread thread_;  // last: starts once the rest is made
};

}  // namespace gvd
