// What the server's renderers report (render/scene/renderer.h's RenderObserver), logged and
// measured alike for 2D and 3D scenes: each render at debug level with its figures and in the
// render metrics, each failed render at error level.
#pragma once

#include <string>

#include "render/scene/renderer.h"
#include "server/metrics.h"

namespace gvd {

// Thread-safe. `metrics` (may be null) must outlive it.
class RenderTelemetry final : public RenderObserver {
 public:
  explicit RenderTelemetry(Metrics* metrics) : metrics_(metrics) {}
  void Rendered(const std::string& scene_id, uint64_t version, size_t sites,
                const RenderStats& stats, double seconds) override;
  void Failed(const std::string& scene_id, uint64_t version, const absl::Status& error) override;

 private:
  Metrics* const metrics_;
};

}  // namespace gvd
