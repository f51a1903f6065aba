#include "server/grpc/service.h"

#include <algorithm>
#include <thread>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "render/analysis/analysis.h"
#include "render/image/image.h"
#include "server/app/jobs.h"
#include "server/grpc/convert.h"
#include "server/grpc/reactors.h"

namespace gvd {

namespace {

using grpc::Status;
using grpc::StatusCode;

// The packed columns a FindNearest request asks for: bit f for v1::FindNearestRequest::Field f.
constexpr uint32_t kDefaultFields = 0x3e;  // SITE .. FEATURE, when a request names none
constexpr uint32_t Bit(v1::FindNearestRequest::Field f) { return 1u << f; }
// The fields that a request with `points` may name: they add to whole NearestSite messages.
constexpr uint32_t kPointFields =
    Bit(v1::FindNearestRequest::CLOSEST) | Bit(v1::FindNearestRequest::GRADIENT);

// Writes the job's answers [begin, end) into the response: as NearestSite results, or packed
// (only the columns in `fields`: bit f for v1::FindNearestRequest::Field f).
// A template on the job (NearestJob, NearestJob3): closest points and gradients have 2 or 3
// coordinates.
template <class J>
void Fill(const J& job, size_t begin, size_t end, bool packed, uint32_t fields,
          v1::FindNearestResponse* response) {
  using Point = typename J::Point;
  constexpr int kWidth = Point::length();
  const std::vector<AnswerRow>& rows = job.rows();
  const std::vector<Point>& points = job.points();
  const std::vector<Point>& nearest_points = job.closest();  // filled when asked for
  const bool closest = (fields & Bit(v1::FindNearestRequest::CLOSEST)) != 0;
  const bool gradient = (fields & Bit(v1::FindNearestRequest::GRADIENT)) != 0;
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
      if (closest) ToProto(nearest_points[i], r->mutable_closest());
      if (gradient) ToProto(UnitGradient(points[i], nearest_points[i]), r->mutable_gradient());
    }
    return;
  }
  // Each column asked for is sized once and written in place; a site's index in site_ids is
  // looked up by its slot (all rows come from one version).
  v1::PackedNearest* p = response->mutable_packed();
  const int n = static_cast<int>(end - begin);
  auto wants = [fields](v1::FindNearestRequest::Field f) { return (fields & (1u << f)) != 0; };
  // A column of `width` values an answer (x and y: 2), sized once, or null when not wanted.
  auto column = [n](auto* field, bool wanted, int width = 1) {
    if (!wanted) return decltype(field->mutable_data())(nullptr);
    field->Resize(width * n, {});
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
  double* closest_xy = column(p->mutable_closest(), closest, kWidth);
  double* gradient_xy = column(p->mutable_gradient(), gradient, kWidth);
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
    if (closest_xy || gradient_xy) {
      const Point c = nearest_points[i];  // NaN for an empty answer
      const Point g = row.site_id == nullptr ? Point(NAN) : UnitGradient(points[i], c);
      for (int a = 0; a < kWidth; ++a) {
        if (closest_xy) closest_xy[kWidth * k + a] = c[a];
        if (gradient_xy) gradient_xy[kWidth * k + a] = g[a];
      }
    }
  }
}

template <class J>
class NearestStreamReactor final : public grpc::ServerWriteReactor<v1::FindNearestResponse> {
 public:
  NearestStreamReactor(std::shared_ptr<CallScope> scope, std::shared_ptr<J> job,
                       uint32_t fields, size_t chunk)
      : scope_(std::move(scope)), job_(std::move(job)), fields_(fields), chunk_(chunk) {}

  // After Start, this object may already be finished and deleted.
  void Start() {
    auto job = job_;
    job->Start([this](const absl::Status& s) {
      const Status status = ToGrpc(s);
      scope_->Record(status);
      if (!status.ok()) {
        Finish(status);
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
  void OnCancel() override {
    if (job_) job_->Cancel();
  }
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
    Fill(*job_, offset_, end, /*packed=*/true, fields_, &message_);
    offset_ = end;
    StartWrite(&message_);
  }

  std::shared_ptr<CallScope> scope_;
  std::shared_ptr<J> job_;
  uint32_t fields_;
  size_t chunk_;
  size_t offset_ = 0;
  v1::FindNearestResponse message_;
};

// A stored scene that is not loaded, as GetScene and ListScenes describe it.
void Describe(const UnloadedScene& scene, v1::Scene* out) {
  ToProto(scene.settings, out);
  out->set_version(scene.version);
  out->set_site_count(scene.sites);
  out->set_memory_bytes(scene.bytes);
  out->set_unavailable(scene.reason);
}

}  // namespace

VoronoiService::VoronoiService(SceneRegistry* registry, const TokenAuth* auth, Metrics* metrics)
    : registry_(registry), limits_(registry->limits()), auth_(auth), calls_(metrics) {}

Status VoronoiService::Admit(grpc::CallbackServerContext* ctx, bool write) const {
  if (draining_) return Status(StatusCode::UNAVAILABLE, "the server is shutting down");
  if (!registry_->loaded()) {
    return Status(StatusCode::UNAVAILABLE, "the server is loading its store; retry shortly");
  }
  if (auth_ != nullptr) return auth_->Check(*ctx, write);
  return Status::OK;
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

VoronoiService::Call VoronoiService::Begin(grpc::CallbackServerContext* ctx, const char* method,
                                           Access access, const std::string* scene_id,
                                           bool three_d) const {
  Call call;
  call.scope = std::make_shared<CallScope>(&calls_, method);
  call.status = Admit(ctx, access == Access::kWrite);
  if (call.ok() && scene_id != nullptr) {
    call.status = ValidateSceneId(*scene_id, limits_);
    if (call.ok()) {
      auto found = registry_->Find(*scene_id);
      if (!found.ok()) {
        call.status = ToGrpc(found.status());
      } else if (three_d && found->three_d()) {
        call.scene3 = *found->As<Scene3>();
      } else if (auto scene = found->As<Scene>(); scene.ok()) {
        call.scene = *scene;
      } else {
        call.status = ToGrpc(scene.status());
      }
    }
  }
  return call;
}

grpc::ServerUnaryReactor* VoronoiService::CreateScene(grpc::CallbackServerContext* ctx,
                                                      const v1::CreateSceneRequest* request,
                                                      v1::Scene* response) {
  Call call = Begin(ctx, "CreateScene", Access::kWrite);
  if (!call.ok()) return call.Finish(ctx);
  SceneSettings settings;
  if (auto s = ToSceneSettings(*request, limits_, &settings); !s.ok()) return call.Finish(ctx, s);
  return LaneReactor::Start(call.scope, registry_->commits(), "--max-queued-writes",
                            [this, settings = std::move(settings), response]() mutable {
                              auto scene = registry_->CreateScene(std::move(settings));
                              if (!scene.ok()) return ToGrpc(scene.status());
                              scene->Visit([&](const auto& s) { ToProto(*s, response); });
                              return Status::OK;
                            });
}

grpc::ServerUnaryReactor* VoronoiService::GetScene(grpc::CallbackServerContext* ctx,
                                                   const v1::GetSceneRequest* request,
                                                   v1::Scene* response) {
  Call call = Begin(ctx, "GetScene", Access::kRead);
  if (!call.ok()) return call.Finish(ctx);
  if (auto s = ValidateSceneId(request->scene_id(), limits_); !s.ok()) return call.Finish(ctx, s);
  auto entry = registry_->Describe(request->scene_id());
  if (!entry.ok()) return call.Finish(ctx, ToGrpc(entry.status()));
  if (entry->unloaded) {
    Describe(*entry->unloaded, response);
    return call.Finish(ctx, Status::OK);
  }
  const SceneRegistry::StoreLag lag = registry_->Lag(request->scene_id());
  if (entry->scene->three_d()) {
    entry->scene->Visit([&](const auto& s) { ToProto(*s, response); });
    ToProto(lag, response);
    return call.Finish(ctx, Status::OK);
  }
  // Sites that meet the window but hold no pixel of the latest frame (paper sec. 6.2): their
  // number and the first kHiddenIds ids, computed once per frame on the CPU pool (a scan of
  // the frame's pixels).
  return LaneReactor::Start(
      call.scope, registry_->answers(), "", [scene = *entry->scene->As<Scene>(), response, lag] {
        constexpr size_t kHiddenIds = 16;
        ToProto(*scene, response);
        ToProto(lag, response);
        const std::shared_ptr<const Frame> frame = scene->frame();
        auto hidden = scene->Derived<std::vector<uint32_t>>(frame, [](const Frame& frame) {
          if (frame.empty()) return std::vector<uint32_t>();
          return HiddenSites(IdsOf(frame, frame.grid().all()), frame.sites());
        });
        response->set_hidden_site_count(hidden->size());
        for (size_t k = 0; k < hidden->size() && k < kHiddenIds; ++k) {
          response->add_hidden_site_ids(frame->sites().get((*hidden)[k])->id);
        }
        return Status::OK;
      });
}

grpc::ServerUnaryReactor* VoronoiService::ListScenes(grpc::CallbackServerContext* ctx,
                                                     const v1::ListScenesRequest*,
                                                     v1::ListScenesResponse* response) {
  Call call = Begin(ctx, "ListScenes", Access::kRead);
  if (!call.ok()) return call.Finish(ctx);
  for (const SceneEntry& entry : registry_->List()) {
    if (entry.unloaded) {
      Describe(*entry.unloaded, response->add_scenes());
    } else {
      entry.scene->Visit([&](const auto& s) { ToProto(*s, response->add_scenes()); });
    }
    if (!entry.unloaded) ToProto(registry_->Lag(entry.id()), response->mutable_scenes()->Mutable(
                                                                response->scenes_size() - 1));
  }
  return call.Finish(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::DeleteScene(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSceneRequest* request,
                                                      v1::DeleteSceneResponse*) {
  Call call = Begin(ctx, "DeleteScene", Access::kWrite);
  if (!call.ok()) return call.Finish(ctx);
  if (auto s = ValidateSceneId(request->scene_id(), limits_); !s.ok()) return call.Finish(ctx, s);
  return LaneReactor::Start(call.scope, registry_->commits(), "--max-queued-writes",
                            [this, id = request->scene_id()] {
                              return ToGrpc(registry_->DeleteScene(id));
                            });
}

grpc::ServerWriteReactor<v1::SceneEvent>* VoronoiService::WatchScene(
    grpc::CallbackServerContext* ctx, const v1::WatchSceneRequest* request) {
  Call call = Begin(ctx, "WatchScene", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return Watches::Refuse(call.scope, call.status);
  if (call.scene3) return watches_.Start(call.scope, call.scene3, request->after_version());
  return watches_.Start(call.scope, call.scene, request->after_version());
}

grpc::ServerUnaryReactor* VoronoiService::UpsertSites(grpc::CallbackServerContext* ctx,
                                                      const v1::UpsertSitesRequest* request,
                                                      v1::UpsertSitesResponse* response) {
  Call call = Begin(ctx, "UpsertSites", Access::kWrite, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  Durability durability;
  if (auto s = ToDurability(request->durability(), &durability); !s.ok()) {
    return call.Finish(ctx, s);
  }
  if (call.scene3) {
    std::vector<Site3> sites;
    if (auto s = ToSites3(*request, limits_, &sites); !s.ok()) return call.Finish(ctx, s);
    return LaneReactor::Start(call.scope, registry_->commits(), "--max-queued-writes",
                              [this, id = request->scene_id(), sites = std::move(sites),
                               durability, response]() mutable {
                                auto version =
                                    registry_->UpsertSites(id, std::move(sites), durability);
                                if (!version.ok()) return ToGrpc(version.status());
                                response->set_version(*version);
                                return Status::OK;
                              });
  }
  std::vector<Site> sites;
  if (auto s = ToSites(*request, limits_, &sites); !s.ok()) return call.Finish(ctx, s);
  return LaneReactor::Start(call.scope, registry_->commits(), "--max-queued-writes",
                            [this, id = request->scene_id(), sites = std::move(sites),
                             durability, response]() mutable {
                              auto version =
                                  registry_->UpsertSites(id, std::move(sites), durability);
                              if (!version.ok()) return ToGrpc(version.status());
                              response->set_version(*version);
                              return Status::OK;
                            });
}

grpc::ServerUnaryReactor* VoronoiService::DeleteSites(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSitesRequest* request,
                                                      v1::DeleteSitesResponse* response) {
  Call call = Begin(ctx, "DeleteSites", Access::kWrite, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  std::vector<std::string> ids;
  if (auto s = ToSiteIds(*request, limits_, &ids); !s.ok()) return call.Finish(ctx, s);
  Durability durability;
  if (auto s = ToDurability(request->durability(), &durability); !s.ok()) {
    return call.Finish(ctx, s);
  }
  return LaneReactor::Start(call.scope, registry_->commits(), "--max-queued-writes",
                            [this, id = request->scene_id(), ids = std::move(ids), durability,
                             response] {
                              auto version = registry_->DeleteSites(id, ids, durability);
                              if (!version.ok()) return ToGrpc(version.status());
                              response->set_version(*version);
                              return Status::OK;
                            });
}

grpc::ServerUnaryReactor* VoronoiService::ListSites(grpc::CallbackServerContext* ctx,
                                                    const v1::ListSitesRequest* request,
                                                    v1::ListSitesResponse* response) {
  Call call = Begin(ctx, "ListSites", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  uint32_t size = request->page_size() == 0 ? 1000 : request->page_size();
  if (size > limits_.max_page_size) {
    return call.Finish(ctx, Status(StatusCode::INVALID_ARGUMENT,
                            absl::StrCat("page_size is ", size, "; it must be at most ",
                                         limits_.max_page_size)));
  }
  // The page token is the last id of the previous page; ids are ordered bytewise.
  auto list = [&](const auto& scene) {
    auto page = scene.ListSites(request->page_token(), size);
    for (const auto& site : page.sites) ToProto(site, response->add_sites());
    response->set_next_page_token(page.last_id);
    response->set_version(page.version);
  };
  if (call.scene3) {
    list(*call.scene3);
  } else {
    list(*call.scene);
  }
  return call.Finish(ctx, Status::OK);
}

// A request's query points for a scene of either dimension.
Status QueryPointsFor(const v1::FindNearestRequest& request, const Scene& scene,
                      const ServerLimits& limits, std::vector<Vec2>* points, bool* outside) {
  return ToQueryPoints(request, scene.settings().grid.window, limits, points, outside);
}
Status QueryPointsFor(const v1::FindNearestRequest& request, const Scene3& scene,
                      const ServerLimits& limits, std::vector<Vec3>* points, bool* outside) {
  return ToQueryPoints3(request, scene.settings().grid3().box, limits, points, outside);
}

template <class S>
Status VoronoiService::ParseNearest(const v1::FindNearestRequest& request, const S& scene,
                                    bool packed, BasicNearestQuery<typename S::Point>* query,
                                    uint32_t* fields) const {
  bool outside = false;
  if (auto s = QueryPointsFor(request, scene, limits_, &query->points, &outside); !s.ok()) {
    return s;
  }
  auto version = registry_->ReadVersion(scene, request.min_version());
  if (!version.ok()) return ToGrpc(version.status());
  query->min_version = *version;
  query->exact = request.exact() || outside;
  query->skip_refinement = request.skip_refinement();
  *fields = packed ? kDefaultFields : 0;
  if (request.fields_size() > 0) {
    *fields = 0;
    for (int i = 0; i < request.fields_size(); ++i) {
      const int f = request.fields(i);
      if (f < v1::FindNearestRequest::SITE || f > v1::FindNearestRequest::GRADIENT) {
        return Status(StatusCode::INVALID_ARGUMENT,
                      absl::StrCat("fields[", i, "] is ", f,
                                   "; it must be SITE, DISTANCE, ERROR_BOUND, EXACT, FEATURE, "
                                   "CLOSEST or GRADIENT"));
      }
      if (!packed && (Bit(static_cast<v1::FindNearestRequest::Field>(f)) & kPointFields) == 0) {
        return Status(StatusCode::INVALID_ARGUMENT,
                      absl::StrCat("fields[", i, "] is ",
                                   v1::FindNearestRequest::Field_Name(f),
                                   "; with points, whose answers are whole NearestSite messages, "
                                   "fields may name only CLOSEST and GRADIENT (send the points "
                                   "as xy, or xyz, to choose the columns of packed answers)"));
      }
      *fields |= 1u << f;
    }
  }
  query->features = !packed || (*fields & Bit(v1::FindNearestRequest::FEATURE)) != 0;
  query->closest = (*fields & (Bit(v1::FindNearestRequest::CLOSEST) |
                               Bit(v1::FindNearestRequest::GRADIENT))) != 0;
  return Status::OK;
}

template <class S>
grpc::ServerUnaryReactor* VoronoiService::StartNearest(grpc::CallbackServerContext* ctx,
                                                       const std::shared_ptr<CallScope>& scope,
                                                       const std::shared_ptr<S>& scene,
                                                       const v1::FindNearestRequest* request,
                                                       v1::FindNearestResponse* response) {
  using Job = BasicNearestJob<S>;
  typename Job::Query query;
  uint32_t fields = 0;
  const bool packed = request->points_size() == 0;
  if (auto s = ParseNearest(*request, *scene, packed, &query, &fields); !s.ok()) {
    return scope->Done(ctx, s);
  }
  auto job = Job::Make(registry_, scene, std::move(query), [ctx] { return ctx->IsCancelled(); });
  return JobReactor<Job>::Start(scope, job, [=](const Job& job) {
    response->set_version(job.version());
    Fill(job, 0, job.rows().size(), packed, fields, response);
  });
}

grpc::ServerUnaryReactor* VoronoiService::FindNearest(grpc::CallbackServerContext* ctx,
                                                      const v1::FindNearestRequest* request,
                                                      v1::FindNearestResponse* response) {
  Call call = Begin(ctx, "FindNearest", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  if (call.scene3) return StartNearest(ctx, call.scope, call.scene3, request, response);
  return StartNearest(ctx, call.scope, call.scene, request, response);
}

template <class S>
grpc::ServerWriteReactor<v1::FindNearestResponse>* VoronoiService::StartNearestStream(
    grpc::CallbackServerContext* ctx, const std::shared_ptr<CallScope>& scope,
    const std::shared_ptr<S>& scene, const v1::FindNearestRequest* request) {
  using Job = BasicNearestJob<S>;
  typename Job::Query query;
  uint32_t fields = 0;
  Status s = ParseNearest(*request, *scene, /*packed=*/true, &query, &fields);
  size_t chunk = request->chunk_size() == 0 ? 65536 : request->chunk_size();
  std::shared_ptr<Job> job;
  if (s.ok()) job = Job::Make(registry_, scene, std::move(query), [ctx] { return ctx->IsCancelled(); });
  auto* reactor = new NearestStreamReactor<Job>(scope, job, fields, chunk);
  if (!s.ok()) {
    scope->Record(s);
    reactor->Finish(s);
  } else {
    reactor->Start();
  }
  return reactor;
}

grpc::ServerWriteReactor<v1::FindNearestResponse>* VoronoiService::FindNearestStream(
    grpc::CallbackServerContext* ctx, const v1::FindNearestRequest* request) {
  Call call = Begin(ctx, "FindNearestStream", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) {
    auto* reactor = new NearestStreamReactor<NearestJob>(call.scope, nullptr, 0, 1);
    call.scope->Record(call.status);
    reactor->Finish(call.status);
    return reactor;
  }
  if (call.scene3) return StartNearestStream(ctx, call.scope, call.scene3, request);
  return StartNearestStream(ctx, call.scope, call.scene, request);
}

template <class S>
grpc::ServerUnaryReactor* VoronoiService::StartImage(const std::shared_ptr<CallScope>& scope,
                                                     grpc::CallbackServerContext* ctx,
                                                     const std::shared_ptr<S>& scene,
                                                     ImageOptions options, uint64_t min_version,
                                                     v1::RenderImageResponse* response) {
  auto version = registry_->ReadVersion(*scene, min_version);
  if (!version.ok()) return scope->Done(ctx, ToGrpc(version.status()));
  using Job = BasicImageJob<S>;
  auto job = Job::Make(registry_, scene, *version, std::move(options),
                       [ctx] { return ctx->IsCancelled(); });
  return JobReactor<Job>::Start(scope, job, [response](const Job& job) {
    const EncodedImage& image = job.image();
    response->set_image(image.bytes.data(), image.bytes.size());
    response->set_mime_type(image.mime_type);
    response->set_width_px(image.width);
    response->set_height_px(image.height);
    response->set_version(job.version());
    for (const std::string& id : image.site_ids) response->add_site_ids(id);
    ToProto(job.window(), response->mutable_window());
  });
}

grpc::ServerUnaryReactor* VoronoiService::RenderImage(grpc::CallbackServerContext* ctx,
                                                      const v1::RenderImageRequest* request,
                                                      v1::RenderImageResponse* response) {
  Call call = Begin(ctx, "RenderImage", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  ImageOptions options;
  if (call.scene3) {
    const Grid3 grid = call.scene3->settings().grid3();
    if (auto s = ToImageOptions3(*request, grid, &options); !s.ok()) return call.Finish(ctx, s);
    response->set_slice(options.slice);
    response->set_slice_z(grid.SliceZ(options.slice));
    return StartImage(call.scope, ctx, call.scene3, std::move(options), request->min_version(),
                      response);
  }
  if (request->width_px() != 0 || request->height_px() != 0) {
    return RenderImageAt(call, ctx, request, response);
  }
  if (auto s = ToImageOptions(*request, call.scene->settings().grid, &options); !s.ok()) {
    return call.Finish(ctx, s);
  }
  return StartImage(call.scope, ctx, call.scene, std::move(options), request->min_version(),
                    response);
}

}  // namespace gvd
