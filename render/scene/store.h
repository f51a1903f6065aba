// Where scenes are made durable: the interface the scene core commits through. The server
// opens one engine (SQLite today, store/sqlite_store.h; a shared engine such as PostgreSQL
// for replicas can sit behind the same calls) and hands it to nothing but this interface.
//
// Sites are kept in the core's own form (core/codec.h), as validated when they were
// accepted: a reload rebuilds snapshots without converting or checking requests again.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/scene/settings.h"
#include "render/kernel/site2.h"
#include "render/kernel/site3.h"

namespace gvd {

// A scene as stored: its settings, its version and its sites (a 3D scene's in sites3).
struct StoredScene {
  SceneSettings settings;
  uint64_t version = 0;
  std::vector<Site> sites;
  std::vector<Site3> sites3;
};

// One accepted write of one scene: the sites it puts (inserted or replaced) and the ids it
// removes, and the version it brings the scene to. A view: valid during the call it is
// passed to.
struct ChangeSet {
  std::string_view scene_id;
  uint64_t version = 0;
  std::span<const std::shared_ptr<const Site>> put;
  std::span<const std::string> removed;
  // A 3D scene's sites put (a 2D scene's change has none; a 3D scene's, no `put`).
  std::span<const std::shared_ptr<const Site3>> put3 = {};

  // The sites put, of the kind a scene of K's sites holds.
  template <class S>
  std::span<const std::shared_ptr<const S>> Put() const {
    if constexpr (std::is_same_v<S, Site3>) {
      return put3;
    } else {
      return put;
    }
  }
};

// Every call is atomic and durable when it returns OK: after a crash, a reload sees all of it
// or (when it failed) none of it. Thread-safe: calls may come from any thread; writes to one
// scene come one at a time and in version order (its writer lock), writes to different scenes
// may overlap.
class SceneStore {
 public:
  virtual ~SceneStore() = default;

  // Every stored scene with its sites and version, in scene id order. DATA_LOSS when a
  // stored scene or site cannot be read.
  virtual absl::StatusOr<std::vector<StoredScene>> Load() = 0;
  // Stores a new scene with no sites. CONTRACT: no stored scene has its id.
  virtual absl::Status CreateScene(const SceneSettings& settings, uint64_t version) = 0;
  // Applies a change set to a stored scene and sets its version.
  virtual absl::Status Commit(const ChangeSet& changes) = 0;
  // Removes a scene and its sites.
  virtual absl::Status DeleteScene(std::string_view scene_id) = 0;

  // Where the data lives, for logs (a path or a connection name).
  virtual std::string Describe() const = 0;
};

}  // namespace gvd
