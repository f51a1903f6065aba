// The render thread: it alone owns the GL context. It drains a queue of scenes marked dirty
// by updates, renders each at its latest version, and publishes the frame. Bursts of updates
// to one scene coalesce into one render.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "absl/status/status.h"
#include "gl/context.h"
#include "gl/zoom.h"
#include "server/metrics.h"
#include "core/scene.h"

namespace gvd {

// Threads: one thread of its own, the only one that touches GL; it renders, reads back and
// publishes frames, and runs the zoom tasks handed to it. Its public calls are thread-safe
// (mu_ guards the queues) and never wait for a render, except Zoom, which waits for its own
// task and must not be called from the render thread.
class RenderLoop {
 public:
  RenderLoop() = default;
  ~RenderLoop();  // stops the thread
  RenderLoop(const RenderLoop&) = delete;
  RenderLoop& operator=(const RenderLoop&) = delete;

  // Starts the thread and waits until it has a GL context and compiled shaders; returns why
  // it could not. Call once.
  absl::Status Start(DevicePreference preference);
  // Finishes the render in progress, fails the scenes still queued, and joins the thread.
  void Stop();

  // The device the context runs on. Valid after Start succeeded.
  const DeviceInfo& device() const { return device_; }

  // Queues a render of the scene at its latest version. Thread-safe; never blocks on a render.
  void MarkDirty(std::shared_ptr<Scene> scene);

  // Renders zoom windows of `base` (gl/zoom.h) on the render thread, between scene
  // renders, and waits for them. Thread-safe; never call it from the render thread. Fails
  // with Unavailable once the loop stops.
  absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> Zoom(std::shared_ptr<const Frame> base,
                                                                 RenderMode mode,
                                                                 std::vector<Grid> grids);

  // Renders are observed here from now on (null: none). Call before Start.
  void set_metrics(Metrics* metrics) { metrics_ = metrics; }

  // A test hook: when the environment variable GVD_TEST_HOLD_RENDERS names a path at Start,
  // the thread renders no scene while a file exists at that path (zoom windows still run), so
  // tests can hold a version unrendered for as long as they need, whatever the machine's speed.
  static constexpr const char* kHoldRendersVariable = "GVD_TEST_HOLD_RENDERS";

 private:
  void Run(DevicePreference preference);

  std::thread thread_;
  DeviceInfo device_;
  Metrics* metrics_ = nullptr;
  std::string hold_path_;  // see kHoldRendersVariable; empty: no hold

  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool started_ = false;
  bool stopping_ = false;
  absl::Status start_status_;
  std::deque<std::shared_ptr<Scene>> queue_;
  std::set<const Scene*> queued_;
  // Work for the GL context other than scene renders (zooms); each is told whether the loop
  // still runs.
  std::deque<std::function<void(Rasterizer*, ZoomRenderer*)>> tasks_;
};

}  // namespace gvd
