// The render seam: how the application core asks for renders of its scenes and hears of
// them, with no knowledge of what renders them. The 2D scenes' renderer is the GL render
// threads (render/gl/render_loop.h), the 3D scenes' the volume scan on the CPU
// (render/plan/volume_renderer.h); the server's main builds both and hands them to the core.
#pragma once

#include <deque>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/scene/cpu_pool.h"
#include "render/scene/render_stats.h"
#include "render/scene/scene.h"

namespace gvd {

// Hears of every render a renderer does, on the thread that did it: each render about to be
// published (before the waiters for its frame resume), and each render that failed (its
// waiters fail with the error). Implementations must be quick and thread-safe.
class RenderObserver {
 public:
  virtual ~RenderObserver() = default;
  virtual void Rendered(const std::string& scene_id, uint64_t version, size_t sites,
                        const RenderStats& stats, double seconds) = 0;
  virtual void Failed(const std::string& scene_id, uint64_t version, const absl::Status& error) = 0;
};

// Renders the scenes of one kernel's sites (a template on the scene: Scene or Scene3).
// Thread-safe: every call may come from any thread.
template <class S>
class BasicRenderer {
 public:
  using Frame = typename S::Frame;
  using Grid = typename SceneFrames<typename S::Kernel>::Grid;
  using Snapshot = typename S::Snapshot;
  virtual ~BasicRenderer() = default;

  // Queues a render of the scene at its latest version; the renderer publishes the frame
  // (S::Publish). Never waits for a render. Bursts of calls for one scene coalesce into one
  // render. After Stop, fails the scene's waiters (UNAVAILABLE) instead.
  virtual void MarkDirty(std::shared_ptr<S> scene) = 0;
  // The scene's sites as `base` holds them, rendered anew over each of `grids` (windows of
  // the plane, or boxes of space, at resolutions of their own: zoom windows, paper sec. 6.2)
  // in `mode`, between scene renders, and waits for them. UNAVAILABLE once stopped.
  // CONTRACT: not called from the renderer's own threads.
  virtual absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> RenderWindows(
      std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids) = 0;
  // `sites`, a snapshot of no scene, rendered whole over `grid` in `mode` (a scene's first
  // render's path, with eps the plane's error bound), between scene renders, and waits for
  // it: a one-off diagram, such as a mosaic's. UNAVAILABLE once stopped.
  // CONTRACT: not called from the renderer's own threads.
  virtual absl::StatusOr<std::shared_ptr<const Frame>> RenderSites(
      std::shared_ptr<const Snapshot> sites, Grid grid, double eps, RenderMode mode,
      Diagram diagram) = 0;
  // Finishes the render under way, fails the waiters of the scenes still queued
  // (UNAVAILABLE) and stops the renderer's threads. Idempotent.
  virtual void Stop() = 0;
};
// The plane's renderers and space's, as Scene and Scene3 are the plane's scenes and space's.
using Renderer = BasicRenderer<Scene>;
using Renderer3 = BasicRenderer<Scene3>;

// The scenes waiting for a render, in the order they were marked, each once: what every
// renderer keeps; and the scenes taken and not yet rendered. Each holds a render due
// (RenderDue) from its queueing until the render that took it is done, so that a render left
// in the background too long is raised. Not thread-safe: the renderer's own lock guards it.
template <class S>
class DirtyQueue {
 public:
  // Queues the scene unless it is queued already; false then.
  bool Push(std::shared_ptr<S> scene) {
    if (!due_.try_emplace(scene.get()).second) return false;
    queue_.push_back(std::move(scene));
    return true;
  }
  // Puts a scene taken back at the head of the queue (unless it was queued again meanwhile),
  // due since it was first queued.
  void PushFront(std::shared_ptr<S> scene) {
    auto taken = rendering_.extract(scene.get());
    const bool queued = due_.count(scene.get()) > 0;
    if (taken) {
      due_.erase(scene.get());
      due_.insert(std::move(taken));
    } else {
      due_.try_emplace(scene.get());
    }
    if (!queued) queue_.push_front(std::move(scene));
  }
  // Takes the first scene `accept` takes, in queue order; null when none. Its render is due
  // until Rendered.
  template <class Accept>
  std::shared_ptr<S> TakeFirst(Accept accept) {
    for (auto it = queue_.begin(); it != queue_.end(); ++it) {
      if (!accept(it->get())) continue;
      std::shared_ptr<S> taken = std::move(*it);
      queue_.erase(it);
      rendering_.insert(due_.extract(taken.get()));
      return taken;
    }
    return nullptr;
  }
  // The render of a scene taken is done (published, failed, or not needed after all).
  void Rendered(const S* scene) { rendering_.erase(scene); }
  // Whether the scene was taken and its render is not done.
  bool rendering(const S* scene) const { return rendering_.count(scene) > 0; }
  bool empty() const { return queue_.empty(); }
  // Whether a queued scene satisfies `pred`.
  template <class Pred>
  bool Any(Pred pred) const {
    for (const auto& scene : queue_) {
      if (pred(static_cast<const S*>(scene.get()))) return true;
    }
    return false;
  }
  // Empties the queue, returning what it held (to fail their waiters outside the lock).
  std::deque<std::shared_ptr<S>> TakeAll() {
    due_.clear();
    return std::exchange(queue_, {});
  }

 private:
  std::deque<std::shared_ptr<S>> queue_;
  std::map<const S*, RenderDue> due_;        // the queued scenes'
  std::map<const S*, RenderDue> rendering_;  // the scenes taken, until Rendered
};

}  // namespace gvd
