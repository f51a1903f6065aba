// The render threads of 2D scenes, the GL side of the render seam (render/scene/renderer.h):
// each alone owns a GL context of its own. They drain one queue of scenes marked dirty by
// updates, render each at its latest version, and publish the frame. Bursts of updates to one
// scene coalesce into one render; a scene is rendered by one thread at a time.
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "render/gl/context.h"
#include "render/gl/zoom.h"
#include "render/scene/render_stats.h"
#include "render/scene/renderer.h"
#include "render/scene/scene.h"

namespace gvd {

// Threads: `lanes` threads of its own, the only ones that touch GL; they render, read back
// and publish frames, and run the zoom tasks handed to them. Its public calls are
// thread-safe (mu_ guards the queues) and never wait for a render, except RenderWindows,
// which waits for its own task and must not be called from a render thread.
//
// Fairness: a scene's GPU state lives on the lane that rendered it last, which renders it
// again. While that lane is busy with another scene, an idle lane takes the scene over
// (rendering it whole on its own context, and the first lane drops its state): so one huge
// render holds up only its own scene, and with L lanes every other scene's update waits at
// most for the renders already under way on the other L - 1 lanes, never for the huge one.
// On Mesa's software device the lanes take turns at GL (GlTurn, render/gl/context.h): one
// makes GL calls while the others compute on the CPU (the native scan) or wait; a lane
// waiting on the test hook holds no turn.
// How many times a render's own time a render thread rests after a render nobody waited for
// or watches (RenderLoop::MarkDirty): such renders take at most a fifth of its time.
inline constexpr double kBackgroundRest = 4;

class RenderLoop final : public Renderer {
 public:
  // `observer` (may be null) hears of every render; it must outlive the loop.
  // `background_rest`: how many times a render's own time its lane rests after a render
  // nobody waited for or watches (MarkDirty; kBackgroundRest; zero: none).
  explicit RenderLoop(int lanes = 2, RenderObserver* observer = nullptr,
                      double background_rest = kBackgroundRest)
      : lanes_(lanes < 1 ? 1 : lanes), observer_(observer),
        background_rest_(std::max(background_rest, 0.0)),
        wake_(new std::condition_variable[lanes_]), waiting_(lanes_, false), busy_(lanes_, false),
        taken_from_(lanes_) {}
  ~RenderLoop() override;  // stops the threads
  RenderLoop(const RenderLoop&) = delete;
  RenderLoop& operator=(const RenderLoop&) = delete;

  // Starts the threads and waits until each has a GL context and compiled shaders; returns
  // why one could not. Call once.
  absl::Status Start(DevicePreference preference);
  // Finishes the render in progress, fails the scenes still queued, and joins the threads.
  void Stop() override;

  // The device the context runs on. Valid after Start succeeded.
  const DeviceInfo& device() const { return device_; }

  // Queues a render of the scene at its latest version. Thread-safe; never blocks on a render.
  // After a render that no caller waited for (RenderWait::callers()) of a scene nobody
  // watches (Scene::watched), its lane rests background_rest times the render's time: renders
  // nobody waits for take at most 1 / (1 + background_rest) of each lane's time, and what
  // changes meanwhile is rendered at once after. SCHED_IDLE alone does not bound their share:
  // the scheduler shares the cores between groups of processes (sessions, cgroups) before it
  // looks at a thread's policy, so the background yields to this process's calls but competes
  // as an equal with another group's work, such as a database's backends on the same
  // machine. A rest ends as soon as a caller waits or a watched scene is queued.
  void MarkDirty(std::shared_ptr<Scene> scene) override;

  // Renders zoom windows of `base` (render/gl/zoom.h) on a render thread, between scene
  // renders, and waits for them. Thread-safe; never call it from a render thread. Fails
  // with Unavailable once the loop stops.
  absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> RenderWindows(
      std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids) override;

  // Renders `sites` whole (SceneRaster, as a scene's first render) on a render thread,
  // between scene renders, and waits for it; the same threading as RenderWindows.
  absl::StatusOr<std::shared_ptr<const Frame>> RenderSites(std::shared_ptr<const SiteSnapshot> sites,
                                                           Grid grid, double eps, RenderMode mode,
                                                           Diagram diagram) override;

  int lanes() const { return lanes_; }

  // A test hook: when the environment variable GVD_TEST_HOLD_RENDERS names a path at Start,
  // no scene is rendered while a file exists at that path (zoom windows still run), so tests
  // can hold a version unrendered for as long as they need, whatever the machine's speed.
  // While a file exists at that path + "." + a scene's id, a full render of that scene
  // waits in its plan, off GL, as if its planning went on: a long render, at any machine's
  // speed. While it waits, a file exists at that path + "." + the id + ".waiting", and the
  // zoom windows queued for its render thread wait with it.
  static constexpr const char* kHoldRendersVariable = "GVD_TEST_HOLD_RENDERS";

 private:
  // Work for a render thread between scene renders: given its rasterizer and zoom renderer,
  // or null ones when the loop stops before running it.
  using Task = std::function<void(Rasterizer*, ZoomRenderer*)>;
  // Queues `task` for the first free render thread; false when the loop is not running.
  bool Enqueue(Task task);
  void Run(int lane, DevicePreference preference);
  // The first queued scene `lane` may render now, removed from the queue (null if none):
  // not being rendered, and its own, nobody's, or a busy lane's; wakes the idle lanes if
  // more are queued, as this lane is busy now. Under mu_.
  std::shared_ptr<Scene> Take(int lane);
  // Wakes `lane` if it sleeps for want of work (waiting_), under mu_: each lane sleeps on a
  // condition of its own, so that a scene marked dirty wakes the one lane that will take it
  // rather than every lane (a woken lane that finds nothing to take costs the waker and the
  // machine a wake-up on another core, on the path of the call that marked the scene).
  void Wake(int lane);
  // Wakes every lane that sleeps for want of work. Under mu_.
  void WakeSleeping();
  // Wakes every lane, whether it sleeps, rests or waits in a test hook. Under mu_.
  void WakeAll();

  const int lanes_;
  std::vector<std::thread> threads_;
  DeviceInfo device_;
  RenderObserver* const observer_;
  const double background_rest_;
  uint64_t waker_ = 0;  // RenderWait::WakeOnCaller's token, from Start to Stop
  std::string hold_path_;  // see kHoldRendersVariable; empty: no hold

  mutable std::mutex mu_;
  std::condition_variable cv_;  // the lanes' start, for Start
  // Per lane: its own condition (Wake), and whether it sleeps for want of work.
  std::unique_ptr<std::condition_variable[]> wake_;
  std::vector<bool> waiting_;
  int started_ = 0;  // lanes that have tried to make their context
  bool stopping_ = false;
  absl::Status start_status_;  // the first lane's failure, if any
  DirtyQueue<Scene> dirty_;
  std::map<const Scene*, int> owner_;      // the lane holding each scene's GPU state
  std::vector<bool> busy_;                 // per lane: rendering a scene
  // Per lane: scenes other lanes took over, whose GPU state it is to release now.
  std::vector<std::vector<const Scene*>> taken_from_;
  // Work for the GL context other than scene renders (zooms); each is told whether the loop
  // still runs.
  std::deque<Task> tasks_;
};

}  // namespace gvd
