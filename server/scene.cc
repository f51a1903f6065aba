#include "server/scene.h"

#include <atomic>
#include <algorithm>
#include <chrono>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/analysis.h"
#include "render/exact.h"
#include "render/parallel.h"

namespace gvd {

namespace {
int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

Scene::Scene(SceneSettings settings) : settings_(std::move(settings)) {
  frame_.store(Frame::Empty(settings_.grid, 1, settings_.eps));
  published_ns_ = NowNs();
}

double Scene::frame_age_seconds() const { return (NowNs() - published_ns_.load()) * 1e-9; }

Scene::Scene(SceneSettings settings, uint64_t version, std::vector<Site> sites)
    : Scene(std::move(settings)) {
  (void)Upsert(std::move(sites), SIZE_MAX);
  std::unique_lock<std::shared_mutex> lock(mu_);
  version_ = version;
}

absl::StatusOr<uint64_t> Scene::Upsert(std::vector<Site> sites, size_t max_sites,
                                       const Persist& persist) {
  std::unique_lock<std::shared_mutex> lock(mu_);
  size_t added = 0;
  for (const Site& s : sites) added += slot_of_.count(s.id) == 0;
  if (slot_of_.size() + added > max_sites) {
    return absl::ResourceExhaustedError(
        absl::StrCat("scene \"", id(), "\" would hold ", slot_of_.size() + added,
                     " sites; the limit per scene is ", max_sites, " (--max-sites-per-scene)"));
  }
  if (persist) {
    if (auto s = persist(version_ + 1); !s.ok()) return s;
  }
  for (Site& s : sites) {
    changed_.insert(s.id);
    auto it = slot_of_.find(s.id);
    uint32_t slot;
    if (it != slot_of_.end()) {
      slot = it->second;
      index_.Remove(slot, slots_.get(slot)->geometry);
      non_plain_ -= !slots_.get(slot)->plain();
    } else {
      if (!free_.empty()) {
        slot = free_.back();
        free_.pop_back();
      } else {
        slot = slots_.size();
      }
      slot_of_.emplace(s.id, slot);
    }
    index_.Insert(slot, s.geometry);
    non_plain_ += !s.plain();
    slots_.Set(slot, std::move(s));
  }
  return ++version_;
}

absl::StatusOr<uint64_t> Scene::Delete(const std::vector<std::string>& ids,
                                       const Persist& persist) {
  std::unique_lock<std::shared_mutex> lock(mu_);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (slot_of_.find(ids[i]) == slot_of_.end()) {
      return absl::NotFoundError(absl::StrCat("ids[", i, "] \"", ids[i],
                                              "\" is not a site of scene \"", id(), "\""));
    }
  }
  if (persist) {
    if (auto s = persist(version_ + 1); !s.ok()) return s;
  }
  for (const auto& i : ids) {
    auto it = slot_of_.find(i);
    uint32_t slot = it->second;
    index_.Remove(slot, slots_.get(slot)->geometry);
    non_plain_ -= !slots_.get(slot)->plain();
    slots_.Set(slot, std::nullopt);
    free_.push_back(slot);
    slot_of_.erase(it);
    changed_.insert(i);
  }
  return ++version_;
}

uint64_t Scene::version() const {
  std::shared_lock<std::shared_mutex> lock(mu_);
  return version_;
}

size_t Scene::site_count() const {
  std::shared_lock<std::shared_mutex> lock(mu_);
  return slot_of_.size();
}

Scene::Picked Scene::Pick(Vec2 q, double max_distance) const {
  std::shared_lock<std::shared_mutex> lock(mu_);
  Picked p;
  p.version = version_;
  if (slot_of_.empty()) return p;
  ExactNearest n = index_.Nearest(q, slots_);
  if (!n.found() || n.distance > max_distance) return p;
  const Site& site = *slots_.get(static_cast<uint32_t>(n.index));
  FeatureHit f = NearestFeature(q, site.geometry);
  p.found = true;
  p.site_id = site.id;
  p.distance = n.distance;
  p.feature_kind = f.kind;
  p.feature_index = f.index;
  return p;
}

Scene::Hidden Scene::HiddenSites() const {
  auto frame = frame_.load();
  std::lock_guard<std::mutex> lock(hidden_mu_);
  if (hidden_frame_ != frame.get()) {
    hidden_ = {};
    if (!frame->empty()) {
      std::vector<uint32_t> slots =
          gvd::HiddenSites(IdsOf(*frame, frame->grid().all()), frame->sites());
      hidden_.count = slots.size();
      for (size_t k = 0; k < slots.size() && k < kHiddenIds; ++k) {
        hidden_.ids.push_back(frame->sites().get(slots[k])->id);
      }
    }
    hidden_frame_ = frame.get();
    hidden_keep_ = frame;  // keeps the address from being reused by another frame
  }
  return hidden_;
}

std::shared_ptr<const ClearanceField> Scene::Clearance(
    const std::shared_ptr<const Frame>& frame) const {
  {
    std::lock_guard<std::mutex> lock(hidden_mu_);
    if (clearance_frame_ == frame) return clearance_;
  }
  auto field = std::make_shared<const ClearanceField>(MakeClearanceField(*frame));
  std::lock_guard<std::mutex> lock(hidden_mu_);
  clearance_frame_ = frame;
  clearance_ = field;
  return field;
}

uint64_t Scene::NearestExact(const std::vector<Vec2>& points, std::vector<ExactAnswer>* answers,
                             const std::function<bool()>& cancelled) const {
  std::atomic<bool> stop{false};
  std::shared_lock<std::shared_mutex> lock(mu_);
  auto frame = frame_.load();
  const bool fresh = frame->version() == version_ && !frame->empty();
  const Window& window = settings_.grid.window;
  // With only plain sites, the nearest site is the nearest by distance: the frame and the
  // spatial index find it. Otherwise (weights, max_distance, sides, FARTHEST) every site is
  // scored.
  const bool plain = non_plain_ == 0 && settings_.diagram == Diagram::kNearest;
  answers->resize(points.size());
  auto answer = [&](Vec2 q, uint32_t slot, double value) {
    const Site* site = slots_.get(slot);
    FeatureHit f = NearestFeature(q, site->geometry);
    return ExactAnswer{site->id, value, f.kind, f.index, true};
  };
  // Cancellation is checked about every million site evaluations: every 4,096 points when
  // the index answers, more often when each point scores every site.
  const size_t check_every =
      plain ? 4096 : std::max<size_t>(1, (size_t{1} << 20) / std::max<uint32_t>(1, slots_.size()));
  // Large batches are split across cores, all under this one shared lock (one version).
  ParallelFor(points.size(), 8192, [&](size_t begin, size_t end) {
    std::vector<uint32_t> nearer;
    for (size_t i = begin; i < end; ++i) {
      if (i % check_every == 0 && cancelled && (stop || cancelled())) {
        stop = true;
        return;
      }
      const Vec2 q = points[i];
      if (!plain) {
        uint32_t best = 0;
        double value = 0;
        bool found = false;
        for (uint32_t s = 0; s < slots_.size(); ++s) {
          const Site* site = slots_.get(s);
          if (site == nullptr) continue;
          double v = SiteValue(q, *site);
          if (std::isfinite(v) && (!found || Beats(settings_.diagram, v, value))) {
            best = s;
            value = v;
            found = true;
          }
        }
        (*answers)[i] = found ? answer(q, best, value) : ExactAnswer{};
        continue;
      }
      std::optional<NearestAnswer> raster;
      if (fresh && window.Contains(q)) raster = frame->Nearest(q);
      if (!raster) {
        ExactNearest best = index_.Nearest(q, slots_);
        (*answers)[i] = answer(q, static_cast<uint32_t>(best.index), best.distance);
        continue;
      }
      // The frame's site exists at this version, at exactly this distance from q (its slots
      // are the render thread's, so it is carried by id): only sites the index finds within
      // that radius can be nearer.
      uint32_t best = slot_of_.find(frame->sites().get(raster->site_index)->id)->second;
      double distance = raster->distance;
      nearer.clear();
      index_.Within(q, distance, &nearer);
      for (uint32_t s : nearer) {
        double d = ExactDistance(q, slots_.get(s)->geometry);
        if (d < distance) {
          best = s;
          distance = d;
        }
      }
      (*answers)[i] = answer(q, best, distance);
    }
  });
  if (stop) return 0;
  return version_;
}

Scene::SitePage Scene::ListSites(std::string_view after, size_t limit) const {
  std::shared_lock<std::shared_mutex> lock(mu_);
  SitePage page;
  page.version = version_;
  auto it = after.empty() ? slot_of_.begin() : slot_of_.upper_bound(after);
  for (; it != slot_of_.end() && page.sites.size() < limit; ++it) {
    page.sites.push_back(*slots_.get(it->second));
  }
  if (it != slot_of_.end() && !page.sites.empty()) page.last_id = page.sites.back().id;
  return page;
}

Scene::Changes Scene::TakeChanges(bool all) {
  std::unique_lock<std::shared_mutex> lock(mu_);
  Changes out;
  out.version = version_;
  if (all) {
    out.changes.reserve(slot_of_.size());
    for (const auto& [id, slot] : slot_of_) out.changes.push_back({id, *slots_.get(slot)});
  } else {
    out.changes.reserve(changed_.size());
    for (const auto& id : changed_) {
      auto it = slot_of_.find(id);
      out.changes.push_back({id, it == slot_of_.end()
                                     ? std::nullopt
                                     : std::optional<Site>(*slots_.get(it->second))});
    }
  }
  changed_.clear();
  return out;
}

void Scene::Publish(std::shared_ptr<const Frame> frame) {
  std::vector<FrameCallback> ready;
  {
    std::unique_lock<std::shared_mutex> lock(mu_);
    frame_.store(frame);
    published_ns_ = NowNs();
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
    std::unique_lock<std::shared_mutex> lock(mu_);
    failed.swap(waiters_);
  }
  for (auto& [token, w] : failed) w.done(status);
}

uint64_t Scene::WhenRendered(uint64_t min_version, FrameCallback done) {
  // Fast path, without the lock: frames only get newer.
  if (auto current = frame_.load(); current->version() >= min_version) {
    done(std::move(current));
    return 0;
  }
  std::shared_ptr<const Frame> ready;
  uint64_t token;
  {
    std::unique_lock<std::shared_mutex> lock(mu_);
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
    std::unique_lock<std::shared_mutex> lock(mu_);
    auto it = waiters_.find(token);
    if (it == waiters_.end()) return;
    done = std::move(it->second.done);
    waiters_.erase(it);
  }
  done(why);
}

}  // namespace gvd
