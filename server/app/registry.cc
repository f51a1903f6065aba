#include "server/app/registry.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <set>

#include "absl/strings/str_cat.h"
#include "render/scene/slot_table.h"
#include "server/log.h"
#include "server/store/digest.h"

namespace gvd {
namespace {

// Threads that wait on the store: enough that writers of many scenes share each fsync
// (group commit) rather than queue for one.
constexpr size_t kCommitThreads = 16;
// A replica reads the store's heads at least this often, told of commits or not.
constexpr int kFollowPollMs = 250;
// Tries of a write that other servers' writes keep overtaking, the later ones after a random
// pause of up to 2^try milliseconds (at most 64), so that racing writers spread out.
constexpr int kWriteTries = 12;

// How a scene is sampled, for messages: "640x480 pixels" or "64x64x64 voxels".
std::string SizeOf(const SceneSettings& s) {
  if (s.three_d()) {
    return absl::StrCat(s.grid.width, "x", s.grid.height, "x", s.depth, " voxels");
  }
  return absl::StrCat(s.grid.width, "x", s.grid.height, " pixels");
}

// `digest`, of `snapshot`'s sites, moved by a change to them: the sites put and those they
// replace, the ids removed.
template <class Snapshot, class SiteT>
uint64_t Moved(uint64_t digest, const Snapshot& snapshot, SitesPut<SiteT> put,
               std::span<const std::string> removed) {
  for (const auto& site : put) {
    if (auto slot = snapshot.Find(site->id)) digest ^= SiteDigest(*snapshot.sites().ptr(*slot));
    digest ^= SiteDigest(*site);
  }
  for (const std::string& id : removed) {
    if (auto slot = snapshot.Find(id)) digest ^= SiteDigest(*snapshot.sites().ptr(*slot));
  }
  return digest;
}

// A scene's whole state read from the log (changes after version 0), as a stored scene.
StoredScene Whole(SceneChanges changes) {
  StoredScene stored{std::move(changes.settings), changes.version, changes.incarnation};
  std::visit(
      [&](const auto& put) {
        using SiteT =
            std::remove_const_t<typename std::decay_t<decltype(put)>::value_type::element_type>;
        std::vector<SiteT> sites;
        sites.reserve(put.size());
        for (const auto& site : put) sites.push_back(*site);
        stored.sites = std::move(sites);
      },
      changes.put);
  return stored;
}

}  // namespace

SceneRegistry::SceneRegistry(SceneStore* store, Renderers renderers, ServerLimits limits,
                             Metrics* metrics)
    : store_(store), renderers_(renderers), limits_(limits), metrics_(metrics),
      memory_(limits.max_memory, [this] { return ScenesMemory(); }),
      commit_threads_(kCommitThreads, "gvd-commit"),
      commits_(commit_threads_, /*priority=*/0, SIZE_MAX, limits.max_queued_writes),
      analyses_(CpuPool::Process(), /*priority=*/0, limits.analysis_threads,
                limits.max_queued_analyses),
      answers_(CpuPool::Process(), /*priority=*/1, SIZE_MAX, SIZE_MAX) {}

SceneRegistry::~SceneRegistry() {
  stop_following_ = true;
  if (follower_.joinable()) follower_.join();
  // The renderers stop first, while answers_ can still take the waiters their last renders
  // resume; writes that commits_ drains below still mark their scenes dirty, and a stopped
  // renderer fails those scenes' waiters on the calling thread.
  if (renderers_.plane) renderers_.plane->Stop();
  if (renderers_.space) renderers_.space->Stop();
}

Executor SceneRegistry::executor() {
  return [this](std::function<void()> job) { answers_.Submit(std::move(job)); };
}

template <class StoreCall>
absl::Status SceneRegistry::Durably(StoreCall store_call) const {
  auto start = std::chrono::steady_clock::now();
  absl::Status s = store_call();
  if (s.ok() && metrics_) {
    metrics_->ObserveCommit(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return s;
}

void SceneRegistry::Published(const SceneHandle& scene) {
  scene.Visit([&](const auto& s) {
    using S = typename std::decay_t<decltype(s)>::element_type;
    if constexpr (std::is_same_v<S, Scene>) {
      // A deleted scene is marked too: its render thread releases the scene's GPU state.
      if (renderers_.plane) renderers_.plane->MarkDirty(s);
    } else {
      if (renderers_.space && !s->deleted()) renderers_.space->MarkDirty(s);
    }
  });
}

template <class S>
uint64_t SceneRegistry::DigestOf(const std::shared_ptr<S>& scene,
                                 const typename S::Snapshot& snapshot) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto d = digests_.find(scene->id()); d != digests_.end() &&
                                             d->second.scene.lock() == scene &&
                                             d->second.version == snapshot.version()) {
      return d->second.digest;
    }
  }
  uint64_t digest = 0;
  snapshot.ids().ForEachAfter("", [&](const IdMap::Entry& e) {
    digest ^= SiteDigest(*snapshot.sites().ptr(e.slot));
    return true;
  });
  NoteDigest(scene, snapshot.version(), digest);
  return digest;
}

template <class S>
void SceneRegistry::NoteDigest(const std::shared_ptr<S>& scene, uint64_t version,
                               uint64_t digest) {
  std::lock_guard<std::mutex> lock(mu_);
  digests_[scene->id()] = {scene, version, digest};
}

uint64_t SceneRegistry::ScenesMemory() const {
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t sum = 0;
  for (const auto& [id, scene] : scenes_) sum += scene.memory_bytes();
  return sum;
}

bool SceneRegistry::loaded() const {
  std::lock_guard<std::mutex> lock(mu_);
  return loaded_;
}

absl::Status SceneRegistry::Load() {
  auto stored = store_->Load();
  if (!stored.ok()) return stored.status();
  size_t sites = 0, unloaded = 0;
  // Scenes load in id order while they fit --max-memory. The rest stay in the store,
  // reported unavailable: a store that outgrew the budget (or a smaller container) still
  // starts, and serves what fits, instead of dying at every start.
  std::sort(stored->begin(), stored->end(),
            [](const StoredScene& a, const StoredScene& b) { return a.settings.id < b.settings.id; });
  for (StoredScene& s : *stored) {
    const size_t count = s.site_count();
    if (Adopt(std::move(s))) {
      sites += count;
    } else {
      ++unloaded;
    }
  }
  Log(LogLevel::kInfo, "store_loaded",
      {{"path", store_->Describe()}, {"scenes", absl::StrCat(stored->size() - unloaded)},
       {"unavailable_scenes", absl::StrCat(unloaded)}, {"sites", absl::StrCat(sites)},
       {"memory", FormatBytes(memory_.used())}});
  std::lock_guard<std::mutex> lock(mu_);
  loaded_ = true;
  return absl::OkStatus();
}

namespace {

// The stored scene's sites, as S's (none when the store read none).
template <class S>
std::vector<typename S::Site> SitesOf(StoredScene& s) {
  auto* sites = std::get_if<std::vector<typename S::Site>>(&s.sites);
  return sites ? std::move(*sites) : std::vector<typename S::Site>();
}

// What a stored scene holds once loaded as S: its raster and its sites.
template <class S>
uint64_t LoadedBytes(const StoredScene& s) {
  uint64_t bytes = S::RasterBytes(s.settings);
  if (const auto* sites = std::get_if<std::vector<typename S::Site>>(&s.sites)) {
    for (const auto& site : *sites) bytes += SiteBytes(site);
  }
  return bytes;
}

// A scene restored from the store, as S.
template <class S>
SceneHandle Restored(StoredScene& s, Executor executor) {
  return std::make_shared<S>(std::move(s.settings), s.version, SitesOf<S>(s), std::move(executor));
}

}  // namespace

bool SceneRegistry::Adopt(StoredScene s, const SceneHandle* replacing) {
  const size_t count = s.site_count();
  const uint64_t bytes = ForDimension(s.settings, [&](auto type) {
    return LoadedBytes<typename decltype(type)::type>(s);
  });
  absl::Status fits = memory_.Reserve(
      bytes, absl::StrCat("scene \"", s.settings.id, "\" (", SizeOf(s.settings), ", ", count,
                          " sites)"));
  if (!fits.ok()) {
    Log(LogLevel::kWarn, "scene_unavailable",
        {{"scene", s.settings.id}, {"reason", std::string(fits.message())}});
    std::string id = s.settings.id;
    std::lock_guard<std::mutex> lock(mu_);
    if (replacing) {
      auto held = scenes_.find(id);
      if (held == scenes_.end() || !(held->second == *replacing)) return false;
      scenes_.erase(held);
      digests_.erase(id);
    }
    if (scenes_.count(id) || creating_.count(id)) return false;
    incarnations_[id] = s.incarnation;
    unloaded_[id] = {std::move(s.settings), s.version, count, bytes, std::string(fits.message())};
    return false;
  }
  MemoryBudget::Reservation reserved(&memory_, bytes);
  const uint64_t incarnation = s.incarnation;
  // Stored sites were validated when they were accepted: they go straight to a snapshot.
  const SceneHandle scene = ForDimension(s.settings, [&](auto type) {
    return Restored<typename decltype(type)::type>(s, executor());
  });
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (replacing) {
      auto held = scenes_.find(scene.id());
      if (held == scenes_.end() || !(held->second == *replacing)) return false;
      held->second = scene;
      digests_.erase(scene.id());
      heads_[scene.id()] = {incarnation, scene.version()};
    } else {
      // A scene made here meanwhile (a replica's create that won) is the one kept.
      if (scenes_.count(scene.id()) || creating_.count(scene.id())) return true;
      scenes_.emplace(scene.id(), scene);
    }
    incarnations_[scene.id()] = incarnation;
  }
  Published(scene);
  return true;
}

absl::StatusOr<SceneHandle> SceneRegistry::CreateScene(SceneSettings settings) {
  // The raster's bytes, reserved until the scene is in its map (then it counts them).
  const uint64_t raster = ForDimension(
      settings, [&](auto type) { return decltype(type)::type::RasterBytes(settings); });
  if (auto s = memory_.Reserve(raster, absl::StrCat("scene \"", settings.id, "\" of ",
                                                    SizeOf(settings)));
      !s.ok()) {
    return s;
  }
  MemoryBudget::Reservation reserved(&memory_, raster);
  const SceneHandle scene = ForDimension(settings, [&](auto type) -> SceneHandle {
    return std::make_shared<typename decltype(type)::type>(std::move(settings), executor());
  });
  {
    std::lock_guard<std::mutex> lock(mu_);
    const size_t held = scenes_.size() + creating_.size();
    if (scenes_.count(scene.id()) || creating_.count(scene.id()) || unloaded_.count(scene.id())) {
      return absl::AlreadyExistsError(absl::StrCat("scene \"", scene.id(), "\" already exists"));
    }
    if (held >= limits_.max_scenes) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "the server holds ", held, " scenes; the limit (--max-scenes) is ", limits_.max_scenes));
    }
    creating_.insert(scene.id());  // reserved: the commit runs without the lock
  }
  absl::StatusOr<uint64_t> incarnation;
  absl::Status stored = Durably([&] {
    incarnation = store_->CreateScene(scene.settings(), scene.version());
    return incarnation.status();
  });
  {
    std::lock_guard<std::mutex> lock(mu_);
    creating_.erase(scene.id());
    if (stored.ok()) {
      scenes_.emplace(scene.id(), scene);
      incarnations_[scene.id()] = *incarnation;
    }
  }
  if (!stored.ok()) return stored;
  const SceneSettings& made = scene.settings();
  Log(LogLevel::kInfo, "scene_created",
      {{"scene", scene.id()}, {"width_px", absl::StrCat(made.grid.width)},
       {"height_px", absl::StrCat(made.grid.height)}, {"depth_px", absl::StrCat(made.depth)},
       {"max_error", FormatNumber(made.eps)}});
  return scene;
}

absl::StatusOr<SceneHandle> SceneRegistry::Find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (auto it = scenes_.find(id); it != scenes_.end()) return it->second;
  if (auto u = unloaded_.find(id); u != unloaded_.end()) {
    return absl::FailedPreconditionError(
        absl::StrCat("scene \"", id, "\" is stored but not loaded: ", u->second.reason));
  }
  return absl::NotFoundError(absl::StrCat("scene \"", id, "\" does not exist"));
}

absl::StatusOr<SceneEntry> SceneRegistry::Describe(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (auto u = unloaded_.find(id); u != unloaded_.end()) return SceneEntry{std::nullopt, u->second};
  auto it = scenes_.find(id);
  if (it == scenes_.end()) {
    return absl::NotFoundError(absl::StrCat("scene \"", id, "\" does not exist"));
  }
  return SceneEntry{it->second, std::nullopt};
}

std::vector<SceneEntry> SceneRegistry::List() const {
  std::vector<SceneEntry> out;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) out.push_back({scene, std::nullopt});
    for (const auto& [id, scene] : unloaded_) out.push_back({std::nullopt, scene});
  }
  std::sort(out.begin(), out.end(),
            [](const SceneEntry& a, const SceneEntry& b) { return a.id() < b.id(); });
  return out;
}

absl::Status SceneRegistry::DeleteScene(const std::string& id) {
  // A scene left unloaded (it did not fit --max-memory) is deleted from the store alone.
  bool unloaded;
  {
    std::lock_guard<std::mutex> lock(mu_);
    unloaded = unloaded_.count(id) > 0;
  }
  if (unloaded) {
    if (auto s = Durably([&] { return store_->DeleteScene(id); }); !s.ok()) return s;
    {
      std::lock_guard<std::mutex> lock(mu_);
      unloaded_.erase(id);
      incarnations_.erase(id);
    }
    Log(LogLevel::kInfo, "scene_deleted", {{"scene", id}, {"loaded", "false"}});
    return absl::OkStatus();
  }
  auto found = Find(id);
  if (!found.ok()) return found.status();
  const SceneHandle scene = *found;
  // The commit holds only the scene's writer lock: writes to the scene wait and then find it
  // deleted, and other scenes' lookups go on.
  absl::Status deleted = scene.Visit([&](const auto& s) {
    return s->Retire([&] { return Durably([&] { return store_->DeleteScene(id); }); });
  });
  if (!deleted.ok()) return deleted;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = scenes_.find(id);
    if (it != scenes_.end() && it->second == scene) {
      scenes_.erase(it);
      incarnations_.erase(id);
    }
  }
  scene.FailWaiters(absl::NotFoundError(absl::StrCat("scene \"", id, "\" was deleted")));
  Published(scene);  // lets the render thread release the scene's target
  Log(LogLevel::kInfo, "scene_deleted", {{"scene", id}});
  return absl::OkStatus();
}

template <class Write>
absl::StatusOr<uint64_t> SceneRegistry::Retrying(const std::string& scene_id,
                                                 Durability durability, Write write) {
  for (int attempt = 1;; ++attempt) {
    auto scene = Find(scene_id);
    if (!scene.ok()) return scene.status();
    uint64_t incarnation = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (auto it = incarnations_.find(scene_id); it != incarnations_.end()) {
        incarnation = it->second;
      }
    }
    // The commit names the incarnation the scene had here (a scene made again elsewhere
    // under the same id refuses it) and, with a shared store, the digest of the sites it was
    // made on (a store that went back in time and was written again refuses it).
    auto commit = [&](const ChangeSet& c) {
      ChangeSet named = c;
      named.incarnation = incarnation;
      named.durability = durability;
      std::optional<uint64_t> after;
      if (store_->shared()) {
        scene->Visit([&](const auto& s) {
          using SiteT = typename std::decay_t<decltype(*s)>::Site;
          auto base = s->snapshot();  // the writer's lock is held: the change follows it
          named.base_digest = DigestOf(s, *base);
          after = Moved(*named.base_digest, *base, c.template Put<SiteT>(), c.removed);
        });
      }
      absl::Status stored = Durably([&] { return store_->Commit(named); });
      if (stored.ok() && after) {
        scene->Visit([&](const auto& s) { NoteDigest(s, c.version, *after); });
      }
      return stored;
    };
    auto version = write(*scene, commit);
    if (version.ok()) {
      Published(*scene);
      if (store_->shared()) {
        std::lock_guard<std::mutex> lock(mu_);
        auto& head = heads_[scene_id];
        if (head.first == incarnation) head.second = std::max(head.second, *version);
      }
    }
    if (version.ok() || version.status().code() != absl::StatusCode::kAborted ||
        !store_->shared() || attempt == kWriteTries) {
      return version;
    }
    // Another server wrote the scene first: read what it wrote, and try again on top of it.
    if (attempt > 1) {
      thread_local std::mt19937 rng(std::random_device{}());
      const uint32_t ms = 1u << std::min(attempt, 6);
      std::this_thread::sleep_for(std::chrono::microseconds(rng() % (ms * 1000)));
    }
    std::lock_guard<std::mutex> follow(follow_mu_);
    if (auto s = Follow(scene_id, nullptr); !s.ok()) return s;
  }
}

absl::StatusOr<uint64_t> SceneRegistry::UpsertSites(const std::string& scene_id,
                                                    std::vector<Site> sites,
                                                    Durability durability) {
  return Upsert(scene_id, std::move(sites), durability);
}

absl::StatusOr<uint64_t> SceneRegistry::UpsertSites(const std::string& scene_id,
                                                    std::vector<Site3> sites,
                                                    Durability durability) {
  return Upsert(scene_id, std::move(sites), durability);
}

template <class SiteT>
absl::StatusOr<uint64_t> SceneRegistry::Upsert(const std::string& scene_id,
                                               std::vector<SiteT> sites, Durability durability) {
  using S = SceneOfSites<SiteT>;
  // What the sites add, reserved until the scene's snapshot holds them (sites they replace
  // are not subtracted: a reservation may only overstate).
  uint64_t added = 0;
  for (const auto& site : sites) added += SiteBytes(site);
  if (auto s = memory_.Reserve(added, absl::StrCat(sites.size(), " sites for scene \"",
                                                   scene_id, "\""));
      !s.ok()) {
    return s;
  }
  MemoryBudget::Reservation reserved(&memory_, added);
  const bool retried = store_->shared();  // then each try takes a copy
  return Retrying(scene_id, durability,
                  [&](const SceneHandle& handle, const auto& commit) -> absl::StatusOr<uint64_t> {
                    auto scene = handle.As<S>();
                    if (!scene.ok()) return scene.status();
                    return (*scene)->Upsert(retried ? sites : std::move(sites),
                                            limits_.max_sites_per_scene, commit);
                  });
}

absl::StatusOr<uint64_t> SceneRegistry::DeleteSites(const std::string& scene_id,
                                                    const std::vector<std::string>& ids,
                                                    Durability durability) {
  return Retrying(scene_id, durability, [&](const SceneHandle& scene, const auto& commit) {
    return scene.Visit([&](const auto& s) { return s->Delete(ids, commit); });
  });
}

absl::StatusOr<uint64_t> SceneRegistry::Apply(const ChangeSet& committed) {
  auto scene = Find(std::string(committed.scene_id));
  if (!scene.ok()) return scene.status();
  return scene->Visit([&](const auto& s) { return ApplyTo(s, committed); });
}

template <class S>
absl::StatusOr<uint64_t> SceneRegistry::ApplyTo(const std::shared_ptr<S>& scene,
                                                const ChangeSet& committed) {
  using SiteT = typename S::Site;
  if (committed.template PutsOther<SiteT>()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "a change to scene \"", scene->id(), "\" puts sites of the other dimension than its own"));
  }
  uint64_t added = 0;
  for (const auto& site : committed.template Put<SiteT>()) added += SiteBytes(*site);
  // Committed elsewhere, so it is not refused for memory: the reservation only keeps the
  // budget's figure honest until the snapshot holds the sites.
  MemoryBudget::Reservation reserved(
      memory_.Reserve(added, "a committed change").ok() ? &memory_ : nullptr, added);
  auto version = scene->Apply(committed);
  if (version.ok()) Published(scene);
  return version;
}

absl::Status SceneRegistry::CatchUp() {
  std::lock_guard<std::mutex> follow(follow_mu_);
  // The scenes held before the heads are read: only these can have been deleted elsewhere
  // (one made here later is not in the heads read), and only their waits registered now can
  // be judged by these heads.
  std::vector<std::pair<std::string, uint64_t>> held;  // id, incarnation
  std::vector<WaitMark> marks;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) marks.push_back({scene, scene.waiter_mark()});
    for (const WaitMark& m : marks) held.emplace_back(m.scene.id(), incarnations_[m.scene.id()]);
    for (const auto& [id, scene] : unloaded_) held.emplace_back(id, incarnations_[id]);
  }
  auto heads = store_->Heads();
  if (!heads.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    caught_up_ = false;
    return heads.status();
  }
  std::map<std::string, std::pair<uint64_t, uint64_t>> latest;  // incarnation, version
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const SceneHead& h : *heads) {
      auto& head = latest[h.id];
      head = {h.incarnation, h.version};
      // A commit of this server's after the heads were read keeps its higher version.
      if (auto old = heads_.find(h.id); old != heads_.end() && old->second.first == h.incarnation) {
        head.second = std::max(head.second, old->second.second);
      }
    }
    heads_ = latest;
    heads_read_ = std::chrono::steady_clock::now();
  }
  absl::Status status;
  for (const SceneHead& h : *heads) {
    if (auto s = Follow(h.id, &h); !s.ok() && status.ok()) status = s;
  }
  for (const auto& [id, incarnation] : held) {
    if (!latest.count(id)) Forget(id, incarnation);
  }
  FailWaitsBeyondHeads(marks);
  std::lock_guard<std::mutex> lock(mu_);
  caught_up_ = status.ok();
  return status;
}

absl::Status SceneRegistry::Follow(const std::string& id, const SceneHead* head) {
  std::optional<SceneHandle> scene;
  uint64_t incarnation = 0;
  {
    std::lock_guard<std::mutex> lock(mu_);
    // A scene being made here is this server's own; one left unloaded stays so.
    if (creating_.count(id) || unloaded_.count(id)) return absl::OkStatus();
    if (auto it = scenes_.find(id); it != scenes_.end()) scene = it->second;
    if (auto it = incarnations_.find(id); it != incarnations_.end()) incarnation = it->second;
  }
  const uint64_t local = scene ? scene->version() : 0;
  // Nothing new. A head behind the version held is read again below, in one read with its
  // log: a commit of this server's since the heads were read is not a store gone back.
  if (scene && head && head->incarnation == incarnation && head->version == local &&
      Agrees(*scene, local, head->digest)) {
    return absl::OkStatus();
  }
  auto changes = store_->ReadChanges(id, local);
  if (changes.status().code() == absl::StatusCode::kNotFound) {
    if (scene) Forget(id, incarnation);
    return absl::OkStatus();
  }
  if (!changes.ok()) return changes.status();
  if (scene && changes->incarnation != incarnation) {
    // Deleted and made again elsewhere: the scene held here is another one.
    Forget(id, incarnation);
    changes = store_->ReadChanges(id, 0);
    if (changes.status().code() == absl::StatusCode::kNotFound) return absl::OkStatus();
    if (!changes.ok()) return changes.status();
  } else if (scene) {
    // The store went back in time: it lost versions held here, or holds other sites at the
    // version held here (it went back and was written again).
    if (changes->version < local ||
        (changes->version == local && !Agrees(*scene, local, changes->digest))) {
      return Reload(*scene, incarnation, local);
    }
    return Advance(*scene, *changes, local);
  }
  Adopt(Whole(std::move(*changes)));
  return absl::OkStatus();
}

absl::Status SceneRegistry::Advance(const SceneHandle& scene, const SceneChanges& changes,
                                    uint64_t after) {
  return scene.Visit([&](const auto& s) -> absl::Status {
    using SiteT = typename std::decay_t<decltype(*s)>::Site;
    auto snapshot = s->snapshot();
    // Nothing new, or the scene moved meanwhile (a write here): the next catch-up reads again.
    if (changes.version <= after || snapshot->version() != after) return absl::OkStatus();
    std::vector<std::string> removed;
    if (changes.complete) {
      // The scene's whole state: whatever else is held goes.
      std::set<std::string_view> kept;
      for (const auto& site : changes.View(after).template Put<SiteT>()) kept.insert(site->id);
      snapshot->ids().ForEachAfter("", [&](const auto& entry) {
        if (!kept.count(entry.id)) removed.push_back(entry.id);
        return true;
      });
    } else {
      // A site put and removed after `after` was never held here.
      for (const std::string& id : changes.removed) {
        if (snapshot->Find(id)) removed.push_back(id);
      }
    }
    ChangeSet net = changes.View(after);
    net.removed = removed;
    // The change must bring the sites held at `after` to those the store has at its version:
    // else the store's history is not the one held here (it went back in time and was
    // written again past `after`). A whole state replaces what is held anyway.
    std::optional<uint64_t> digest;
    if (!changes.complete && changes.digest) {
      digest = Moved(DigestOf(s, *snapshot), *snapshot, net.template Put<SiteT>(),
                     net.removed);
      if (*digest != *changes.digest) return Reload(scene, changes.incarnation, after);
    }
    auto applied = ApplyTo(s, net);
    if (!applied.ok() && applied.status().code() != absl::StatusCode::kFailedPrecondition &&
        applied.status().code() != absl::StatusCode::kNotFound &&
        applied.status().code() != absl::StatusCode::kAborted) {
      return applied.status();
    }
    if (applied.ok()) {
      // The store held this version when it was read: the store version reported is never
      // below the one held (a write's retry reads the log without reading the heads).
      std::lock_guard<std::mutex> lock(mu_);
      if (auto head = heads_.find(s->id());
          head != heads_.end() && head->second.first == changes.incarnation) {
        head->second.second = std::max(head->second.second, changes.version);
      }
    }
    if (applied.ok() && digest) NoteDigest(s, changes.version, *digest);
    return absl::OkStatus();
  });
}

absl::Status SceneRegistry::Reload(const SceneHandle& held, uint64_t incarnation,
                                   uint64_t version) {
  const std::string& id = held.id();
  auto whole = store_->ReadChanges(id, 0);
  if (whole.status().code() == absl::StatusCode::kNotFound) {
    Forget(id, incarnation);
    return absl::OkStatus();
  }
  if (!whole.ok()) return whole.status();
  const uint64_t stored = whole->version;
  StoredScene scene = Whole(std::move(*whole));
  const size_t sites = scene.site_count();
  Adopt(std::move(scene), &held);
  // Readers waiting on the scene held here wait for versions of a history the store lost.
  if (held.Visit([](const auto& s) { return s->Retire(nullptr, /*reloaded=*/true).ok(); })) {
    held.FailWaiters(absl::AbortedError(absl::StrCat(
        "scene \"", id, "\" was read again from the store, which went back in time (from version ",
        version, " held here to ", stored, "): the version awaited may now name another "
        "change; read again")));
    Published(held);  // lets the render thread release the scene's target
  }
  const uint64_t lost = version > stored ? version - stored : 0;
  Log(LogLevel::kWarn, "scene_reloaded",
      {{"scene", id}, {"store", store_->Describe()}, {"held_version", absl::StrCat(version)},
       {"store_version", absl::StrCat(stored)}, {"versions_lost", absl::StrCat(lost)},
       {"sites", absl::StrCat(sites)}});
  if (metrics_) metrics_->ObserveReload(id, lost);
  return absl::OkStatus();
}

bool SceneRegistry::Agrees(const SceneHandle& scene, uint64_t version,
                           std::optional<uint64_t> digest) {
  if (!digest) return true;
  return scene.Visit([&](const auto& s) {
    auto snapshot = s->snapshot();
    // A scene that moved on meanwhile is judged by the next catch-up.
    return snapshot->version() != version || DigestOf(s, *snapshot) == *digest;
  });
}

void SceneRegistry::Forget(const std::string& id, uint64_t incarnation) {
  std::optional<SceneHandle> scene;
  {
    std::lock_guard<std::mutex> lock(mu_);
    // Only the scene that was judged gone: one made here meanwhile under the id stays.
    auto it = incarnations_.find(id);
    if (it == incarnations_.end() || it->second != incarnation) return;
    if (auto it = scenes_.find(id); it != scenes_.end()) {
      scene = it->second;
      scenes_.erase(it);
    }
    unloaded_.erase(id);
    incarnations_.erase(id);
    digests_.erase(id);
  }
  if (scene && scene->Visit([](const auto& s) { return s->Retire().ok(); })) {
    scene->FailWaiters(absl::NotFoundError(absl::StrCat("scene \"", id, "\" was deleted")));
    Published(*scene);
  }
  Log(LogLevel::kInfo, "scene_deleted", {{"scene", id}, {"by", "another server"}});
}

void SceneRegistry::FailWaitsBeyondHeads(const std::vector<WaitMark>& marks) {
  for (const WaitMark& m : marks) {
    const std::string& id = m.scene.id();
    uint64_t head = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto h = heads_.find(id);
      // The marks are of the scene objects held before the heads were read: a scene made
      // again since has waiters of its own, not judged by these heads.
      auto held = incarnations_.find(id);
      if (h == heads_.end() || held == incarnations_.end() || held->second != h->second.first) {
        continue;
      }
      auto s = scenes_.find(id);
      if (s == scenes_.end() || !(s->second == m.scene)) continue;
      head = h->second.second;
    }
    m.scene.FailWaitersBeyond(head, m.mark,
                              absl::OutOfRangeError(absl::StrCat(
                                  "min_version is ahead of scene \"", id,
                                  "\", which is at version ", head, " in the store")));
  }
}

void SceneRegistry::StartFollowing() {
  follower_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "gvd-follow");
    bool reachable = true;
    while (!stop_following_) {
      absl::Status s = CatchUp();
      if (!s.ok() && reachable) {
        Log(LogLevel::kWarn, "store_unreachable",
            {{"store", store_->Describe()}, {"error", s.ToString()}});
      } else if (s.ok() && !reachable) {
        Log(LogLevel::kInfo, "store_caught_up", {{"store", store_->Describe()}});
      }
      reachable = s.ok();
      if (!stop_following_) store_->WaitForChanges(kFollowPollMs);
    }
  });
}

bool SceneRegistry::caught_up() const {
  std::lock_guard<std::mutex> lock(mu_);
  return caught_up_;
}

SceneRegistry::StoreLag SceneRegistry::Lag(const std::string& id) const {
  if (!store_->shared()) return {};
  std::lock_guard<std::mutex> lock(mu_);
  StoreLag lag;
  if (auto it = heads_.find(id); it != heads_.end()) lag.store_version = it->second.second;
  lag.read_age_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - heads_read_).count();
  return lag;
}

absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> SceneRegistry::Zoom(
    std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids) {
  if (renderers_.plane == nullptr) return absl::UnavailableError("the server renders nothing");
  return renderers_.plane->RenderWindows(std::move(base), mode, std::move(grids));
}

absl::StatusOr<std::shared_ptr<const Frame>> SceneRegistry::RenderSites(
    std::shared_ptr<const SiteSnapshot> sites, const Grid& grid, double eps, RenderMode mode) {
  if (renderers_.plane == nullptr) return absl::UnavailableError("the server renders nothing");
  return renderers_.plane->RenderSites(std::move(sites), grid, eps, mode, Diagram::kNearest);
}

absl::StatusOr<std::unique_ptr<MemoryBudget::Reservation>> SceneRegistry::Reserve(
    uint64_t bytes, const std::string& what) {
  if (auto s = memory_.Reserve(bytes, what); !s.ok()) return s;
  return std::make_unique<MemoryBudget::Reservation>(&memory_, bytes);
}

std::vector<Metrics::SceneSample> SceneRegistry::Sample() const {
  std::vector<SceneHandle> scenes;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) scenes.push_back(scene);
  }
  std::vector<Metrics::SceneSample> out;
  for (const SceneHandle& s : scenes) {
    const double lag = static_cast<double>(s.version() - s.frame_version());
    out.push_back({s.id(), static_cast<double>(s.site_count()), lag, s.frame_age_seconds(),
                   static_cast<double>(s.memory_bytes()), s.render_seconds()});
  }
  return out;  // in id order, as the map holds them
}

}  // namespace gvd
