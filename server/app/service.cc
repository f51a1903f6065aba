#include "server/app/service.h"

#include <thread>

#include "absl/strings/str_cat.h"
#include "render/analysis/analysis.h"
#include "server/app/convert/common.h"
#include "server/app/convert/scenes.h"
#include "server/app/convert/sites.h"

namespace gvd {

Service::Service(SceneRegistry* registry, const TokenAuth* auth, Metrics* metrics)
    : registry_(registry), limits_(registry->limits()), auth_(auth), calls_(metrics) {}

int Service::Drain(std::chrono::milliseconds grace) {
  draining_ = true;
  watches_.EndAll(absl::UnavailableError("the server is shutting down"));
  auto deadline = std::chrono::steady_clock::now() + grace;
  while (calls_.in_flight > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return calls_.in_flight;
}

Service::Begun Service::Begin(const Call& call, const char* method, Access access,
                              const std::string* scene_id) {
  Begun begun;
  begun.scope = std::make_shared<CallScope>(&calls_, method);
  if (draining_) {
    begun.status = absl::UnavailableError("the server is shutting down");
  } else if (!registry_->loaded()) {
    begun.status = absl::UnavailableError("the server is loading its store; retry shortly");
  } else if (auth_ != nullptr) {
    begun.status = auth_->Check(call.authorization(), access == Access::kWrite);
  }
  if (begun.status.ok() && scene_id != nullptr) {
    begun.status = ValidateSceneId(*scene_id, limits_);
    if (begun.status.ok()) {
      auto scene = registry_->Find(*scene_id);
      if (scene.ok()) {
        begun.scene = *scene;
      } else {
        begun.status = scene.status();
      }
    }
  }
  return begun;
}

Done Service::Ending(std::shared_ptr<CallScope> scope, Done done) {
  return [scope = std::move(scope), done = std::move(done)](const absl::Status& s) {
    scope->Record(s);
    done(s);
  };
}

void Service::OnLane(CpuPool::Lane& lane, const char* limit, std::function<absl::Status()> work,
                     Done done) {
  auto shared = std::make_shared<Done>(std::move(done));
  const bool queued = lane.Submit([shared, work = std::move(work)] { (*shared)(work()); });
  if (!queued) {
    (*shared)(absl::ResourceExhaustedError(
        absl::StrCat(lane.max_queued(), " calls already wait for their turn (", limit, ")")));
  }
}

void Service::Write(size_t bytes, std::function<absl::Status()> work, Done done) {
  if (bytes <= kWriteHereBytes && registry_->local_store()) {
    absl::Status status;
    if (registry_->commits().RunHereIfIdle([&] { status = work(); })) return done(status);
  }
  OnLane(registry_->commits(), "--max-queued-writes", std::move(work), std::move(done));
}

void Service::CreateScene(CallPtr call, const v1::CreateSceneRequest& request,
                          v1::CreateSceneResponse* response, Done done) {
  Begun begun = Begin(*call, "CreateScene", Access::kWrite);
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  SceneSettings settings;
  if (auto s = ToSceneSettings(request, limits_, &settings); !s.ok()) return done(s);
  OnLane(
      registry_->commits(), "--max-queued-writes",
      [this, settings = std::move(settings), response]() mutable -> absl::Status {
        auto scene = registry_->CreateScene(std::move(settings));
        if (!scene.ok()) return scene.status();
        ToProto(*scene, response->mutable_scene());
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::GetScene(CallPtr call, const v1::GetSceneRequest& request,
                       v1::GetSceneResponse* response, Done done) {
  Begun begun = Begin(*call, "GetScene", Access::kRead);
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  if (auto s = ValidateSceneId(request.scene_id(), limits_); !s.ok()) return done(s);
  auto entry = registry_->Describe(request.scene_id());
  if (!entry.ok()) return done(entry.status());
  v1::Scene* out = response->mutable_scene();
  if (entry->unloaded) {
    ToProto(*entry->unloaded, out);
    return done(absl::OkStatus());
  }
  ToProto(*entry->scene, out);
  ToProto(registry_->Lag(request.scene_id()), out);
  auto plane = entry->scene->As<Scene>();
  if (!plane.ok()) return done(absl::OkStatus());  // a 3D scene has no hidden sites to count
  // Sites that meet the window but hold no pixel of the latest frame (paper sec. 6.2): their
  // number and the first kHiddenIds ids, computed once per frame on the CPU pool (a scan of
  // the frame's pixels).
  OnLane(
      registry_->answers(), "",
      [scene = *plane, out] {
        constexpr size_t kHiddenIds = 16;
        const std::shared_ptr<const Frame> frame = scene->frame();
        auto hidden = scene->Derived<std::vector<uint32_t>>(frame, [](const Frame& frame) {
          if (frame.empty()) return std::vector<uint32_t>();
          return HiddenSites(IdsOf(frame, frame.grid().all()), frame.sites());
        });
        out->set_hidden_site_count(hidden->size());
        for (size_t k = 0; k < hidden->size() && k < kHiddenIds; ++k) {
          out->add_hidden_site_ids(frame->sites().get((*hidden)[k])->id);
        }
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::ListScenes(CallPtr call, const v1::ListScenesRequest& request,
                         v1::ListScenesResponse* response, Done done) {
  Begun begun = Begin(*call, "ListScenes", Access::kRead);
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  const uint32_t size = request.page_size() == 0 ? 1000 : request.page_size();
  if (size > limits_.max_page_size) {
    return done(Invalid(absl::StrCat("page_size is ", size, "; it must be at most ",
                                     limits_.max_page_size)));
  }
  // The page token is the last id of the previous page; ids are ordered bytewise.
  for (const SceneEntry& entry : registry_->List()) {
    if (entry.id() <= request.page_token()) continue;
    if (response->scenes_size() == static_cast<int>(size)) {
      response->set_next_page_token(response->scenes(response->scenes_size() - 1).scene_id());
      break;
    }
    v1::Scene* scene = response->add_scenes();
    if (entry.unloaded) {
      ToProto(*entry.unloaded, scene);
    } else {
      ToProto(*entry.scene, scene);
      ToProto(registry_->Lag(entry.id()), scene);
    }
  }
  done(absl::OkStatus());
}

void Service::DeleteScene(CallPtr call, const v1::DeleteSceneRequest& request,
                          v1::DeleteSceneResponse*, Done done) {
  Begun begun = Begin(*call, "DeleteScene", Access::kWrite);
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  if (auto s = ValidateSceneId(request.scene_id(), limits_); !s.ok()) return done(s);
  OnLane(
      registry_->commits(), "--max-queued-writes",
      [this, id = request.scene_id()] { return registry_->DeleteScene(id); }, std::move(done));
}

void Service::WatchScene(CallPtr call, const v1::WatchSceneRequest& request,
                         StreamWriter<v1::WatchSceneResponse>* stream) {
  Begun begun = Begin(*call, "WatchScene", Access::kRead, &request.scene_id());
  if (!begun.status.ok()) {
    begun.scope->Record(begun.status);
    return stream->Finish(begun.status);
  }
  watches_.Start(std::move(call), begun.scope, *begun.scene, request.after_version(), stream);
}

void Service::UpsertSites(CallPtr call, const v1::UpsertSitesRequest& request,
                          v1::UpsertSitesResponse* response, Done done) {
  Begun begun = Begin(*call, "UpsertSites", Access::kWrite, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  Durability durability;
  if (auto s = ToDurability(request.durability(), &durability); !s.ok()) return done(s);
  begun.scene->Visit([&](const auto& scene) {
    std::vector<typename std::decay_t<decltype(*scene)>::Site> sites;
    if (auto s = ToSites(request, limits_, &sites); !s.ok()) return done(s);
    Write(
        request.ByteSizeLong(),
        [this, id = request.scene_id(), sites = std::move(sites), durability,
         response]() mutable -> absl::Status {
          auto version = registry_->UpsertSites(id, std::move(sites), durability);
          if (!version.ok()) return version.status();
          response->set_version(*version);
          return absl::OkStatus();
        },
        std::move(done));
  });
}

void Service::DeleteSites(CallPtr call, const v1::DeleteSitesRequest& request,
                          v1::DeleteSitesResponse* response, Done done) {
  Begun begun = Begin(*call, "DeleteSites", Access::kWrite, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  std::vector<std::string> ids;
  if (auto s = ToSiteIds(request, limits_, &ids); !s.ok()) return done(s);
  Durability durability;
  if (auto s = ToDurability(request.durability(), &durability); !s.ok()) return done(s);
  Write(
      request.ByteSizeLong(),
      [this, id = request.scene_id(), ids = std::move(ids), durability,
       response]() -> absl::Status {
        auto version = registry_->DeleteSites(id, ids, durability);
        if (!version.ok()) return version.status();
        response->set_version(*version);
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::ListSites(CallPtr call, const v1::ListSitesRequest& request,
                        v1::ListSitesResponse* response, Done done) {
  Begun begun = Begin(*call, "ListSites", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  const uint32_t size = request.page_size() == 0 ? 1000 : request.page_size();
  if (size > limits_.max_page_size) {
    return done(Invalid(
        absl::StrCat("page_size is ", size, "; it must be at most ", limits_.max_page_size)));
  }
  // The page token is the last id of the previous page; ids are ordered bytewise.
  begun.scene->Visit([&](const auto& scene) {
    auto page = scene->ListSites(request.page_token(), size);
    for (const auto& site : page.sites) ToProto(site, response->add_sites());
    response->set_next_page_token(page.last_id);
    response->set_version(page.version);
  });
  done(absl::OkStatus());
}

}  // namespace gvd
