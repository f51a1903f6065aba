#include "server/service.h"

#include "absl/strings/str_cat.h"
#include "server/convert.h"
#include "server/log.h"

namespace gvd {
namespace {

using grpc::Status;
using grpc::StatusCode;

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* ctx, const Status& status) {
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(status);
  return reactor;
}

// Answers every query point from one frame.
Status Answer(const Frame& frame, const std::vector<Vec2>& points,
              v1::FindNearestResponse* response) {
  response->set_version(frame.version());
  auto* results = response->mutable_results();
  results->Reserve(static_cast<int>(points.size()));
  for (const Vec2& q : points) {
    auto answer = frame.Nearest(q);
    if (!answer) return Status(StatusCode::INTERNAL, "frame has no site at a query point");
    v1::NearestSite* r = results->Add();
    r->set_site_id(frame.sites().get(answer->site_index)->id);
    r->set_distance(answer->distance);
    r->set_error_bound(answer->error_bound);
  }
  return Status::OK;
}

// A FindNearest call that may wait for the render thread. Shared state lets the frame
// callback and OnCancel race safely: whichever removes the waiter from the scene finishes.
class NearestReactor final : public grpc::ServerUnaryReactor {
 public:
  NearestReactor(std::shared_ptr<Scene> scene, std::vector<Vec2> points,
                 v1::FindNearestResponse* response)
      : scene_(std::move(scene)),
        points_(std::move(points)),
        response_(response),
        pending_(std::make_shared<Pending>()) {}

  // Registers the wait. After WhenRendered this object may already be finished and deleted,
  // so only locals are touched from then on.
  void Start(uint64_t min_version) {
    auto scene = scene_;
    auto pending = pending_;
    uint64_t token = scene->WhenRendered(min_version, [this](auto frame) { OnFrame(frame); });
    std::lock_guard<std::mutex> lock(pending->mu);
    pending->token = token;
    if (pending->cancelled) scene->Cancel(token, absl::CancelledError("call cancelled"));
  }

  void OnCancel() override {
    std::lock_guard<std::mutex> lock(pending_->mu);
    pending_->cancelled = true;
    if (pending_->token != 0) {
      scene_->Cancel(pending_->token, absl::DeadlineExceededError(
                                          "cancelled or past its deadline while waiting for "
                                          "the scene's min_version to be rendered"));
    }
  }

  void OnDone() override { delete this; }

 private:
  struct Pending {
    std::mutex mu;
    uint64_t token = 0;
    bool cancelled = false;
  };

  void OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame) {
    if (!frame.ok()) {
      Finish(ToGrpc(frame.status()));
    } else if ((*frame)->empty()) {
      Finish(Status(StatusCode::FAILED_PRECONDITION,
                    absl::StrCat("scene \"", scene_->id(), "\" has no sites at version ",
                                 (*frame)->version())));
    } else {
      Finish(Answer(**frame, points_, response_));
    }
  }

  std::shared_ptr<Scene> scene_;
  std::vector<Vec2> points_;
  v1::FindNearestResponse* response_;
  std::shared_ptr<Pending> pending_;
};

}  // namespace

VoronoiService::VoronoiService(RenderLoop* renderer, ServerLimits limits)
    : renderer_(renderer), limits_(limits) {}

Status VoronoiService::Lookup(const std::string& scene_id, std::shared_ptr<Scene>* scene) const {
  if (auto s = ValidateSceneId(scene_id, limits_); !s.ok()) return s;
  std::lock_guard<std::mutex> lock(mu_);
  auto it = scenes_.find(scene_id);
  if (it == scenes_.end()) {
    return Status(StatusCode::NOT_FOUND, absl::StrCat("scene \"", scene_id, "\" does not exist"));
  }
  *scene = it->second;
  return Status::OK;
}

grpc::ServerUnaryReactor* VoronoiService::CreateScene(grpc::CallbackServerContext* ctx,
                                                      const v1::CreateSceneRequest* request,
                                                      v1::Scene* response) {
  SceneSettings settings;
  if (auto s = ToSceneSettings(*request, limits_, &settings); !s.ok()) return Done(ctx, s);
  auto scene = std::make_shared<Scene>(std::move(settings));
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (scenes_.count(scene->id())) {
      return Done(ctx, Status(StatusCode::ALREADY_EXISTS,
                              absl::StrCat("scene \"", scene->id(), "\" already exists")));
    }
    if (scenes_.size() >= limits_.max_scenes) {
      return Done(ctx, Status(StatusCode::RESOURCE_EXHAUSTED,
                              absl::StrCat("the server holds ", scenes_.size(),
                                           " scenes; the limit is ", limits_.max_scenes)));
    }
    scenes_.emplace(scene->id(), scene);
  }
  ToProto(*scene, response);
  Log(LogLevel::kInfo, "scene_created",
      {{"scene", scene->id()}, {"width_px", absl::StrCat(request->width_px())},
       {"height_px", absl::StrCat(request->height_px())},
       {"max_error", FormatNumber(scene->settings().eps)}});
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::GetScene(grpc::CallbackServerContext* ctx,
                                                   const v1::GetSceneRequest* request,
                                                   v1::Scene* response) {
  std::shared_ptr<Scene> scene;
  if (auto s = Lookup(request->scene_id(), &scene); !s.ok()) return Done(ctx, s);
  ToProto(*scene, response);
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::ListScenes(grpc::CallbackServerContext* ctx,
                                                     const v1::ListScenesRequest*,
                                                     v1::ListScenesResponse* response) {
  std::vector<std::shared_ptr<Scene>> scenes;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, scene] : scenes_) scenes.push_back(scene);
  }
  for (const auto& scene : scenes) ToProto(*scene, response->add_scenes());
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::DeleteScene(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSceneRequest* request,
                                                      v1::DeleteSceneResponse*) {
  if (auto s = ValidateSceneId(request->scene_id(), limits_); !s.ok()) return Done(ctx, s);
  std::shared_ptr<Scene> scene;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = scenes_.find(request->scene_id());
    if (it == scenes_.end()) {
      return Done(ctx, Status(StatusCode::NOT_FOUND, absl::StrCat("scene \"", request->scene_id(),
                                                                  "\" does not exist")));
    }
    scene = std::move(it->second);
    scenes_.erase(it);
  }
  scene->MarkDeleted();
  scene->FailWaiters(absl::NotFoundError(absl::StrCat("scene \"", scene->id(), "\" was deleted")));
  renderer_->MarkDirty(scene);  // lets the render thread release the scene's target
  Log(LogLevel::kInfo, "scene_deleted", {{"scene", scene->id()}});
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::UpsertSites(grpc::CallbackServerContext* ctx,
                                                      const v1::UpsertSitesRequest* request,
                                                      v1::UpsertSitesResponse* response) {
  std::shared_ptr<Scene> scene;
  if (auto s = Lookup(request->scene_id(), &scene); !s.ok()) return Done(ctx, s);
  std::vector<Site> sites;
  if (auto s = ToSites(*request, limits_, &sites); !s.ok()) return Done(ctx, s);
  auto version = scene->Upsert(std::move(sites), limits_.max_sites_per_scene);
  if (!version.ok()) return Done(ctx, ToGrpc(version.status()));
  response->set_version(*version);
  renderer_->MarkDirty(scene);
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::DeleteSites(grpc::CallbackServerContext* ctx,
                                                      const v1::DeleteSitesRequest* request,
                                                      v1::DeleteSitesResponse* response) {
  std::shared_ptr<Scene> scene;
  if (auto s = Lookup(request->scene_id(), &scene); !s.ok()) return Done(ctx, s);
  std::vector<std::string> ids;
  if (auto s = ToSiteIds(*request, limits_, &ids); !s.ok()) return Done(ctx, s);
  auto version = scene->Delete(ids);
  if (!version.ok()) return Done(ctx, ToGrpc(version.status()));
  response->set_version(*version);
  renderer_->MarkDirty(scene);
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::ListSites(grpc::CallbackServerContext* ctx,
                                                    const v1::ListSitesRequest* request,
                                                    v1::ListSitesResponse* response) {
  std::shared_ptr<Scene> scene;
  if (auto s = Lookup(request->scene_id(), &scene); !s.ok()) return Done(ctx, s);
  uint32_t size = request->page_size() == 0 ? 1000 : request->page_size();
  if (size > limits_.max_page_size) {
    return Done(ctx, Status(StatusCode::INVALID_ARGUMENT,
                            absl::StrCat("page_size is ", size, "; it must be at most ",
                                         limits_.max_page_size)));
  }
  // The page token is the last id of the previous page; ids are ordered bytewise.
  Scene::SitePage page = scene->ListSites(request->page_token(), size);
  for (const Site& site : page.sites) ToProto(site, response->add_sites());
  response->set_next_page_token(page.last_id);
  response->set_version(page.version);
  return Done(ctx, Status::OK);
}

grpc::ServerUnaryReactor* VoronoiService::FindNearest(grpc::CallbackServerContext* ctx,
                                                      const v1::FindNearestRequest* request,
                                                      v1::FindNearestResponse* response) {
  std::shared_ptr<Scene> scene;
  if (auto s = Lookup(request->scene_id(), &scene); !s.ok()) return Done(ctx, s);
  std::vector<Vec2> points;
  if (auto s = ToQueryPoints(*request, scene->settings().grid.window, limits_, &points); !s.ok()) {
    return Done(ctx, s);
  }
  uint64_t version = scene->version();
  uint64_t min_version = request->min_version();
  if (min_version > version) {
    return Done(ctx, Status(StatusCode::OUT_OF_RANGE,
                            absl::StrCat("min_version ", min_version, " is ahead of scene \"",
                                         scene->id(), "\", which is at version ", version)));
  }
  // A scene that has sites but whose first render is still under way waits for it rather
  // than answering "no sites".
  if (scene->frame()->empty() && scene->site_count() > 0) min_version = version;
  auto* reactor = new NearestReactor(scene, std::move(points), response);
  reactor->Start(min_version);
  return reactor;
}

}  // namespace gvd
