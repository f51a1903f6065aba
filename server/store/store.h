// Where scenes are made durable: the interface the application core commits through and
// replicas follow. The server opens one engine (SQLite, server/store/sqlite_store.h, for one
// server; PostgreSQL, server/store/postgres_store.h, shared by replicas) and hands it to
// nothing but this interface.
//
// The store is a log as well as a state. Each site's row carries the version that last put
// or removed it (a removal leaves a tombstone), so the rows a scene's versions after V wrote
// are what a follower at V missed: ReadChanges gives them as one net change. A commit is a
// conditional append: it names the version it follows, and the engine refuses it (ABORTED)
// when the scene has moved on, so writers on several servers get distinct, ordered versions
// and none overwrites another's change unseen. Tombstones older than a window of versions
// are dropped (the scene's horizon moves up); a follower from before the horizon reads the
// scene's whole state instead. An engine shared by replicas also keeps each scene's digest
// (digest.h), which its heads and log report and a commit may name: a follower compares it
// with its own, to tell a store that went back in time and was written again from the
// history it holds.
//
// Sites are kept in the scene core's own byte form (render/scene/codec.h), as validated when
// they were accepted: a reload rebuilds snapshots without converting or checking requests
// again.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <variant>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/kernel/site2.h"
#include "render/kernel/site3.h"
#include "render/scene/change.h"
#include "render/scene/settings.h"

namespace gvd {

// Sites of a scene of either dimension, as a store reads them.
using AnySites = std::variant<std::vector<Site>, std::vector<Site3>>;
template <class S>
using SharedSites = std::vector<std::shared_ptr<const S>>;
using AnySharedSites = std::variant<SharedSites<Site>, SharedSites<Site3>>;
// The sites as a change puts them (a view of `sites`).
template <class S>
AnySitesPut AsPut(const SharedSites<S>& sites) {
  return SitesPut<S>(sites);
}

// A scene as stored: its settings, its version and its sites (of the scene's dimension).
struct StoredScene {
  SceneSettings settings;
  uint64_t version = 0;
  // Which creation of the scene's id this is: a scene deleted and made again under the same
  // id has another (chosen by the engine; 0 in an engine that does not tell).
  uint64_t incarnation = 0;
  AnySites sites;

  size_t site_count() const {
    return std::visit([](const auto& s) { return s.size(); }, sites);
  }
};

// A scene's head in the store: what a follower compares its own copy with.
struct SceneHead {
  std::string id;
  uint64_t incarnation = 0;
  uint64_t version = 0;
  // The digest of its sites (server/store/digest.h); unset in an engine that keeps none.
  std::optional<uint64_t> digest;
};

// What a follower at version `after` of a scene missed, read from one consistent state of
// the store: the scene's settings, incarnation and version now, and the net change from
// `after` to it (each site put after `after` as it is now, each id removed after `after`).
// When `after` is 0, or the scene's tombstones from after `after` were dropped, `complete`
// is set: `put` holds every site and `removed` nothing, and the follower drops whatever
// else it holds.
struct SceneChanges {
  SceneSettings settings;
  uint64_t incarnation = 0;
  uint64_t version = 0;
  std::optional<uint64_t> digest;  // of the sites at `version`, as SceneHead's
  bool complete = false;
  AnySharedSites put;  // of the scene's dimension
  std::vector<std::string> removed;

  // The change as the scene core applies it, following `after` (a view of this object).
  ChangeSet View(uint64_t after) const {
    return {settings.id, version, std::visit([](const auto& sites) { return AsPut(sites); }, put),
            removed, after};
  }
};

// Every call is atomic and durable when it returns OK (a relaxed commit: written, and durable
// within the engine's bound): after a crash, a reload sees all of it or (when it failed) none
// of it. Thread-safe: calls may come from any thread; writes to one
// scene come one at a time and in version order (its writer lock), writes to different scenes
// may overlap.
class SceneStore {
 public:
  virtual ~SceneStore() = default;

  // Every stored scene with its sites and version, in scene id order. DATA_LOSS when a
  // stored scene or site cannot be read.
  virtual absl::StatusOr<std::vector<StoredScene>> Load() = 0;
  // Stores a new scene with no sites and returns its incarnation. ALREADY_EXISTS when a
  // stored scene has its id (the engine decides: of two servers creating one id at once, one
  // is refused).
  virtual absl::StatusOr<uint64_t> CreateScene(const SceneSettings& settings,
                                               uint64_t version) = 0;
  // Applies a change set to a stored scene and sets its version, if the scene is at the
  // version the change follows (changes.base()) and of its incarnation (when the change
  // names one): ABORTED, changing nothing, when it is not (another server wrote first, or
  // deleted the scene and made it again); NOT_FOUND when the scene is not stored.
  virtual absl::Status Commit(const ChangeSet& changes) = 0;
  // Removes a scene and its sites.
  virtual absl::Status DeleteScene(std::string_view scene_id) = 0;

  // Whether other servers write to the same store (then the server follows it).
  virtual bool shared() const { return false; }
  // Every stored scene's head, in id order.
  virtual absl::StatusOr<std::vector<SceneHead>> Heads() {
    return absl::UnimplementedError("this store keeps no log");
  }
  // What a follower at version `after` of the scene missed; NOT_FOUND when it is not stored.
  virtual absl::StatusOr<SceneChanges> ReadChanges(std::string_view /*scene_id*/,
                                                   uint64_t /*after*/) {
    return absl::UnimplementedError("this store keeps no log");
  }
  // Waits until another server may have committed something, or `timeout_ms` passed: true
  // when told of a commit. A store nobody else writes only sleeps.
  virtual bool WaitForChanges(int timeout_ms) {
    std::this_thread::sleep_for(std::chrono::milliseconds(timeout_ms));
    return false;
  }

  // Where the data lives, for logs (a path or a connection name).
  virtual std::string Describe() const = 0;
};

}  // namespace gvd
