#include "server/app/registry.h"

#include <algorithm>
#include <chrono>

#include "absl/strings/str_cat.h"
#include "render/scene/slot_table.h"
#include "server/log.h"

namespace gvd {
namespace {

// Threads that wait on the store: enough that writers of many scenes share each fsync
// (group commit) rather than queue for one.
constexpr size_t kCommitThreads = 16;

// How a scene is sampled, for messages: "640x480 pixels" or "64x64x64 voxels".
std::string SizeOf(const SceneSettings& s) {
  if (s.three_d()) {
    return absl::StrCat(s.grid.width, "x", s.grid.height, "x", s.depth, " voxels");
  }
  return absl::StrCat(s.grid.width, "x", s.grid.height, " pixels");
}

}  // namespace

SceneRegistry::SceneRegistry(SceneStore* store, RenderLoop* renderer, ServerLimits limits,
                             Metrics* metrics)
    : store_(store), renderer_(renderer), limits_(limits), metrics_(metrics),
      memory_(limits.max_memory, [this] { return ScenesMemory(); }),
      commit_threads_(kCommitThreads, "gvd-commit"),
      commits_(commit_threads_, /*priority=*/0, SIZE_MAX, limits.max_queued_writes),
      analyses_(CpuPool::Process(), /*priority=*/0, limits.analysis_threads,
                limits.max_queued_analyses),
      answers_(CpuPool::Process(), /*priority=*/1, SIZE_MAX, SIZE_MAX) {}

SceneRegistry::~SceneRegistry() { volumes_.Stop(); }

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

void SceneRegistry::Published(const std::shared_ptr<Scene>& scene) {
  if (renderer_) renderer_->MarkDirty(scene);
}

void SceneRegistry::Published(const std::shared_ptr<Scene3>& scene) {
  // 3D scenes render on the CPU, whether or not the server has a GL renderer.
  if (!scene->deleted()) volumes_.MarkDirty(scene);
}

template <>
std::map<std::string, std::shared_ptr<Scene>>& SceneRegistry::Scenes<Scene>() {
  return scenes_;
}
template <>
std::map<std::string, std::shared_ptr<Scene3>>& SceneRegistry::Scenes<Scene3>() {
  return scenes3_;
}
template <>
const std::map<std::string, std::shared_ptr<Scene>>& SceneRegistry::Scenes<Scene>() const {
  return scenes_;
}
template <>
const std::map<std::string, std::shared_ptr<Scene3>>& SceneRegistry::Scenes<Scene3>() const {
  return scenes3_;
}

uint64_t SceneRegistry::ScenesMemory() const {
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t sum = 0;
  for (const auto& [id, scene] : scenes_) sum += scene->memory_bytes();
  for (const auto& [id, scene] : scenes3_) sum += scene->memory_bytes();
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
    const bool three_d = s.settings.three_d();
    const size_t count = three_d ? s.sites3.size() : s.sites.size();
    uint64_t bytes = three_d ? Scene3::RasterBytes(s.settings) : Scene::RasterBytes(s.settings);
    for (const Site& site : s.sites) bytes += SiteBytes(site);
    for (const Site3& site : s.sites3) bytes += SiteBytes(site);
    absl::Status fits = memory_.Reserve(
        bytes, absl::StrCat("scene \"", s.settings.id, "\" (", SizeOf(s.settings), ", ", count,
                            " sites)"));
    if (!fits.ok()) {
      Log(LogLevel::kWarn, "scene_unavailable",
          {{"scene", s.settings.id}, {"reason", std::string(fits.message())}});
      std::string id = s.settings.id;
      std::lock_guard<std::mutex> lock(mu_);
      unloaded_[id] = {std::move(s.settings), s.version, count, bytes,
                       std::string(fits.message())};
      ++unloaded;
      continue;
    }
    MemoryBudget::Reservation reserved(&memory_, bytes);
    sites += count;
    // Stored sites were validated when they were accepted: they go straight to a snapshot.
    auto load = [&](auto scene) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        Scenes<typename decltype(scene)::element_type>()[scene->id()] = scene;
      }
      Published(scene);
    };
    if (three_d) {
      load(std::make_shared<Scene3>(std::move(s.settings), s.version, std::move(s.sites3),
                                    executor()));
    } else {
      load(std::make_shared<Scene>(std::move(s.settings), s.version, std::move(s.sites),
                                   executor()));
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

absl::StatusOr<std::shared_ptr<Scene>> SceneRegistry::CreateScene(SceneSettings settings) {
  return Create<Scene>(std::move(settings));
}

absl::StatusOr<std::shared_ptr<Scene3>> SceneRegistry::CreateScene3(SceneSettings settings) {
  return Create<Scene3>(std::move(settings));
}

template <class S>
absl::StatusOr<std::shared_ptr<S>> SceneRegistry::Create(SceneSettings settings) {
  // The raster's bytes, reserved until the scene is in its map (then it counts them).
  const uint64_t raster = S::RasterBytes(settings);
  if (auto s = memory_.Reserve(raster, absl::StrCat("scene \"", settings.id, "\" of ",
                                                    SizeOf(settings)));
      !s.ok()) {
    return s;
  }
  MemoryBudget::Reservation reserved(&memory_, raster);
  auto scene = std::make_shared<S>(std::move(settings), executor());
  {
    std::lock_guard<std::mutex> lock(mu_);
    const size_t held = scenes_.size() + scenes3_.size() + creating_.size();
    if (scenes_.count(scene->id()) || scenes3_.count(scene->id()) ||
        creating_.count(scene->id()) || unloaded_.count(scene->id())) {
      return absl::AlreadyExistsError(absl::StrCat("scene \"", scene->id(), "\" already exists"));
    }
    if (held >= limits_.max_scenes) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "the server holds ", held, " scenes; the limit (--max-scenes) is ", limits_.max_scenes));
    }
    creating_.insert(scene->id());  // reserved: the commit runs without the lock
  }
  absl::Status stored =
      Durably([&] { return store_->CreateScene(scene->settings(), scene->version()); });
  {
    std::lock_guard<std::mutex> lock(mu_);
    creating_.erase(scene->id());
    if (stored.ok()) Scenes<S>().emplace(scene->id(), scene);
  }
  if (!stored.ok()) return stored;
  const SceneSettings& made = scene->settings();
  Log(LogLevel::kInfo, "scene_created",
      {{"scene", scene->id()}, {"width_px", absl::StrCat(made.grid.width)},
       {"height_px", absl::StrCat(made.grid.height)}, {"depth_px", absl::StrCat(made.depth)},
       {"max_error", FormatNumber(made.eps)}});
  return scene;
}

absl::StatusOr<std::shared_ptr<Scene>> SceneRegistry::Find(const std::string& id) const {
  return FindOf<Scene>(id);
}

absl::StatusOr<std::shared_ptr<Scene3>> SceneRegistry::Find3(const std::string& id) const {
  return FindOf<Scene3>(id);
}

template <class S>
absl::StatusOr<std::shared_ptr<S>> SceneRegistry::FindOf(const std::string& id) const {
  constexpr bool kThreeD = std::is_same_v<S, Scene3>;
  std::lock_guard<std::mutex> lock(mu_);
  const auto& mine = Scenes<S>();
  auto it = mine.find(id);
  if (it != mine.end()) return it->second;
  if (kThreeD ? scenes_.count(id) > 0 : scenes3_.count(id) > 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "scene \"", id, "\" is a ", kThreeD ? "2D" : "3D",
        " scene; this call needs a ", kThreeD ? "3D" : "2D", " one"));
  }
  if (auto u = unloaded_.find(id); u != unloaded_.end()) {
    return absl::FailedPreconditionError(
        absl::StrCat("scene \"", id, "\" is stored but not loaded: ", u->second.reason));
  }
  return absl::NotFoundError(absl::StrCat("scene \"", id, "\" does not exist"));
}

absl::StatusOr<SceneEntry> SceneRegistry::Describe(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (auto u = unloaded_.find(id); u != unloaded_.end()) return SceneEntry{nullptr, u->second};
  if (auto it = scenes3_.find(id); it != scenes3_.end()) {
    return SceneEntry{nullptr, std::nullopt, it->second};
  }
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
    for (const auto& [id, scene] : scenes3_) out.push_back({nullptr, std::nullopt, scene});
    for (const auto& [id, scene] : unloaded_) out.push_back({nullptr, scene});
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
    }
    Log(LogLevel::kInfo, "scene_deleted", {{"scene", id}, {"loaded", "false"}});
    return absl::OkStatus();
  }
  auto retire = [&](const auto& scene) -> absl::Status {
    using S = typename std::decay_t<decltype(scene)>::element_type;
    // The commit holds only the scene's writer lock: writes to the scene wait and then find
    // it deleted, and other scenes' lookups go on.
    absl::Status deleted =
        scene->Retire([&] { return Durably([&] { return store_->DeleteScene(id); }); });
    if (!deleted.ok()) return deleted;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto& scenes = Scenes<S>();
      auto it = scenes.find(id);
      if (it != scenes.end() && it->second == scene) scenes.erase(it);
    }
    scene->FailWaiters(absl::NotFoundError(absl::StrCat("scene \"", id, "\" was deleted")));
    Published(scene);  // lets the render thread release the scene's target
    Log(LogLevel::kInfo, "scene_deleted", {{"scene", id}});
    return absl::OkStatus();
  };
  if (auto scene3 = Find3(id); scene3.ok()) return retire(*scene3);
  auto scene = Find(id);
  if (!scene.ok()) return scene.status();
  return retire(*scene);
}

absl::StatusOr<uint64_t> SceneRegistry::UpsertSites(const std::string& scene_id,
                                                    std::vector<Site> sites) {
  return Upsert<Scene>(scene_id, std::move(sites));
}

absl::StatusOr<uint64_t> SceneRegistry::UpsertSites3(const std::string& scene_id,
                                                     std::vector<Site3> sites) {
  return Upsert<Scene3>(scene_id, std::move(sites));
}

template <class S>
absl::StatusOr<uint64_t> SceneRegistry::Upsert(const std::string& scene_id,
                                               std::vector<typename S::Site> sites) {
  auto scene = FindOf<S>(scene_id);
  if (!scene.ok()) return scene.status();
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
  auto version = (*scene)->Upsert(std::move(sites), limits_.max_sites_per_scene,
                                  [&](const ChangeSet& c) {
                                    return Durably([&] { return store_->Commit(c); });
                                  });
  if (version.ok()) Published(*scene);
  return version;
}

absl::StatusOr<uint64_t> SceneRegistry::DeleteSites(const std::string& scene_id,
                                                    const std::vector<std::string>& ids) {
  auto remove = [&](const auto& scene) -> absl::StatusOr<uint64_t> {
    auto version = scene->Delete(
        ids, [&](const ChangeSet& c) { return Durably([&] { return store_->Commit(c); }); });
    if (version.ok()) Published(scene);
    return version;
  };
  if (auto scene3 = Find3(scene_id); scene3.ok()) return remove(*scene3);
  auto scene = Find(scene_id);
  if (!scene.ok()) return scene.status();
  return remove(*scene);
}

absl::StatusOr<uint64_t> SceneRegistry::Apply(const ChangeSet& committed) {
  const std::string id(committed.scene_id);
  if (auto scene3 = Find3(id); scene3.ok()) return ApplyTo(*scene3, committed);
  auto scene = Find(id);
  if (!scene.ok()) return scene.status();
  return ApplyTo(*scene, committed);
}

template <class S>
absl::StatusOr<uint64_t> SceneRegistry::ApplyTo(const std::shared_ptr<S>& scene,
                                                const ChangeSet& committed) {
  constexpr bool kThreeD = std::is_same_v<S, Scene3>;
  if (kThreeD ? !committed.put.empty() : !committed.put3.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "a change to scene \"", scene->id(), "\" puts ", kThreeD ? "2D" : "3D",
        " sites; it is a ", kThreeD ? "3D" : "2D", " scene"));
  }
  uint64_t added = 0;
  for (const auto& site : committed.template Put<typename S::Site>()) added += SiteBytes(*site);
  // Committed elsewhere, so it is not refused for memory: the reservation only keeps the
  // budget's figure honest until the snapshot holds the sites.
  MemoryBudget::Reservation reserved(
      memory_.Reserve(added, "a committed change").ok() ? &memory_ : nullptr, added);
  auto version = scene->Apply(committed);
  if (version.ok()) Published(scene);
  return version;
}

absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> SceneRegistry::Zoom(
    std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids) {
  if (renderer_ == nullptr) return absl::UnavailableError("the server renders nothing");
  return renderer_->Zoom(std::move(base), mode, std::move(grids));
}

std::vector<Metrics::SceneSample> SceneRegistry::Sample() const {
  std::vector<std::shared_ptr<Scene>> scenes;
  std::vector<std::shared_ptr<Scene3>> scenes3;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) scenes.push_back(scene);
    for (const auto& [id, scene] : scenes3_) scenes3.push_back(scene);
  }
  std::vector<Metrics::SceneSample> out;
  auto sample = [&](const auto& s) {
    double lag = static_cast<double>(s->version() - s->frame()->version());
    out.push_back({s->id(), static_cast<double>(s->site_count()), lag, s->frame_age_seconds(),
                   static_cast<double>(s->memory_bytes()), s->render_seconds()});
  };
  for (const auto& s : scenes) sample(s);
  for (const auto& s : scenes3) sample(s);
  std::sort(out.begin(), out.end(),
            [](const Metrics::SceneSample& a, const Metrics::SceneSample& b) { return a.scene < b.scene; });
  return out;
}

}  // namespace gvd
