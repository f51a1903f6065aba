#include "server/render_telemetry.h"

#include "absl/strings/str_cat.h"
#include "server/log.h"

namespace gvd {

void RenderTelemetry::Rendered(const std::string& scene_id, uint64_t version, size_t sites,
                               const RenderStats& stats, double seconds) {
  if (metrics_) metrics_->ObserveRender(stats, seconds);
  const PixelRect& w = stats.window;
  Log(LogLevel::kDebug, "rendered",
      {{"scene", scene_id},
       {"version", absl::StrCat(version)},
       {"sites", absl::StrCat(sites)},
       {"full", stats.full ? "true" : "false"},
       {"window", absl::StrCat(w.x0, ",", w.y0, ",", w.x1, ",", w.y1)},
       {"pixels", absl::StrCat(stats.pixels)},
       {"sites_drawn", absl::StrCat(stats.sites_drawn)},
       {"coverage_ms", absl::StrCat(stats.coverage_seconds * 1e3)},
       {"draw_ms", absl::StrCat(stats.draw_seconds * 1e3)},
       {"readback_ms", absl::StrCat(stats.readback_seconds * 1e3)},
       {"total_ms", absl::StrCat(seconds * 1e3)}});
}

void RenderTelemetry::Failed(const std::string& scene_id, uint64_t version,
                             const absl::Status& error) {
  Log(LogLevel::kError, "render_failed",
      {{"scene", scene_id}, {"version", absl::StrCat(version)}, {"error", error.ToString()}});
}

}  // namespace gvd
