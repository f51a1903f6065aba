// The application core's scenes: every scene the server holds, of either dimension, and
// every way they change, with no transport. A replica's follower calls Apply with the changes
// other servers commit.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "render/scene/cpu_pool.h"
#include "render/scene/renderer.h"
#include "render/scene/scene.h"
#include "server/app/limits.h"
#include "server/app/memory.h"
#include "server/app/scene_handle.h"
#include "server/metrics.h"
#include "server/store/store.h"

namespace gvd {

// A stored scene that did not fit --max-memory when the store was loaded: kept in the store,
// listed, removable, and refused for anything else (FAILED_PRECONDITION with the reason).
struct UnloadedScene {
  SceneSettings settings;
  uint64_t version = 0;
  size_t sites = 0;
  uint64_t bytes = 0;
  std::string reason;
};

// A scene as listed: loaded (`scene` set) or stored but not loaded (`unloaded` set).
struct SceneEntry {
  std::optional<SceneHandle> scene;
  std::optional<UnloadedScene> unloaded;
  const std::string& id() const { return scene ? scene->id() : unloaded->settings.id; }
};

// What renders the registry's scenes: the seam's two sides (render/scene/renderer.h). Either
// may be null: then no frame of that dimension ever comes (a test's registry, say).
struct Renderers {
  Renderer* plane = nullptr;   // 2D scenes
  Renderer3* space = nullptr;  // 3D scenes
};

// Thread-safe. Threading rules:
//  - every call may come from any thread; none waits for a render;
//  - the calls that change state (CreateScene, DeleteScene, UpsertSites, DeleteSites) wait
//    for the store's durable commit, under no lock of this class (a scene's own writer lock
//    serializes its writes): run them on commits(), or one small write at a time on the
//    calling thread while commits() is idle (Service::Write);
//  - mu_ guards only the scene map and the ids being created, never across a store call.
//
// The write path, the same for every change: the memory it adds is reserved (or the change
// refused, RESOURCE_EXHAUSTED naming --max-memory), it is committed to the store (refused
// as a whole if the store fails), then published: the scene's next snapshot is installed
// (Scene::Install, the step Apply shares) and the render threads are told.
class SceneRegistry {
 public:
  // `store` and the renderers must outlive the registry; `metrics` may be null. Until Load()
  // has run the registry is empty and loaded() is false.
  SceneRegistry(SceneStore* store, Renderers renderers, ServerLimits limits,
                Metrics* metrics = nullptr);
  // Stops the renderers first (their threads publish frames whose waiters resume on this
  // registry's lanes), then finishes what the lanes hold.
  ~SceneRegistry();
  SceneRegistry(const SceneRegistry&) = delete;
  SceneRegistry& operator=(const SceneRegistry&) = delete;

  // Rebuilds every stored scene in id order while it fits --max-memory (the others stay
  // unloaded) and queues its render; then loaded() is true. Call once.
  absl::Status Load();
  bool loaded() const;

  // A new scene at version 1 with no sites, of the dimension its settings say. ALREADY_EXISTS
  // for an id stored or being created; RESOURCE_EXHAUSTED past --max-scenes or --max-memory.
  absl::StatusOr<SceneHandle> CreateScene(SceneSettings settings);
  // The loaded scene; NOT_FOUND naming it, FAILED_PRECONDITION for an unloaded one.
  absl::StatusOr<SceneHandle> Find(const std::string& id) const;
  // The scene, loaded or not; NOT_FOUND naming it.
  absl::StatusOr<SceneEntry> Describe(const std::string& id) const;
  // Every scene, loaded or not, in id order.
  std::vector<SceneEntry> List() const;
  // Deletes the scene, loaded or not, from the store and then from memory; its frame
  // waiters fail with NOT_FOUND and its watchers are told. NOT_FOUND when there is none.
  absl::Status DeleteScene(const std::string& id);

  // Inserts or replaces sites (a 2D scene's Site or a 3D scene's Site3), atomically; returns
  // the scene's new version once the change is durable (Durability says when that is).
  // FAILED_PRECONDITION when the scene is of the other dimension.
  // CONTRACT: sites are valid and their ids distinct.
  absl::StatusOr<uint64_t> UpsertSites(const std::string& scene_id, std::vector<Site> sites,
                                       Durability durability = Durability::kSync);
  absl::StatusOr<uint64_t> UpsertSites(const std::string& scene_id, std::vector<Site3> sites,
                                       Durability durability = Durability::kSync);
  // Removes sites, atomically; NOT_FOUND naming the first unknown id.
  // CONTRACT: ids are distinct.
  absl::StatusOr<uint64_t> DeleteSites(const std::string& scene_id,
                                       const std::vector<std::string>& ids,
                                       Durability durability = Durability::kSync);
  // Publishes a change that is durable already, committed elsewhere (another server on the
  // same store): the write path's last step. Scene::Apply says when it is refused.
  absl::StatusOr<uint64_t> Apply(const ChangeSet& committed);

  // ---- Following a store other servers write to (SceneStore::shared) ----
  //
  // A replica holds every scene of the store. It catches up when the store tells of a commit
  // and at least every kFollowPollMs: scenes made elsewhere are loaded, scenes deleted
  // elsewhere (or deleted and made again) dropped, and a scene behind its head reads what it
  // missed (SceneStore::ReadChanges) and publishes it through Apply. A write refused because
  // another server wrote the scene first (ABORTED) catches the scene up and is tried again.

  // Brings every scene up to the store's heads; the store's error when it cannot be read.
  absl::Status CatchUp();
  // Starts the thread that follows the store (after Load). Stopped by the destructor.
  void StartFollowing();
  // Whether the last catch-up read the store and applied what it found: false from the
  // moment the store cannot be read until a catch-up succeeds again.
  bool caught_up() const;
  // How far the scene is behind the store: its head as last read (0 when the store is not
  // shared), and the seconds since the store was last read.
  struct StoreLag {
    uint64_t store_version = 0;
    double read_age_seconds = 0;
  };
  StoreLag Lag(const std::string& id) const;

  // The version a read of `scene` waits for: `requested` (OUT_OF_RANGE when the scene has
  // not reached it), or the current one while the scene's first render is under way, so
  // that a new scene's reader waits rather than hearing "no sites".
  // With a shared store, a version the scene has not reached waits when the store's head
  // (as last read) has it, or may have it: then the next catch-up fails the wait with
  // OUT_OF_RANGE if the store has not reached it either.
  template <class S>
  absl::StatusOr<uint64_t> ReadVersion(const S& scene, uint64_t requested) const;

  // Where the work that must not run on a transport's threads runs:
  //  - answers(): answers to queries, image encoding, and frames' waiters (the CPU pool);
  //  - analyses(): structure and planning calls, at most --analysis-threads at once and
  //    --max-queued-analyses waiting (the CPU pool, below answers);
  //  - commits(): the calls that wait on the store (a pool of threads of its own, as they
  //    mostly wait), at most --max-queued-writes waiting; a small write runs on its caller's
  //    thread instead, as one of this lane's jobs, while the lane is idle (Service::Write).
  CpuPool::Lane& answers() { return answers_; }
  CpuPool::Lane& analyses() { return analyses_; }
  CpuPool::Lane& commits() { return commits_; }
  // Whether the store is this server's own (SQLite on its disk), not one shared with replicas,
  // whose commit may wait on a network and a database's failover.
  bool local_store() const { return !store_->shared(); }
  // Runs `job` on answers() (frames' waiters resume there).
  Executor executor();

  // Renders zoom windows of a frame (Renderer::RenderWindows); UNAVAILABLE without a
  // renderer.
  absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> Zoom(
      std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids);
  // Renders sites of no scene whole over a grid of the plane (Renderer::RenderSites), in the
  // NEAREST diagram; UNAVAILABLE without a renderer.
  absl::StatusOr<std::shared_ptr<const Frame>> RenderSites(std::shared_ptr<const SiteSnapshot> sites,
                                                           const Grid& grid, double eps,
                                                           RenderMode mode);

  const ServerLimits& limits() const { return limits_; }
  // Per-scene figures for the metrics.
  std::vector<Metrics::SceneSample> Sample() const;
  // What the scenes hold and reserve now, of --max-memory.
  uint64_t memory_used() const { return memory_.used(); }
  // Reserves `bytes` of --max-memory for `what` (a call's working memory, such as a mosaic's
  // image) while the reservation lives; RESOURCE_EXHAUSTED naming --max-memory when they do
  // not fit.
  absl::StatusOr<std::unique_ptr<MemoryBudget::Reservation>> Reserve(uint64_t bytes,
                                                                     const std::string& what);

 private:
  // Runs one store call, timing it for the metrics.
  template <class StoreCall>
  absl::Status Durably(StoreCall store_call) const;
  // The write path's end for a scene whose snapshot changed: its renderer renders it.
  void Published(const SceneHandle& scene);
  // UpsertSites of either dimension's sites.
  template <class SiteT>
  absl::StatusOr<uint64_t> Upsert(const std::string& scene_id, std::vector<SiteT> sites,
                                  Durability durability);
  // Apply's steps on a scene of S's dimension.
  template <class S>
  absl::StatusOr<uint64_t> ApplyTo(const std::shared_ptr<S>& scene, const ChangeSet& committed);
  // Holds a stored scene if it fits --max-memory (true), else lists it unloaded; in place of
  // `replacing`, when given (and still held: else the stored scene is dropped).
  bool Adopt(StoredScene stored, const SceneHandle* replacing = nullptr);
  // The bytes the loaded scenes hold (the budget's own figure). Takes mu_.
  uint64_t ScenesMemory() const;
  // Runs a write (`write(scene, commit)`, commit being the Persist that names the scene's
  // incarnation and the durability asked for) on the scene `scene_id`, catching the scene up
  // and trying again when another server wrote it first.
  template <class Write>
  absl::StatusOr<uint64_t> Retrying(const std::string& scene_id, Durability durability,
                                    Write write);
  // Catch-up's steps, under follow_mu_: one scene to its head; a scene from the store.
  // `head` is the scene's head as just read, or null to read the store for it.
  absl::Status Follow(const std::string& id, const SceneHead* head);
  absl::Status Advance(const SceneHandle& scene, const SceneChanges& changes, uint64_t after);
  // Reads the scene again from the store in place of `held` (of `incarnation`, at version
  // `version`), which the store no longer has: it went back in time.
  absl::Status Reload(const SceneHandle& held, uint64_t incarnation, uint64_t version);
  // The digest of the sites of `scene`'s `snapshot` (server/store/digest.h), from digests_
  // when it has the snapshot's. With a shared store only.
  template <class S>
  uint64_t DigestOf(const std::shared_ptr<S>& scene, const typename S::Snapshot& snapshot);
  // Notes `digest` as the digest of `scene`'s sites at `version`.
  template <class S>
  void NoteDigest(const std::shared_ptr<S>& scene, uint64_t version, uint64_t digest);
  // Whether the scene's sites have `digest` (unset: not known, taken as yes), when it is still
  // at `version`.
  bool Agrees(const SceneHandle& scene, uint64_t version, std::optional<uint64_t> digest);
  // Drops a scene deleted in the store by another server: the one of `incarnation`, if it
  // is still the one held under the id.
  void Forget(const std::string& id, uint64_t incarnation);
  // A held scene object and the first waiter token it had not given when the heads were
  // read.
  struct WaitMark {
    SceneHandle scene;
    uint64_t mark = 0;
  };
  // Fails the waits of versions beyond the store's heads (registered before their marks).
  void FailWaitsBeyondHeads(const std::vector<WaitMark>& marks);

  SceneStore* const store_;
  const Renderers renderers_;
  const ServerLimits limits_;
  Metrics* const metrics_;

  // --max-memory over the scenes' own figures. Its lock is taken before mu_.
  MemoryBudget memory_;
  // Guards everything below; never held across a store call.
  mutable std::mutex mu_;
  bool loaded_ = false;
  std::map<std::string, SceneHandle> scenes_;
  // Ids of scenes being created (reserved, not yet committed): they count against
  // --max-scenes and refuse a second create, but are not found until committed.
  std::set<std::string> creating_;
  std::map<std::string, UnloadedScene> unloaded_;
  // Each held scene's incarnation in the store (0 while unknown), and each stored scene's
  // head as last read, with when.
  std::map<std::string, uint64_t> incarnations_;
  std::map<std::string, std::pair<uint64_t, uint64_t>> heads_;  // incarnation, version
  std::chrono::steady_clock::time_point heads_read_;
  // The digests of held scenes' sites at a version, as last counted or moved by a change.
  struct Digest {
    std::weak_ptr<const void> scene;  // the scene object whose sites these are
    uint64_t version = 0;
    uint64_t digest = 0;
  };
  std::map<std::string, Digest> digests_;
  bool caught_up_ = true;

  // Serializes catch-ups (the follower's and writers').
  std::mutex follow_mu_;
  std::atomic<bool> stop_following_{false};
  std::thread follower_;

  // The threads that wait on the store. Declared before the lanes, which go first.
  CpuPool commit_threads_;
  // Declared last: answers_ goes first, finishing what is queued (which may still queue
  // analyses), then analyses_, then commits_.
  CpuPool::Lane commits_;
  CpuPool::Lane analyses_;
  CpuPool::Lane answers_;
};

template <class S>
absl::StatusOr<uint64_t> SceneRegistry::ReadVersion(const S& scene, uint64_t requested) const {
  const uint64_t version = scene.version();
  // A replica waits for what another server committed, or what the store may hold that it
  // has not read yet; the follower's next catch-up ends the wait one way or the other.
  if (requested > version && store_->shared()) return requested;
  if (requested > version) {
    return absl::OutOfRangeError(absl::StrCat("min_version ", requested, " is ahead of scene \"",
                                              scene.id(), "\", which is at version ", version));
  }
  // A scene whose first render is under way waits for it rather than answering "no sites".
  if (scene.frame()->empty() && scene.site_count() > 0) return version;
  return requested;
}

}  // namespace gvd
