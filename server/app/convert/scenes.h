// Scenes: CreateSceneRequest into the settings of a scene, and a scene (loaded or only
// stored, of either dimension) into the API's Scene.
#pragma once

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/scene/scene.h"
#include "server/app/limits.h"
#include "server/app/registry.h"

namespace gvd {

// Checks a CreateSceneRequest and derives the scene's settings (eps = one pixel for 0); a
// request with depth_px makes a 3D scene's.
absl::Status ToSceneSettings(const v1::CreateSceneRequest& request, const ServerLimits& limits,
                             SceneSettings* settings);

// The settings' fields of a Scene.
void ToProto(const SceneSettings& settings, v1::Scene* out);
// A loaded scene: its settings, versions, site count and memory.
void ToProto(const SceneHandle& scene, v1::Scene* out);
// A stored scene that is not loaded, with the reason.
void ToProto(const UnloadedScene& scene, v1::Scene* out);
// A replica's lag behind its shared store (nothing on a server with a store of its own).
void ToProto(const SceneRegistry::StoreLag& lag, v1::Scene* out);

}  // namespace gvd
