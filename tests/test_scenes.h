// Small helpers shared by the integration tests.
#pragma once

#include <regex>
#include <string>

#include "gvd/v1/voronoi.pb.h"

namespace gvd::testing {

// A CreateSceneRequest for the unit square at width x height pixels.
inline v1::CreateSceneRequest UnitScene(const std::string& id, uint32_t width, uint32_t height) {
  v1::CreateSceneRequest r;
  r.set_scene_id(id);
  r.mutable_window()->set_max_x(1);
  r.mutable_window()->set_max_y(1);
  r.set_width_px(width);
  r.set_height_px(height);
  return r;
}

// The metrics port a server logged ("event=metrics ... port=N"), or 0.
inline int MetricsPort(const std::string& log) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex("event=metrics address=\\S+ port=(\\d+)"))) return 0;
  return std::stoi(m[1]);
}

}  // namespace gvd::testing
