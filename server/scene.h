// A scene: its grid, its sites, its version counter and the latest frame rendered from them.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "render/frame.h"
#include "render/geometry.h"
#include "render/plan.h"
#include "render/scene_raster.h"
#include "render/site.h"
#include "render/site_index.h"

namespace gvd {

struct SceneSettings {
  std::string id;
  Grid grid;
  double eps = 0;        // the distance meshes' error bound, scene units (never 0)
  uint32_t cone_triangles = 0;  // for sites inside the window
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;
};

// Called exactly once: with a frame of at least the awaited version, or with the reason
// there will be none (scene deleted, render failed, call cancelled).
using FrameCallback = std::function<void(absl::StatusOr<std::shared_ptr<const Frame>>)>;

// Thread-safe. Handlers mutate sites and read frames; the render thread snapshots sites and
// publishes frames. Readers of frame() never wait for a render.
class Scene {
 public:
  // A new scene at version 1 with no sites and an empty frame.
  explicit Scene(SceneSettings settings);
  // A scene restored from the store, at its stored version.
  Scene(SceneSettings settings, uint64_t version, std::vector<Site> sites);

  // Makes a change durable before it is applied: called with the version the change brings
  // the scene to, under the scene's lock; an error cancels the change.
  using Persist = std::function<absl::Status(uint64_t new_version)>;

  const SceneSettings& settings() const { return settings_; }
  const std::string& id() const { return settings_.id; }

  // Inserts or replaces sites, atomically; returns the new version. If the scene would then
  // hold more than max_sites sites, or `persist` fails, changes nothing and says why.
  // CONTRACT: sites are valid and their ids distinct.
  absl::StatusOr<uint64_t> Upsert(std::vector<Site> sites, size_t max_sites,
                                  const Persist& persist = nullptr);
  // Removes the sites, atomically. If ids[i] is unknown, or `persist` fails, removes nothing
  // and says why (NotFound naming ids[i]). CONTRACT: ids are distinct.
  absl::StatusOr<uint64_t> Delete(const std::vector<std::string>& ids,
                                  const Persist& persist = nullptr);

  uint64_t version() const;
  size_t site_count() const;

  // Exact best sites at the current version, which it returns. In a NEAREST scene of plain
  // sites: when the latest frame is of that version and q lies in the window, the frame's
  // answer bounds the search (paper sec. 6.3: the raster's site is an upper bound) and the
  // spatial index supplies every site within it; otherwise the index alone finds the nearest.
  // Scenes with weighted, bounded or one-sided sites, and FARTHEST scenes, score every site
  // (O(sites) per point). Concurrent calls do not block each other.
  // CONTRACT: the scene has sites.
  // found = false: no site is a candidate at the point (site_id empty).
  struct ExactAnswer {
    std::string site_id;
    double distance = INFINITY;
    FeatureKind feature_kind = FeatureKind::kVertex;
    uint32_t feature_index = 0;
    bool found = false;
  };
  // `cancelled`, when given, is polled every few thousand points; once it says true the
  // answers are left incomplete and the call returns 0.
  uint64_t NearestExact(const std::vector<Vec2>& points, std::vector<ExactAnswer>* answers,
                        const std::function<bool()>& cancelled = nullptr) const;

  // The site whose geometry is nearest to q by Euclidean distance (weights, sides,
  // max_distance and the diagram do not apply: selection, paper sec. 7.2), exact, at the
  // current version; found = false when there are no sites or the nearest is farther than
  // max_distance. O(log n).
  struct Picked {
    bool found = false;
    std::string site_id;
    double distance = 0;
    FeatureKind feature_kind = FeatureKind::kVertex;
    uint32_t feature_index = 0;
    uint64_t version = 0;
  };
  Picked Pick(Vec2 q, double max_distance) const;

  // Sites whose geometry meets the window but which hold no pixel of the latest frame (paper
  // sec. 6.2): their number and the first `kHiddenIds` ids. Computed once per frame.
  static constexpr size_t kHiddenIds = 16;
  struct Hidden {
    uint64_t count = 0;
    std::vector<std::string> ids;
  };
  Hidden HiddenSites() const;

  // The clearance field of `frame` (render/plan.h), kept for the latest frame asked about so
  // that repeated plans on one frame compute it once.
  std::shared_ptr<const ClearanceField> Clearance(const std::shared_ptr<const Frame>& frame) const;

  struct SitePage {
    std::vector<Site> sites;
    std::string last_id;  // id of the last site returned, when there are more
    uint64_t version = 0;
  };
  // Up to `limit` sites with ids greater than `after`, in id order.
  SitePage ListSites(std::string_view after, size_t limit) const;

  // For the render thread: the sites changed since the last call, each once with its current
  // geometry (none if deleted), and the version they bring the scene to. With `all`, every
  // site as an upsert (for a render from scratch), and the changed set is cleared as well.
  struct Changes {
    uint64_t version = 0;
    std::vector<SiteChange> changes;
  };
  Changes TakeChanges(bool all);

  // Seconds since the latest frame was published.
  double frame_age_seconds() const;

  // The latest published frame. Lock-free for readers.
  std::shared_ptr<const Frame> frame() const { return frame_.load(); }
  // Publishes a newer frame and hands it to the waiters it satisfies.
  void Publish(std::shared_ptr<const Frame> frame);
  // Fails every waiter (the render failed, or the scene is being deleted).
  void FailWaiters(const absl::Status& status);

  // Calls `done` with a frame of version >= min_version: at once, on this thread, when the
  // latest frame is new enough; else from the thread that publishes one. Returns a token for
  // Cancel() (0 when done was called at once). CONTRACT: min_version <= version().
  uint64_t WhenRendered(uint64_t min_version, FrameCallback done);
  // If the waiter is still pending, removes it and calls it with `why`.
  void Cancel(uint64_t token, const absl::Status& why);

  void MarkDeleted() { deleted_ = true; }
  bool deleted() const { return deleted_; }

 private:
  struct Waiter {
    uint64_t min_version;
    FrameCallback done;
  };

  const SceneSettings settings_;
  std::atomic<bool> deleted_{false};
  std::atomic<std::shared_ptr<const Frame>> frame_;
  std::atomic<int64_t> published_ns_{0};  // steady_clock

  mutable std::shared_mutex mu_;  // guards everything below; shared by exact queries
  uint64_t version_ = 1;
  std::map<std::string, uint32_t, std::less<>> slot_of_;  // id -> slot, in id order
  SlotTable slots_;
  std::vector<uint32_t> free_;
  SiteIndex index_;
  size_t non_plain_ = 0;  // live sites that are not Site::plain()
  std::set<std::string> changed_;  // since the last TakeChanges
  uint64_t next_token_ = 1;
  std::map<uint64_t, Waiter> waiters_;

  mutable std::mutex hidden_mu_;  // guards the two below
  mutable const Frame* hidden_frame_ = nullptr;  // the frame `hidden_` describes
  mutable std::shared_ptr<const Frame> hidden_keep_;
  mutable Hidden hidden_;
  mutable std::shared_ptr<const Frame> clearance_frame_;  // guarded by hidden_mu_
  mutable std::shared_ptr<const ClearanceField> clearance_;
};

}  // namespace gvd
