// Prometheus metrics (prometheus-cpp), served at /metrics on their own port. Thread-safe.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/scene/render_stats.h"

namespace prometheus {
class Exposer;
class Registry;
template <class T>
class Family;
class Counter;
class Gauge;
class Histogram;
}  // namespace prometheus

namespace gvd {

class Metrics {
 public:
  // Per-scene figures, sampled at each scrape.
  struct SceneSample {
    std::string scene;
    double sites;
    double version_lag;        // accepted version - rendered version
    double frame_age_seconds;  // since the rendered frame was published
    double memory_bytes;       // Scene::memory_bytes, what the memory budget charges it
    double render_seconds;     // Scene::render_seconds, its render cost so far
  };
  using SceneSampler = std::function<std::vector<SceneSample>()>;

  Metrics();
  ~Metrics();

  // The memory budget (--max-memory), reported beside the scenes' total.
  void SetMemoryLimit(uint64_t bytes);

  // Serves /metrics on `address` (HOST:PORT; port 0 picks one). Returns the bound port.
  absl::StatusOr<int> Serve(const std::string& address, SceneSampler sampler);
  // The scenes are sampled no more (a scrape under way finishes first): call it before what
  // the sampler reads goes.
  void StopSampling();

  // A call of `method` began, or ended (gvd_rpc_in_flight).
  void RpcStarted(const std::string& method);
  void RpcEnded(const std::string& method);
  void ObserveRpc(const std::string& method, absl::StatusCode code, double seconds);
  // One render of `render_seconds`, as its stats describe it: for a render that drew meshes,
  // the area they drew over the window's; for a computed one, its mean candidates per pixel.
  void ObserveRender(const RenderStats& stats, double render_seconds);
  void ObserveCommit(double seconds);

 private:
  class SceneCollector;
  std::shared_ptr<prometheus::Registry> registry_;
  std::shared_ptr<SceneCollector> scenes_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  prometheus::Family<prometheus::Histogram>* rpc_seconds_;
  prometheus::Family<prometheus::Counter>* rpc_total_;
  prometheus::Family<prometheus::Gauge>* rpc_in_flight_;
  prometheus::Family<prometheus::Histogram>* render_seconds_;
  prometheus::Histogram* readback_seconds_;
  prometheus::Family<prometheus::Counter>* rendered_pixels_;
  prometheus::Family<prometheus::Histogram>* fill_ratio_;
  prometheus::Family<prometheus::Histogram>* candidates_per_pixel_;
  prometheus::Histogram* commit_seconds_;
};

}  // namespace gvd
