#include "server/metrics.h"

#include <prometheus/collectable.h>
#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/metric_family.h>
#include <prometheus/registry.h>

#include <mutex>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace gvd {
namespace {

// Exponential buckets from 10 us to about 40 s.
prometheus::Histogram::BucketBoundaries Seconds() {
  prometheus::Histogram::BucketBoundaries b;
  for (double v = 1e-5; v < 60; v *= 2.5) b.push_back(v);
  return b;
}

// Drawn area over the window's: an incremental render draws a small part of it, a full one
// at least all of it (3 is the aim, tens what whole-tile coverage draws).
prometheus::Histogram::BucketBoundaries FillRatios() {
  return {1e-4, 1e-3, 0.01, 0.1, 1, 1.5, 2, 3, 5, 10, 20, 50, 100, 200, 500, 1000};
}

prometheus::MetricFamily Gauge(const std::string& name, const std::string& help) {
  prometheus::MetricFamily f;
  f.name = name;
  f.help = help;
  f.type = prometheus::MetricType::Gauge;
  return f;
}

}  // namespace

// Samples the scenes when scraped.
class Metrics::SceneCollector : public prometheus::Collectable {
 public:
  void Set(SceneSampler sampler) {
    std::lock_guard<std::mutex> lock(mu_);
    sampler_ = std::move(sampler);
  }
  void SetMemoryLimit(double bytes) {
    std::lock_guard<std::mutex> lock(mu_);
    memory_limit_ = bytes;
  }
  std::vector<prometheus::MetricFamily> Collect() const override {
    std::lock_guard<std::mutex> lock(mu_);
    if (!sampler_) return {};
    auto sites = Gauge("gvd_scene_sites", "Sites in the scene.");
    auto lag = Gauge("gvd_scene_version_lag",
                     "Accepted versions of the scene not yet in its rendered frame.");
    auto age = Gauge("gvd_scene_frame_age_seconds", "Age of the scene's rendered frame.");
    auto memory = Gauge("gvd_scene_memory_bytes",
                        "Bytes the memory budget charges the scene: its raster and its sites.");
    auto render = Gauge("gvd_scene_render_seconds_total",
                        "Time the render threads have spent on the scene (its render cost).");
    auto total = Gauge("gvd_memory_bytes", "Bytes the scenes hold together (of --max-memory).");
    auto limit = Gauge("gvd_memory_limit_bytes", "The memory budget, --max-memory.");
    double sum = 0;
    for (const SceneSample& s : sampler_()) {
      for (auto [family, value] : {std::pair{&sites, s.sites}, {&lag, s.version_lag},
                                   {&age, s.frame_age_seconds}, {&memory, s.memory_bytes},
                                   {&render, s.render_seconds}}) {
        prometheus::ClientMetric m;
        m.label.push_back({"scene", s.scene});
        m.gauge.value = value;
        family->metric.push_back(std::move(m));
      }
      sum += s.memory_bytes;
    }
    total.metric.emplace_back().gauge.value = sum;
    limit.metric.emplace_back().gauge.value = memory_limit_;
    return {sites, lag, age, memory, render, total, limit};
  }

 private:
  mutable std::mutex mu_;
  SceneSampler sampler_;
  double memory_limit_ = 0;
};

Metrics::Metrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      scenes_(std::make_shared<SceneCollector>()) {
  rpc_seconds_ = &prometheus::BuildHistogram()
                      .Name("gvd_rpc_duration_seconds")
                      .Help("Time from a call's arrival to its status, by method.")
                      .Register(*registry_);
  rpc_total_ = &prometheus::BuildCounter()
                    .Name("gvd_rpc_total")
                    .Help("Calls finished, by method and status code.")
                    .Register(*registry_);
  rpc_in_flight_ = &prometheus::BuildGauge()
                        .Name("gvd_rpc_in_flight")
                        .Help("Calls begun and not yet finished, by method.")
                        .Register(*registry_);
  render_seconds_ = &prometheus::BuildHistogram()
                         .Name("gvd_render_seconds")
                         .Help("Renders, from taking the changes to the frame (readback "
                               "included), by kind: full or incremental.")
                         .Register(*registry_);
  readback_seconds_ = &prometheus::BuildHistogram()
                           .Name("gvd_readback_seconds")
                           .Help("Reading rendered windows back from the GPU.")
                           .Register(*registry_)
                           .Add({}, Seconds());
  rendered_pixels_ = &prometheus::BuildCounter()
                          .Name("gvd_rendered_pixels_total")
                          .Help("Pixels redrawn and read back, by kind.")
                          .Register(*registry_);
  fill_ratio_ = &prometheus::BuildHistogram()
                     .Name("gvd_render_fill_ratio")
                     .Help("Area of the meshes a render drew over the window's area, by kind "
                           "(a full render covers the window at least once).")
                     .Register(*registry_);
  candidates_per_pixel_ = &prometheus::BuildHistogram()
                               .Name("gvd_render_candidates_per_pixel")
                               .Help("Sites a computed render scanned per pixel, on average, "
                                     "by kind.")
                               .Register(*registry_);
  commit_seconds_ = &prometheus::BuildHistogram()
                         .Name("gvd_store_commit_seconds")
                         .Help("Store transactions, BEGIN to durable COMMIT.")
                         .Register(*registry_)
                         .Add({}, Seconds());
  reloads_ = &prometheus::BuildCounter()
                  .Name("gvd_store_reloads_total")
                  .Help("Scenes read again from a shared store that went back in time (a "
                        "restore, a failover that lost commits), by scene.")
                  .Register(*registry_);
  versions_lost_ = &prometheus::BuildCounter()
                        .Name("gvd_store_versions_lost_total")
                        .Help("Versions a replica held beyond the head of a store that went "
                              "back in time, by scene (0 for a store written past them again).")
                        .Register(*registry_);
}

Metrics::~Metrics() = default;

void Metrics::ObserveReload(const std::string& scene, uint64_t versions_lost) {
  reloads_->Add({{"scene", scene}}).Increment();
  versions_lost_->Add({{"scene", scene}}).Increment(static_cast<double>(versions_lost));
}

void Metrics::SetMemoryLimit(uint64_t bytes) { scenes_->SetMemoryLimit(static_cast<double>(bytes)); }

absl::StatusOr<int> Metrics::Serve(const std::string& address, SceneSampler sampler) {
  scenes_->Set(std::move(sampler));
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(address);
  } catch (const std::exception& e) {
    return absl::UnavailableError(absl::StrCat("cannot serve metrics on ", address, ": ", e.what()));
  }
  exposer_->RegisterCollectable(registry_);
  exposer_->RegisterCollectable(scenes_);
  auto ports = exposer_->GetListeningPorts();
  return ports.empty() ? 0 : ports[0];
}

void Metrics::StopSampling() { scenes_->Set(nullptr); }

Metrics::Rpc::Rpc(Metrics* metrics, const std::string& method)
    : total_(metrics->rpc_total_),
      method_(method),
      in_flight_(&metrics->rpc_in_flight_->Add({{"method", method}})),
      seconds_(&metrics->rpc_seconds_->Add({{"method", method}}, Seconds())) {}

void Metrics::Rpc::Started() { in_flight_->Increment(); }

void Metrics::Rpc::Ended() { in_flight_->Decrement(); }

void Metrics::Rpc::Observe(absl::StatusCode code, double seconds) {
  seconds_->Observe(seconds);
  const size_t c = static_cast<size_t>(code);
  if (c >= by_code_.size()) {  // not a code absl names today
    total_->Add({{"method", method_}, {"code", absl::StatusCodeToString(code)}}).Increment();
    return;
  }
  prometheus::Counter* counter = by_code_[c].load(std::memory_order_acquire);
  if (counter == nullptr) {  // the family gives a racing caller the same counter
    counter = &total_->Add({{"method", method_}, {"code", absl::StatusCodeToString(code)}});
    by_code_[c].store(counter, std::memory_order_release);
  }
  counter->Increment();
}

Metrics::Rpc* Metrics::RpcOf(const std::string& method) {
  std::lock_guard<std::mutex> lock(rpcs_mu_);
  std::unique_ptr<Rpc>& rpc = rpcs_[method];
  if (rpc == nullptr) rpc.reset(new Rpc(this, method));
  return rpc.get();
}

void Metrics::ObserveRender(const RenderStats& stats, double render_seconds) {
  const char* kind = stats.full ? "full" : "incremental";
  render_seconds_->Add({{"kind", kind}}, Seconds()).Observe(render_seconds);
  if (stats.computed) {
    candidates_per_pixel_->Add({{"kind", kind}}, FillRatios()).Observe(stats.candidates_per_pixel);
  } else {
    fill_ratio_->Add({{"kind", kind}}, FillRatios()).Observe(stats.fill_ratio);
  }
  readback_seconds_->Observe(stats.readback_seconds);
  rendered_pixels_->Add({{"kind", kind}}).Increment(static_cast<double>(stats.pixels));
}

void Metrics::ObserveCommit(double seconds) { commit_seconds_->Observe(seconds); }

}  // namespace gvd
