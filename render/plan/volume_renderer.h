// The render thread of 3D scenes: it drains a queue of scenes marked dirty by updates,
// renders each at its latest version into a volume (volume_scan.h: from the scene's last
// volume, re-rendering only what the change can alter; whole for a first render) and
// publishes it. Bursts of updates to one scene coalesce into one render. The voxels are
// computed on the process's CPU pool (ParallelFor); no GL is involved.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

#include "render/plan/volume_scan.h"
#include "render/scene/scene.h"

namespace gvd {

// Thread-safe: MarkDirty may come from any thread and never waits for a render.
class VolumeRenderer {
 public:
  // What the render thread reports after each render, before its waiters resume (may be
  // empty): the scene, the version rendered, the work and the seconds it took.
  using Observer = std::function<void(const Scene3& scene, uint64_t version,
                                      const VolumeScanStats& stats, double seconds)>;
  explicit VolumeRenderer(Observer observer = nullptr);
  ~VolumeRenderer();  // Stop()
  VolumeRenderer(const VolumeRenderer&) = delete;
  VolumeRenderer& operator=(const VolumeRenderer&) = delete;

  // Queues a render of the scene at its latest version.
  void MarkDirty(std::shared_ptr<Scene3> scene);
  // Finishes the render under way, fails the waiters of the scenes still queued
  // (UNAVAILABLE) and joins the thread. Later MarkDirty calls fail their scene's waiters.
  void Stop();

  // Renders the scene's latest version and publishes it, on the calling thread: what the
  // render thread does for each scene it takes (and what a test without one calls).
  static void RenderNow(Scene3& scene, const Observer& observer = nullptr);

 private:
  void Run();

  const Observer observer_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::deque<std::shared_ptr<Scene3>> queue_;
  std::set<const Scene3*> queued_;
  std::thread thread_;  // last: starts once the rest is made
};

}  // namespace gvd
