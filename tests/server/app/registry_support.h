// What the application core's tests share: a scene's settings, a point site, and a job run
// to its end.
#pragma once

#include <future>
#include <memory>
#include <string>

#include "server/app/jobs.h"
#include "server/app/scene_handle.h"

namespace gvd {

inline SceneSettings Settings(const std::string& id, uint32_t side = 64) {
  SceneSettings s;
  s.id = id;
  s.grid = {{0, 0, 1, 1}, side, side};
  s.eps = s.grid.pixel_size();
  s.cone_triangles = 3;  // a count the store takes; nothing here draws a mesh
  return s;
}

inline Site Point(const std::string& id, double x, double y) { return {id, PointSite{{x, y}}}; }

// A registry's scene as S: the test knows its dimension.
template <class S = Scene>
absl::StatusOr<std::shared_ptr<S>> As(const absl::StatusOr<SceneHandle>& handle) {
  if (!handle.ok()) return handle.status();
  return handle->As<S>();
}

// Waits for a job and returns its status.
inline absl::Status RunJob(const std::shared_ptr<FrameJob>& job) {
  std::promise<absl::Status> done;
  job->Start([&](const absl::Status& s) { done.set_value(s); });
  return done.get_future().get();
}

}  // namespace gvd
