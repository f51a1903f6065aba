#include "render/scene/scene.h"

#include <atomic>
#include <algorithm>
#include <chrono>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/scene/batch.h"
#include "render/scene/cpu_pool.h"

namespace gvd {

namespace {
int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

template <class K>
BasicScene<K>::BasicScene(SceneSettings settings, Executor executor)
    : settings_(std::move(settings)), executor_(std::move(executor)) {
  snapshot_.store(Snapshot::Empty(1));
  frame_.store(SceneFrames<K>::Empty(settings_, snapshot_.load()));
  published_ns_ = NowNs();
}

template <class K>
double BasicScene<K>::frame_age_seconds() const { return (NowNs() - published_ns_.load()) * 1e-9; }

template <class K>
BasicScene<K>::BasicScene(SceneSettings settings, uint64_t version, std::vector<Site> sites,
                          Executor executor)
    : BasicScene(std::move(settings), std::move(executor)) {
  Builder builder(snapshot_.load(), &free_slots_);
  for (Site& site : sites) builder.Put(std::move(site));
  snapshot_.store(builder.Build(version));
}

template <class K>
absl::StatusOr<uint64_t> BasicScene<K>::Write(const std::function<absl::Status(Builder&)>& edit,
                                      const Persist& persist) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  if (deleted_) return Gone();
  auto base = snapshot_.load();
  Builder builder(base, &free_slots_);
  absl::Status status = edit(builder);
  if (!status.ok()) {
    builder.Abandon();
    return status;
  }
  ChangeSet change{id(), base->version() + 1, SitesPut<Site>(builder.put()), builder.removed()};
  // A bulk change builds the next snapshot while the store makes it durable (the snapshot
  // is dropped if the store refuses); a small one builds only what the store took.
  constexpr size_t kBulk = 4096;
  std::shared_ptr<const Snapshot> next;
  if (persist && builder.put().size() + builder.removed().size() >= kBulk) {
    ParallelFor(2, 1, [&](size_t begin, size_t end) {
      for (size_t k = begin; k < end; ++k) {
        if (k == 0) {
          status = persist(change);
        } else {
          next = builder.Build(change.version);
        }
      }
    });
  } else if (persist) {
    status = persist(change);
  }
  if (!status.ok()) {
    builder.Abandon();
    return status;
  }
  return Install(builder, std::move(next), change.version);
}

template <class K>
absl::StatusOr<uint64_t> BasicScene<K>::Apply(const ChangeSet& committed) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  if (deleted_) return Gone();
  auto base = snapshot_.load();
  if (committed.base() != base->version() || committed.version <= base->version()) {
    return absl::FailedPreconditionError(
        absl::StrCat("scene \"", id(), "\" is at version ", base->version(),
                     "; a change from version ", committed.base(), " to ",
                     committed.version, " cannot follow it"));
  }
  Builder builder(base, &free_slots_);
  for (const std::string& removed : committed.removed) {
    if (!builder.Remove(removed)) {
      builder.Abandon();
      return absl::NotFoundError(absl::StrCat("\"", removed, "\" is not a site of scene \"",
                                              id(), "\" at version ", base->version()));
    }
  }
  for (const std::shared_ptr<const Site>& site : committed.template Put<Site>()) builder.Put(*site);
  return Install(builder, nullptr, committed.version);
}

template <class K>
uint64_t BasicScene<K>::Install(Builder& builder, std::shared_ptr<const Snapshot> next,
                        uint64_t version) {
  if (next == nullptr) next = builder.Build(version);
  // Freed slots are taken again only by later snapshots: this one's frames may still show
  // them until the render of the next.
  free_slots_.insert(free_slots_.end(), builder.freed().rbegin(), builder.freed().rend());
  std::vector<FrameCallback> ready;
  std::shared_ptr<const Frame> frame;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    snapshot_.store(next);
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      if (it->second.committed && it->second.min_version <= version) {
        ready.push_back(std::move(it->second.done));
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
    if (!ready.empty()) frame = frame_.load();
  }
  for (auto& done : ready) Resume(std::move(done), frame);
  return version;
}

template <class K>
absl::Status BasicScene<K>::Gone() const {
  if (reloaded_) {
    return absl::AbortedError(absl::StrCat("scene \"", id(), "\" was reloaded from the store"));
  }
  return absl::NotFoundError(absl::StrCat("scene \"", id(), "\" was deleted"));
}

template <class K>
absl::Status BasicScene<K>::Retire(const std::function<absl::Status()>& persist,
                                   bool reloaded) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  if (deleted_) return Gone();
  if (persist) {
    if (auto s = persist(); !s.ok()) return s;
  }
  reloaded_ = reloaded;
  deleted_ = true;
  Notify(nullptr, /*last=*/true);
  return absl::OkStatus();
}

template <class K>
uint64_t BasicScene<K>::Watch(FrameListener listener) {
  std::lock_guard<std::mutex> lock(listeners_mu_);
  const uint64_t token = next_listener_++;
  listeners_.emplace(token, std::make_shared<const FrameListener>(std::move(listener)));
  watched_ = true;
  return token;
}

template <class K>
void BasicScene<K>::Unwatch(uint64_t token) {
  std::lock_guard<std::mutex> calling(listeners_call_mu_);
  std::lock_guard<std::mutex> lock(listeners_mu_);
  listeners_.erase(token);
  watched_ = !listeners_.empty();
}

template <class K>
void BasicScene<K>::Notify(const std::shared_ptr<const Frame>& frame, bool last) {
  std::lock_guard<std::mutex> calling(listeners_call_mu_);
  std::vector<std::shared_ptr<const FrameListener>> listeners;
  {
    std::lock_guard<std::mutex> lock(listeners_mu_);
    listeners.reserve(listeners_.size());
    for (const auto& [token, l] : listeners_) listeners.push_back(l);
    if (last) {
      listeners_.clear();
      watched_ = false;
    }
  }
  for (const auto& l : listeners) (*l)(frame);
}

template <class K>
absl::StatusOr<uint64_t> BasicScene<K>::Upsert(std::vector<Site> sites, size_t max_sites,
                                       const Persist& persist) {
  return Write(
      [&](Builder& builder) {
        builder.Reserve(sites.size());
        for (Site& s : sites) builder.Put(std::move(s));
        if (builder.size() > max_sites) {
          return absl::ResourceExhaustedError(
              absl::StrCat("scene \"", id(), "\" would hold ", builder.size(),
                           " sites; the limit per scene is ", max_sites,
                           " (--max-sites-per-scene)"));
        }
        return absl::OkStatus();
      },
      persist);
}

template <class K>
absl::StatusOr<uint64_t> BasicScene<K>::Delete(const std::vector<std::string>& ids,
                                       const Persist& persist) {
  return Write(
      [&](Builder& builder) {
        for (size_t i = 0; i < ids.size(); ++i) {
          if (!builder.Remove(ids[i])) {
            return absl::NotFoundError(absl::StrCat("ids[", i, "] \"", ids[i],
                                                    "\" is not a site of scene \"", id(), "\""));
          }
        }
        return absl::OkStatus();
      },
      persist);
}

template <class K>
typename BasicScene<K>::Picked BasicScene<K>::Pick(Point q, double max_distance) const {
  auto snapshot = snapshot_.load();
  Picked p;
  p.version = snapshot->version();
  if (snapshot->empty()) return p;
  ExactNearest n = snapshot->index().Nearest(q);
  if (!n.found() || n.distance > max_distance) return p;
  p.site = snapshot->sites().ptr(static_cast<uint32_t>(n.index));
  const Site& site = *p.site;
  const auto f = K::Feature(q, site);
  p.found = true;
  p.distance = n.distance;
  p.feature_kind = f.kind;
  p.feature_index = f.index;
  p.closest = f.closest;
  return p;
}

template <class K>
uint64_t BasicScene<K>::NearestExact(const std::vector<Point>& points, std::vector<ExactAnswer>* answers,
                             const std::function<bool()>& cancelled, bool features) const {
  const auto snapshot = snapshot_.load();
  const auto frame = frame_.load();
  // The frame bounds the search only when it shows this very snapshot: then its ids are this
  // snapshot's slots.
  const bool fresh = frame->snapshot_ptr() == snapshot && !frame->empty();
  const auto& slots = snapshot->sites();
  const auto& index = snapshot->index();
  // With only plain sites, the nearest site is the nearest by distance: the frame and the
  // spatial index find it. With weights, max_distance or sides, the index finds the sites
  // that can beat a value found at the point. A FARTHEST diagram scores every site.
  const bool nearest = settings_.diagram == Diagram::kNearest;
  const bool plain = snapshot->plain() && nearest;
  answers->resize(points.size());
  auto answer = [&](Point q, uint32_t slot, double value) {
    const Site* site = slots.get(slot);
    const auto f = features ? K::Feature(q, *site) : typename K::Hit{};
    return ExactAnswer{site->id, value,     f.kind, f.index, f.closest,
                       true,     slot,      snapshot->CurveError(value)};
  };
  // Cancellation is checked about every million site evaluations: every 4,096 points when
  // the index answers, more often when each point scores every site.
  const size_t check_every =
      nearest ? 4096 : std::max<size_t>(1, (size_t{1} << 20) / std::max<uint32_t>(1, slots.size()));
  // Large batches are split across cores, all on this one snapshot.
  const bool done = AnswerBatch(
      points.size(), SceneFrames<K>::Order(settings_, points), check_every, cancelled,
      [&](size_t i, std::vector<uint32_t>& nearer) {
        const Point q = points[i];
        if (!plain && nearest) {
          // Weights, max_distance or sides: a value V found at q bounds the search, as a site
          // s beats it only where m_s d + a_s < V, so d < (V - least a) / least m. V comes from
          // the frame when it shows this snapshot (its answer's value is exact; "no candidate"
          // is certain), else from the site nearest by distance; where neither gives one,
          // every site is scored below.
          uint32_t best = 0;
          double value = INFINITY;
          std::optional<NearestAnswer> raster;
          if (fresh && SceneFrames<K>::Covers(settings_, q)) raster = frame->Nearest(q);
          if (raster && !raster->found) {
            (*answers)[i] = ExactAnswer{};
            return true;
          }
          if (raster) {
            best = raster->site_index;
            value = raster->distance;
          } else if (ExactNearest n = index.Nearest(q); n.found()) {
            best = static_cast<uint32_t>(n.index);
            value = K::Value(q, *slots.get(best));
          }
          if (std::isfinite(value)) {
            snapshot->Improve(q, &best, &value, &nearer);
            (*answers)[i] = answer(q, best, value);
            return true;
          }
        }
        if (!plain) {
          uint32_t best = 0;
          double value = 0;
          bool found = false;
          for (uint32_t s = 0; s < slots.size(); ++s) {
            const Site* site = slots.get(s);
            if (site == nullptr) continue;
            double v = K::Value(q, *site);
            if (std::isfinite(v) && (!found || Beats(settings_.diagram, v, value))) {
              best = s;
              value = v;
              found = true;
            }
          }
          (*answers)[i] = found ? answer(q, best, value) : ExactAnswer{};
          return true;
        }
        std::optional<NearestAnswer> raster;
        if (fresh && SceneFrames<K>::Covers(settings_, q)) raster = frame->Nearest(q);
        if (!raster) {
          ExactNearest best = index.Nearest(q);
          (*answers)[i] = answer(q, static_cast<uint32_t>(best.index), best.distance);
          return true;
        }
        // The frame's site is at exactly this distance from q: only sites the index finds
        // within that radius can be nearer.
        uint32_t best = raster->site_index;
        double distance = raster->distance;
        nearer.clear();
        index.Within(q, distance, &nearer);
        for (uint32_t s : nearer) {
          double d = K::Distance(q, *slots.get(s));
          if (d < distance) {
            best = s;
            distance = d;
          }
        }
        (*answers)[i] = answer(q, best, distance);
        return true;
      });
  if (!done) return 0;
  return snapshot->version();
}

template <class K>
typename BasicScene<K>::SitePage BasicScene<K>::ListSites(std::string_view after, size_t limit) const {
  auto snapshot = snapshot_.load();
  SitePage page;
  page.version = snapshot->version();
  bool more = false;
  snapshot->ids().ForEachAfter(after, [&](const IdMap::Entry& e) {
    if (page.sites.size() == limit) {
      more = true;
      return false;
    }
    page.sites.push_back(*snapshot->sites().get(e.slot));
    return true;
  });
  if (more && !page.sites.empty()) page.last_id = page.sites.back().id;
  return page;
}

template <class K>
void BasicScene<K>::Publish(std::shared_ptr<const Frame> frame) {
  std::vector<FrameCallback> ready;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
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
  for (auto& done : ready) Resume(std::move(done), frame);
  if (!deleted_) Notify(frame, /*last=*/false);
}

template <class K>
void BasicScene<K>::Resume(FrameCallback done, std::shared_ptr<const Frame> frame) {
  if (executor_) {
    executor_([done = std::move(done), frame = std::move(frame)] { done(frame); });
  } else {
    done(std::move(frame));
  }
}

template <class K>
void BasicScene<K>::FailWaiters(const absl::Status& status) {
  std::map<uint64_t, Waiter> failed;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    failed.swap(waiters_);
  }
  for (auto& [token, w] : failed) w.done(status);
}

template <class K>
uint64_t BasicScene<K>::waiter_mark() {
  std::lock_guard<std::mutex> lock(waiters_mu_);
  return next_token_;
}

template <class K>
void BasicScene<K>::FailWaitersBeyond(uint64_t version, uint64_t mark,
                                      const absl::Status& status) {
  std::vector<FrameCallback> failed;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    for (auto it = waiters_.begin(); it != waiters_.end() && it->first < mark;) {
      if (it->second.min_version > version) {
        failed.push_back(std::move(it->second.done));
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (auto& done : failed) done(status);
}

template <class K>
uint64_t BasicScene<K>::WhenRendered(uint64_t min_version, FrameCallback done) {
  // Fast path, without the lock: frames only get newer.
  if (auto current = frame_.load(); current->version() >= min_version) {
    done(std::move(current));
    return 0;
  }
  std::shared_ptr<const Frame> ready;
  uint64_t token;
  RenderWait render;  // made outside the lock: the first one reschedules the render threads
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    token = next_token_++;
    auto current = frame_.load();
    if (current->version() >= min_version) {
      ready = std::move(current);
    } else {
      waiters_.emplace(token, Waiter{min_version, std::move(done), false, std::move(render)});
    }
  }
  if (ready) done(std::move(ready));
  return token;
}

template <class K>
uint64_t BasicScene<K>::WhenCommitted(uint64_t min_version, FrameCallback done) {
  uint64_t token;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    token = next_token_++;
    // Install stores the snapshot under this lock: a version it installs after this check
    // finds the waiter.
    if (snapshot_.load()->version() < min_version) {
      waiters_.emplace(token, Waiter{min_version, std::move(done), true});
      return token;
    }
  }
  done(frame_.load());
  return 0;
}

template <class K>
void BasicScene<K>::Cancel(uint64_t token, const absl::Status& why) {
  FrameCallback done;
  {
    std::lock_guard<std::mutex> lock(waiters_mu_);
    auto it = waiters_.find(token);
    if (it == waiters_.end()) return;
    done = std::move(it->second.done);
    waiters_.erase(it);
  }
  done(why);
}

template class BasicScene<Kernel2>;
template class BasicScene<Kernel3>;

}  // namespace gvd
