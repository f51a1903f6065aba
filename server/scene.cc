#include "server/scene.h"

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace gvd {

Scene::Scene(SceneSettings settings) : settings_(std::move(settings)) {
  frame_.store(Frame::Empty(settings_.grid, 1, settings_.eps));
}

absl::StatusOr<uint64_t> Scene::Upsert(std::vector<Site> sites, size_t max_sites) {
  std::lock_guard<std::mutex> lock(mu_);
  size_t added = 0;
  for (const Site& s : sites) added += sites_.count(s.id) == 0;
  if (sites_.size() + added > max_sites) {
    return absl::ResourceExhaustedError(
        absl::StrCat("scene \"", id(), "\" would hold ", sites_.size() + added,
                     " sites; the limit per scene is ", max_sites));
  }
  for (Site& s : sites) {
    changed_.insert(s.id);
    sites_.insert_or_assign(std::move(s.id), std::move(s.geometry));
  }
  return ++version_;
}

absl::StatusOr<uint64_t> Scene::Delete(const std::vector<std::string>& ids) {
  std::lock_guard<std::mutex> lock(mu_);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (sites_.find(ids[i]) == sites_.end()) {
      return absl::NotFoundError(absl::StrCat("ids[", i, "] \"", ids[i],
                                              "\" is not a site of scene \"", id(), "\""));
    }
  }
  for (const auto& i : ids) {
    sites_.erase(i);
    changed_.insert(i);
  }
  return ++version_;
}

uint64_t Scene::version() const {
  std::lock_guard<std::mutex> lock(mu_);
  return version_;
}

size_t Scene::site_count() const {
  std::lock_guard<std::mutex> lock(mu_);
  return sites_.size();
}

Scene::SitePage Scene::ListSites(std::string_view after, size_t limit) const {
  std::lock_guard<std::mutex> lock(mu_);
  SitePage page;
  page.version = version_;
  auto it = after.empty() ? sites_.begin() : sites_.upper_bound(after);
  for (; it != sites_.end() && page.sites.size() < limit; ++it) {
    page.sites.push_back({it->first, it->second});
  }
  if (it != sites_.end() && !page.sites.empty()) page.last_id = page.sites.back().id;
  return page;
}

Scene::Changes Scene::TakeChanges(bool all) {
  std::lock_guard<std::mutex> lock(mu_);
  Changes out;
  out.version = version_;
  if (all) {
    out.changes.reserve(sites_.size());
    for (const auto& [id, geometry] : sites_) out.changes.push_back({id, geometry});
  } else {
    out.changes.reserve(changed_.size());
    for (const auto& id : changed_) {
      auto it = sites_.find(id);
      out.changes.push_back(
          {id, it == sites_.end() ? std::nullopt : std::optional<Geometry>(it->second)});
    }
  }
  changed_.clear();
  return out;
}

void Scene::Publish(std::shared_ptr<const Frame> frame) {
  std::vector<FrameCallback> ready;
  {
    std::lock_guard<std::mutex> lock(mu_);
    frame_.store(frame);
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      if (it->second.min_version <= frame->version()) {
        ready.push_back(std::move(it->second.done));
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (auto& done : ready) done(frame);
}

void Scene::FailWaiters(const absl::Status& status) {
  std::map<uint64_t, Waiter> failed;
  {
    std::lock_guard<std::mutex> lock(mu_);
    failed.swap(waiters_);
  }
  for (auto& [token, w] : failed) w.done(status);
}

uint64_t Scene::WhenRendered(uint64_t min_version, FrameCallback done) {
  std::shared_ptr<const Frame> ready;
  uint64_t token;
  {
    std::lock_guard<std::mutex> lock(mu_);
    token = next_token_++;
    auto current = frame_.load();
    if (current->version() >= min_version) {
      ready = std::move(current);
    } else {
      waiters_.emplace(token, Waiter{min_version, std::move(done)});
    }
  }
  if (ready) done(std::move(ready));
  return token;
}

void Scene::Cancel(uint64_t token, const absl::Status& why) {
  FrameCallback done;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = waiters_.find(token);
    if (it == waiters_.end()) return;
    done = std::move(it->second.done);
    waiters_.erase(it);
  }
  done(why);
}

}  // namespace gvd
