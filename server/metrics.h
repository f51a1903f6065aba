// Prometheus metrics (prometheus-cpp), served at /metrics on their own port. Thread-safe.
#pragma once

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"

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

  // The metrics of one method's calls, made on its first call and kept with the Metrics.
  // Thread-safe.
  class Rpc {
   public:
    // A call began, or ended (gvd_rpc_in_flight).
    void Started();
    void Ended();
    // A call's status and duration (gvd_rpc_total, gvd_rpc_duration_seconds).
    void Observe(absl::StatusCode code, double seconds);

   private:
    friend class Metrics;
    Rpc(Metrics* metrics, const std::string& method);
    prometheus::Family<prometheus::Counter>* const total_;
    const std::string method_;
    prometheus::Gauge* const in_flight_;
    prometheus::Histogram* const seconds_;
    std::array<std::atomic<prometheus::Counter*>, 17> by_code_{};  // absl::StatusCode's
  };
  // `method`'s (the label of every call of it): one lookup a call, where each metric's own
  // lookup by labels would cost thousands of instructions.
  Rpc* RpcOf(const std::string& method);
  // One render of `render_seconds`, as its stats describe it: for a render that drew meshes,
  // the area they drew over the window's; for a computed one, its mean candidates per pixel.
  void ObserveRender(const RenderStats& stats, double render_seconds);
  void ObserveCommit(double seconds);
  // A replica read `scene` again from a store that went back in time, `versions_lost` below
  // the version it held (0 when the store was written past it again).
  void ObserveReload(const std::string& scene, uint64_t versions_lost);

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
  prometheus::Family<prometheus::Counter>* reloads_;
  prometheus::Family<prometheus::Counter>* versions_lost_;
  std::mutex rpcs_mu_;
  absl::flat_hash_map<std::string, std::unique_ptr<Rpc>> rpcs_;  // guarded by rpcs_mu_
};

}  // namespace gvd
