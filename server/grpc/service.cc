#include "server/grpc/service.h"

#include "server/grpc/call_scope.h"
#include "server/grpc/frame_job.h"

#include "absl/strings/str_cat.h"
#include "render/analysis/analysis.h"
#include "render/image/image.h"
#include "server/grpc/convert.h"
#include "render/scene/cpu_pool.h"
#include "render/kernel/segment_tree.h"
#include "server/log.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <unordered_map>

namespace gvd {

namespace {

using grpc::Status;
using grpc::StatusCode;

// Writes rows [begin, end) into the response: as NearestSite results, or packed (only the
// columns in `fields`, NearestQuery::fields).
void Fill(const std::vector<AnswerRow>& rows, size_t begin, size_t end, bool packed,
          uint32_t fields, v1::FindNearestResponse* response) {
  if (!packed) {
    auto* results = response->mutable_results();
    results->Reserve(static_cast<int>(end - begin));
    for (size_t i = begin; i < end; ++i) {
      v1::NearestSite* r = results->Add();
      if (rows[i].site_id == nullptr) {
        r->set_empty(true);
        r->set_distance(INFINITY);
        r->set_exact(true);
        continue;
      }
      r->set_site_id(*rows[i].site_id);
      r->set_distance(rows[i].distance);
      r->set_error_bound(rows[i].error_bound);
      r->set_exact(rows[i].exact);
      r->set_feature_index(rows[i].feature_index);
      r->set_feature_kind(ToProto(rows[i].feature_kind));
    }
    return;
  }
  // Each column asked for is sized once and written in place; a site's index in site_ids is
  // looked up by its slot (all rows come from one version).
  v1::PackedNearest* p = response->mutable_packed();
  const int n = static_cast<int>(end - begin);
  auto wants = [fields](v1::FindNearestRequest::Field f) { return (fields & (1u << f)) != 0; };
  auto column = [n](auto* field, bool wanted) {
    if (!wanted) return decltype(field->mutable_data())(nullptr);
    field->Resize(n, {});
    return field->mutable_data();
  };
  uint32_t* site = column(p->mutable_site(), wants(v1::FindNearestRequest::SITE));
  double* distance = column(p->mutable_distance(), wants(v1::FindNearestRequest::DISTANCE));
  double* error_bound =
      column(p->mutable_error_bound(), wants(v1::FindNearestRequest::ERROR_BOUND));
  bool* exact = column(p->mutable_exact(), wants(v1::FindNearestRequest::EXACT));
  uint32_t* feature_index =
      column(p->mutable_feature_index(), wants(v1::FindNearestRequest::FEATURE));
  int* feature_kind = column(p->mutable_feature_kind(), wants(v1::FindNearestRequest::FEATURE));
  if (site != nullptr) {
    // slot -> index in site_ids: a table over the slots when the rows are many for the slots
    // they span (a large batch), a hash map otherwise (small stream chunks of a large scene).
    uint32_t slots = 0;
    for (size_t i = begin; i < end; ++i) slots = std::max(slots, rows[i].slot + 1);
    const bool dense = slots <= 4 * size_t(n) + 1024;
    std::vector<uint32_t> table(dense ? slots : 0, UINT32_MAX);
    std::unordered_map<uint32_t, uint32_t> map;
    for (size_t i = begin, k = 0; i < end; ++i, ++k) {
      const AnswerRow& row = rows[i];
      if (row.site_id == nullptr) {
        site[k] = UINT32_MAX;
        continue;
      }
      uint32_t& name = dense ? table[row.slot] : map.try_emplace(row.slot, UINT32_MAX).first->second;
      if (name == UINT32_MAX) {
        name = static_cast<uint32_t>(p->site_ids_size());
        p->add_site_ids(*row.site_id);
      }
      site[k] = name;
    }
  }
  for (size_t i = begin, k = 0; i < end; ++i, ++k) {
    const AnswerRow& row = rows[i];
    if (distance) distance[k] = row.distance;
    if (error_bound) error_bound[k] = row.error_bound;
    if (exact) exact[k] = row.exact;
    if (feature_index) {
      feature_index[k] = row.feature_index;
      feature_kind[k] = ToProto(row.feature_kind);
    }
  }
}

class NearestUnaryReactor final : public grpc::ServerUnaryReactor {
 public:
  NearestUnaryReactor(NearestQuery query, bool packed, v1::FindNearestResponse* response)
      : job_(std::make_shared<NearestJob>(std::move(query))), packed_(packed),
        response_(response) {}

  // After Start, this object may already be finished and deleted.
  void Start() {
    auto job = job_;
    job->Start([this](const Status& s) {
      if (s.ok()) {
        response_->set_version(job_->version());
        Fill(job_->rows(), 0, job_->rows().size(), packed_, job_->fields(), response_);
      }
      Finish(s);
    });
  }
  void OnCancel() override { job_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  std::shared_ptr<NearestJob> job_;
  bool packed_;
  v1::FindNearestResponse* response_;
};

class NearestStreamReactor final : public grpc::ServerWriteReactor<v1::FindNearestResponse> {
 public:
  NearestStreamReactor(NearestQuery query, size_t chunk)
      : job_(std::make_shared<NearestJob>(std::move(query))), chunk_(chunk) {}

  void Start() {
    auto job = job_;
    job->Start([this](const Status& s) {
      if (!s.ok()) {
        Finish(s);
        return;
      }
      Next();
    });
  }
  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(Status(StatusCode::CANCELLED, "the client stopped reading"));
      return;
    }
    Next();
  }
  void OnCancel() override { job_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  void Next() {
    const auto& rows = job_->rows();
    if (offset_ >= rows.size()) {
      Finish(Status::OK);
      return;
    }
    size_t end = std::min(rows.size(), offset_ + chunk_);
    message_.Clear();
    message_.set_version(job_->version());
    message_.set_offset(offset_);
    Fill(rows, offset_, end, /*packed=*/true, job_->fields(), &message_);
    offset_ = end;
    StartWrite(&message_);
  }

  std::shared_ptr<NearestJob> job_;
  size_t chunk_;
  size_t offset_ = 0;
  v1::FindNearestResponse message_;
};

}  // namespace

VoronoiService::VoronoiService(RenderLoop* renderer, SceneStore* store, ServerLimits limits,
                               const TokenAuth* auth, Metrics* metrics)
    : renderer_(renderer), store_(store), limits_(limits), auth_(auth), metrics_(metrics),
      calls_(metrics),
      memory_(limits.max_memory, [this] { return ScenesMemory(); }),
      analyses_(CpuPool::Process(), /*priority=*/0, limits.analysis_threads,
                limits.max_queued_analyses),
      answers_(CpuPool::Process(), /*priority=*/1, SIZE_MAX, SIZE_MAX) {}

Executor VoronoiService::executor() {
  return [this](std::function<void()> job) { answers_.Submit(std::move(job)); };
}

template <class StoreCall>
absl::Status VoronoiService::Durably(StoreCall store_call) const {
  auto start = std::chrono::steady_clock::now();
  absl::Status s = store_call();
  if (s.ok() && metrics_) {
    metrics_->ObserveCommit(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return s;
}

uint64_t VoronoiService::ScenesMemory() const {
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t sum = 0;
  for (const auto& [id, scene] : scenes_) sum += scene->memory_bytes();
  return sum;
}

std::vector<Metrics::SceneSample> VoronoiService::SampleScenes() const {
  std::vector<std::shared_ptr<Scene>> scenes;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) scenes.push_back(scene);
  }
  std::vector<Metrics::SceneSample> out;
  for (const auto& s : scenes) {
    double lag = static_cast<double>(s->version() - s->frame()->version());
    out.push_back({s->id(), static_cast<double>(s->site_count()), lag, s->frame_age_seconds(),
                   static_cast<double>(s->memory_bytes()), s->render_seconds()});
  }
  return out;
}

Status VoronoiService::Admit(grpc::CallbackServerContext* ctx, bool write) const {
  if (auto s = Ready(); !s.ok()) return s;
  if (auth_ != nullptr) return auth_->Check(*ctx, write);
  return Status::OK;
}

absl::Status VoronoiService::Load() {
  auto stored = store_->Load();
  if (!stored.ok()) return stored.status();
  size_t sites = 0, unloaded = 0;
  // Scenes load in id order while they fit --max-memory. The rest stay in the store,
  // reported unavailable: a store that outgrew the budget (or a smaller container) still
  // starts, and serves what fits, instead of dying at every start.
  std::sort(stored->begin(), stored->end(),
            [](const StoredScene& a, const StoredScene& b) { return a.settings.id < b.settings.id; });
  for (StoredScene& s : *stored) {
    uint64_t bytes = Scene::RasterBytes(s.settings);
    for (const Site& site : s.sites) bytes += SiteBytes(site);
    absl::Status fits = memory_.Reserve(
        bytes, absl::StrCat("scene \"", s.settings.id, "\" (", s.settings.grid.width, "x",
                            s.settings.grid.height, " pixels, ", s.sites.size(), " sites)"));
    if (!fits.ok()) {
      Log(LogLevel::kWarn, "scene_unavailable",
          {{"scene", s.settings.id}, {"reason", std::string(fits.message())}});
      std::string id = s.settings.id;
      std::lock_guard<std::mutex> lock(mu_);
      unloaded_[id] = {std::move(s.settings), s.version, s.sites.size(), bytes,
                       std::string(fits.message())};
      ++unloaded;
      continue;
    }
    MemoryBudget::Reservation reserved(&memory_, bytes);
    sites += s.sites.size();
    // Stored sites were validated when they were accepted: they go straight to a snapshot.
    auto scene = std::make_shared<Scene>(std::move(s.settings), s.version, std::move(s.sites),
                                         executor());
    {
      std::lock_guard<std::mutex> lock(mu_);
      scenes_[scene->id()] = scene;
    }
    renderer_->MarkDirty(scene);
  }
  Log(LogLevel::kInfo, "store_loaded",
      {{"path", store_->Describe()}, {"scenes", absl::StrCat(stored->size() - unloaded)},
       {"unavailable_scenes", absl::StrCat(unloaded)}, {"sites", absl::StrCat(sites)},
       {"memory", FormatBytes(memory_.used())}});
  ready_ = true;
  return absl::OkStatus();
}

Status VoronoiService::Ready() const {
  if (draining_) return Status(StatusCode::UNAVAILABLE, "the server is shutting down");
  if (ready_) return Status::OK;
  return Status(StatusCode::UNAVAILABLE, "the server is loading its store; retry shortly");
}

int VoronoiService::Drain(std::chrono::milliseconds grace) {
  draining_ = true;
  watches_.EndAll(Status(StatusCode::UNAVAILABLE, "the server is shutting down"));
  auto deadline = std::chrono::steady_clock::now() + grace;
  while (calls_.in_flight > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return calls_.in_flight;
}

Status VoronoiService::Lookup(const std::string& scene_id, std::shared_ptr<Scene>* scene) const {
  if (auto s = Ready(); !s.ok()) return s;
  if (auto s = ValidateSceneId(scene_id, limits_); !s.ok()) return s;
  std::lock_guard<std::mutex> lock(mu_);
  auto it = scenes_.find(scene_id);
  if (it == scenes_.end()) {
    if (auto u = unloaded_.find(scene_id); u != unloaded_.end()) {
      return Status(StatusCode::FAILED_PRECONDITION,
                    absl::StrCat("scene \"", scene_id, "\" is stored but not loaded: ",
                                 u->second.reason));
    }
    return Status(StatusCode::NOT_FOUND, absl::StrCat("scene \"", scene_id, "\" does not exist"));
  }
  *scene = it->second;
  return Status::OK;
}

VoronoiService::Call VoronoiService::Begin(grpc::CallbackServerContext* ctx, const char* method,
                                           Access access, const std::string* scene_id) const {
  Call call;
  call.scope = std::make_shared<CallScope>(&calls_, method);
  call.status = Admit(ctx, access == Access::kWrite);
  if (call.ok() && scene_id != nullptr) call.status = Lookup(*scene_id, &call.scene);
  return call;
}

grpc::ServerUnaryReactor* VoronoiService::CreateScene(grpc::CallbackServerContext* ctx,
                                                      const v1::CreateSceneRequest* request,
                                                      v1::Scene* response) {
  Call call = Begin(ctx, "CreateScene", Access::kWrite);
  if (!call.ok()) return call.Finish(ctx);
  SceneSettings settings;
  if (auto s = ToSceneSettings(*request, limits_, &settings); !s.ok()) return call.Finish(ctx, s);
  // The raster's bytes, reserved until the scene is in scenes_ (then it counts them).
  const uint64_t raster = Scene::RasterBytes(settings);
  if (auto s = memory_.Reserve(raster, absl::StrCat("scene \"", settings.id, "\" of ",
                                                    settings.grid.width, "x", settings.grid.height,
                                                    " pixels"));
      !s.ok()) {
    return call.Finish(ctx, ToGrpc(s));
  }
  MemoryBudget::Reservation reserved(&memory_, raster);
  auto scene = std::make_shared<Scene>(std::move(settings), executor());
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (scenes_.count(scene->id()) || creating_.count(scene->id()) ||
        unloaded_.count(scene->id())) {
      return call.Finish(ctx, Status(StatusCode::ALREADY_EXISTS,
                              absl::StrCat("scene \"", scene->id(), "\" already exists")));
    }
    if (scenes_.size() + creating_.size() >= limits_.max_scenes) {
      return call.Finish(ctx, Status(StatusCode::RESOURCE_EXHAUSTED,
                              absl::StrCat("the server holds ", scenes_.size() + creating_.size(),
                                           " scenes; the limit (--max-scenes) is ",
                                           limits_.max_scenes)));
    }
    creating_.insert(scene->id());  // reserved: the commit runs without the lock
  }
  absl::Status stored =
      Durably([&] { return store_->CreateScene(scene->settings(), scene->version()); });
  {
    std::lock_guard<std::mutex> lock(mu_);
    creating_.erase(scene->id());
    if (stored.ok()) scenes_.emplace(scene->id(), scene);
  }
  if (!stored.ok()) return call.Finish(ctx, ToGrpc(stored));
  ToProto(*scene, response);
  Log(LogLevel::kInfo, "scene_created",
      {{"scene", scene->id()}, {"width_px", absl::StrCat(request->width_px())},
       {"height_px", absl::StrCat(request->height_px())},
       {"max_error", FormatNumber(scene->settings().eps)}});
  return call.Finish(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::GetScene(grpc::CallbackServerContext* ctx,
                                                   const v1::GetSceneRequest* request,
                                                   v1::Scene* response) {
  Call call = Begin(ctx, "GetScene", Access::kRead);
  if (!call.ok()) return call.Finish(ctx);
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto u = unloaded_.find(request->scene_id()); u != unloaded_.end()) {
      Describe(u->second, response);
      return call.Finish(ctx, Status::OK);
    }
  }
  call.status = Lookup(request->scene_id(), &call.scene);
  if (!call.ok()) return call.Finish(ctx);
  const std::shared_ptr<Scene>& scene = call.scene;
  ToProto(*scene, response);
  // Sites that meet the window but hold no pixel of the latest frame (paper sec. 6.2): their
  // number and the first kHiddenIds ids, computed once per frame.
  constexpr size_t kHiddenIds = 16;
  const std::shared_ptr<const Frame> frame = scene->frame();
  auto hidden = scene->Derived<std::vector<uint32_t>>(frame, [](const Frame& frame) {
    if (frame.empty()) return std::vector<uint32_t>();
    return HiddenSites(IdsOf(frame, frame.grid().all()), frame.sites());
  });
  response->set_hidden_site_count(hidden->size());
  for (size_t k = 0; k < hidden->size() && k < kHiddenIds; ++k) {
    response->add_hidden_site_ids(frame->sites().get((*hidden)[k])->id);
  }
  return call.Finish(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::ListScenes(grpc::CallbackServerContext* ctx,
                                                     const v1::ListScenesRequest*,
                                                     v1::ListScenesResponse* response) {
  Call call = Begin(ctx, "ListScenes", Access::kRead);
  if (!call.ok()) return call.Finish(ctx);
  std::vector<std::shared_ptr<Scene>> scenes;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) scenes.push_back(scene);
    for (const auto& [id, scene] : unloaded_) Describe(scene, response->add_scenes());
  }
  for (const auto& scene : scenes) ToProto(*scene, response->add_scenes());
  std::sort(response->mutable_scenes()->begin(), response->mutable_scenes()->end(),
            [](const v1::Scene& a, const v1::Scene& b) { return a.scene_id() < b.scene_id(); });
  return call.Finish(ctx, Status::OK);
}

void VoronoiService::Describe(const Unloaded& scene, v1::Scene* out) {
  ToProto(scene.settings, out);
  out->set_version(scene.version);
  out->set_site_count(scene.sites);
  out->set_memory_bytes(scene.bytes);
  out->set_unavailable(scene.reason);
}

grpc::ServerUnaryReactor* VoronoiService::DeleteScene(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSceneRequest* request,
                                                      v1::DeleteSceneResponse*) {
  Call call = Begin(ctx, "DeleteScene", Access::kWrite);
  if (!call.ok()) return call.Finish(ctx);
  // A scene left unloaded (it did not fit --max-memory) is deleted from the store alone.
  bool unloaded;
  {
    std::lock_guard<std::mutex> lock(mu_);
    unloaded = unloaded_.count(request->scene_id()) > 0;
  }
  if (unloaded) {
    absl::Status deleted = Durably([&] { return store_->DeleteScene(request->scene_id()); });
    if (!deleted.ok()) return call.Finish(ctx, ToGrpc(deleted));
    {
      std::lock_guard<std::mutex> lock(mu_);
      unloaded_.erase(request->scene_id());
    }
    Log(LogLevel::kInfo, "scene_deleted", {{"scene", request->scene_id()}, {"loaded", "false"}});
    return call.Finish(ctx, Status::OK);
  }
  call.status = Lookup(request->scene_id(), &call.scene);
  if (!call.ok()) return call.Finish(ctx);
  const std::shared_ptr<Scene>& scene = call.scene;
  // The commit holds only the scene's writer lock: writes to the scene wait and then find it
  // deleted, and other scenes' lookups go on.
  absl::Status deleted =
      scene->Retire([&] { return Durably([&] { return store_->DeleteScene(scene->id()); }); });
  if (!deleted.ok()) return call.Finish(ctx, ToGrpc(deleted));
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = scenes_.find(scene->id());
    if (it != scenes_.end() && it->second == scene) scenes_.erase(it);
  }
  scene->FailWaiters(absl::NotFoundError(absl::StrCat("scene \"", scene->id(), "\" was deleted")));
  renderer_->MarkDirty(scene);  // lets the render thread release the scene's target
  Log(LogLevel::kInfo, "scene_deleted", {{"scene", scene->id()}});
  return call.Finish(ctx, Status::OK);
}

grpc::ServerWriteReactor<v1::SceneEvent>* VoronoiService::WatchScene(
    grpc::CallbackServerContext* ctx, const v1::WatchSceneRequest* request) {
  Call call = Begin(ctx, "WatchScene", Access::kRead, &request->scene_id());
  if (!call.ok()) return Watches::Refuse(call.scope, call.status);
  return watches_.Start(call.scope, call.scene, request->after_version());
}

grpc::ServerUnaryReactor* VoronoiService::UpsertSites(grpc::CallbackServerContext* ctx,
                                                      const v1::UpsertSitesRequest* request,
                                                      v1::UpsertSitesResponse* response) {
  Call call = Begin(ctx, "UpsertSites", Access::kWrite, &request->scene_id());
  if (!call.ok()) return call.Finish(ctx);
  const std::shared_ptr<Scene>& scene = call.scene;
  std::vector<Site> sites;
  if (auto s = ToSites(*request, limits_, &sites); !s.ok()) return call.Finish(ctx, s);
  // What the sites add, reserved until the scene's snapshot holds them (sites they replace
  // are not subtracted: a reservation may only overstate).
  uint64_t added = 0;
  for (const Site& site : sites) added += SiteBytes(site);
  if (auto s = memory_.Reserve(added, absl::StrCat(sites.size(), " sites for scene \"",
                                                   scene->id(), "\""));
      !s.ok()) {
    return call.Finish(ctx, ToGrpc(s));
  }
  MemoryBudget::Reservation reserved(&memory_, added);
  auto version = scene->Upsert(std::move(sites), limits_.max_sites_per_scene,
                               [&](const ChangeSet& c) {
                                 return Durably([&] { return store_->Commit(c); });
                               });
  if (!version.ok()) return call.Finish(ctx, ToGrpc(version.status()));
  response->set_version(*version);
  renderer_->MarkDirty(scene);
  return call.Finish(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::DeleteSites(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSitesRequest* request,
                                                      v1::DeleteSitesResponse* response) {
  Call call = Begin(ctx, "DeleteSites", Access::kWrite, &request->scene_id());
  if (!call.ok()) return call.Finish(ctx);
  const std::shared_ptr<Scene>& scene = call.scene;
  std::vector<std::string> ids;
  if (auto s = ToSiteIds(*request, limits_, &ids); !s.ok()) return call.Finish(ctx, s);
  auto version = scene->Delete(
      ids, [&](const ChangeSet& c) { return Durably([&] { return store_->Commit(c); }); });
  if (!version.ok()) return call.Finish(ctx, ToGrpc(version.status()));
  response->set_version(*version);
  renderer_->MarkDirty(scene);
  return call.Finish(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::ListSites(grpc::CallbackServerContext* ctx,
                                                    const v1::ListSitesRequest* request,
                                                    v1::ListSitesResponse* response) {
  Call call = Begin(ctx, "ListSites", Access::kRead, &request->scene_id());
  if (!call.ok()) return call.Finish(ctx);
  const std::shared_ptr<Scene>& scene = call.scene;
  uint32_t size = request->page_size() == 0 ? 1000 : request->page_size();
  if (size > limits_.max_page_size) {
    return call.Finish(ctx, Status(StatusCode::INVALID_ARGUMENT,
                            absl::StrCat("page_size is ", size, "; it must be at most ",
                                         limits_.max_page_size)));
  }
  // The page token is the last id of the previous page; ids are ordered bytewise.
  Scene::SitePage page = scene->ListSites(request->page_token(), size);
  for (const Site& site : page.sites) ToProto(site, response->add_sites());
  response->set_next_page_token(page.last_id);
  response->set_version(page.version);
  return call.Finish(ctx, Status::OK);
}

Status VoronoiService::ParseNearest(const v1::FindNearestRequest& request,
                                    NearestQuery* query) const {
  bool outside = false;
  if (auto s = ToQueryPoints(request, query->scene->settings().grid.window, limits_,
                             &query->points, &outside);
      !s.ok()) {
    return s;
  }
  if (auto s = WaitFor(request.min_version(), query); !s.ok()) return s;
  query->exact = request.exact() || outside;
  query->skip_refinement = request.skip_refinement();
  if (request.fields_size() > 0) {
    query->fields = 0;
    for (int i = 0; i < request.fields_size(); ++i) {
      const int f = request.fields(i);
      if (f < v1::FindNearestRequest::SITE || f > v1::FindNearestRequest::FEATURE) {
        return Status(StatusCode::INVALID_ARGUMENT,
                      absl::StrCat("fields[", i, "] is ", f,
                                   "; it must be SITE, DISTANCE, ERROR_BOUND, EXACT or FEATURE"));
      }
      query->fields |= 1u << f;
    }
  }
  if (query->exact && query->scene->site_count() == 0) {
    return Status(StatusCode::FAILED_PRECONDITION,
                  absl::StrCat("scene \"", query->scene->id(), "\" has no sites at version ",
                               query->scene->version()));
  }
  return Status::OK;
}

Status VoronoiService::WaitFor(uint64_t requested, NearestQuery* query) const {
  uint64_t version = query->scene->version();
  if (requested > version) {
    return Status(StatusCode::OUT_OF_RANGE,
                  absl::StrCat("min_version ", requested, " is ahead of scene \"",
                               query->scene->id(), "\", which is at version ", version));
  }
  query->min_version = requested;
  // A scene whose first render is under way waits for it rather than answering "no sites".
  if (query->scene->frame()->empty() && query->scene->site_count() > 0) {
    query->min_version = version;
  }
  return Status::OK;
}

grpc::ServerUnaryReactor* VoronoiService::FindNearest(grpc::CallbackServerContext* ctx,
                                                      const v1::FindNearestRequest* request,
                                                      v1::FindNearestResponse* response) {
  Call call = Begin(ctx, "FindNearest", Access::kRead, &request->scene_id());
  if (!call.ok()) return call.Finish(ctx);
  NearestQuery query{call.scope, ctx, call.scene};
  if (request->fields_size() > 0 && request->points_size() > 0) {
    return call.Finish(ctx, Status(StatusCode::INVALID_ARGUMENT,
                                   "fields selects the columns of packed answers; send the "
                                   "points as xy, or leave fields empty"));
  }
  if (auto s = ParseNearest(*request, &query); !s.ok()) return call.Finish(ctx, s);
  auto* reactor = new NearestUnaryReactor(std::move(query), request->xy_size() > 0, response);
  reactor->Start();
  return reactor;
}

grpc::ServerWriteReactor<v1::FindNearestResponse>* VoronoiService::FindNearestStream(
    grpc::CallbackServerContext* ctx, const v1::FindNearestRequest* request) {
  Call call = Begin(ctx, "FindNearestStream", Access::kRead, &request->scene_id());
  NearestQuery query{call.scope, ctx, call.scene};
  Status s = call.status;
  if (s.ok()) s = ParseNearest(*request, &query);
  if (!s.ok()) query.scope->Record(s);
  size_t chunk = request->chunk_size() == 0 ? 65536 : request->chunk_size();
  auto* reactor = new NearestStreamReactor(std::move(query), chunk);
  if (!s.ok()) {
    reactor->Finish(s);
  } else {
    reactor->Start();
  }
  return reactor;
}

}  // namespace gvd

namespace gvd {

grpc::ServerUnaryReactor* VoronoiService::RenderImage(grpc::CallbackServerContext* ctx,
                                                      const v1::RenderImageRequest* request,
                                                      v1::RenderImageResponse* response) {
  Call call = Begin(ctx, "RenderImage", Access::kRead, &request->scene_id());
  if (!call.ok()) return call.Finish(ctx);
  NearestQuery query{call.scope, ctx, call.scene};
  ImageOptions options;
  if (auto s = ToImageOptions(*request, query.scene->settings().grid, &options); !s.ok()) {
    return call.Finish(ctx, s);
  }
  if (auto s = WaitFor(request->min_version(), &query); !s.ok()) return call.Finish(ctx, s);
  query.on_frame = [options, response](const Frame& frame) {
    auto image = EncodeImage(frame, options);
    if (!image.ok()) return ToGrpc(image.status());
    response->set_image(image->bytes.data(), image->bytes.size());
    response->set_mime_type(image->mime_type);
    response->set_width_px(image->width);
    response->set_height_px(image->height);
    response->set_version(frame.version());
    for (std::string& id : image->site_ids) response->add_site_ids(std::move(id));
    ToProto(frame.grid().Area(options.rect), response->mutable_window());
    return Status::OK;
  };
  auto* reactor = new FrameReactor(std::move(query));
  reactor->Start();
  return reactor;
}

}  // namespace gvd
