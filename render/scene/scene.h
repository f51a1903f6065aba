// A scene: its settings, the latest snapshot of its sites and the latest frame rendered
// from them. No GL, no gRPC: the server, the tests and the benchmarks share it.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <typeindex>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/scene/shared_cell.h"
#include "render/scene/settings.h"
#include "render/scene/snapshot.h"
#include "render/scene/volume.h"
#include "render/scene/change.h"
#include "render/scene/cpu_pool.h"
#include "render/kernel/grid2.h"
#include "render/kernel/kernel2.h"
#include "render/kernel/kernel3.h"
#include "render/kernel/site2.h"

namespace gvd {

// Runs a job on a thread that is not the caller's (the process's CPU pool).
using Executor = std::function<void(std::function<void()>)>;

// What a scene of a kernel's sites renders into, and what that asks of its settings: the
// plane's frames (frame.h) and space's volumes (volume.h).
template <class K>
struct SceneFrames;
template <>
struct SceneFrames<Kernel2> {
  using Frame = gvd::Frame;
  using Grid = gvd::Grid;
  static std::shared_ptr<const Frame> Empty(const SceneSettings& s,
                                            std::shared_ptr<const SiteSnapshot> sites) {
    return Frame::Empty(s.grid, s.eps, std::move(sites));
  }
  // The scene's grid, and the part of the plane it samples (its window).
  static const Grid& GridOf(const SceneSettings& s) { return s.grid; }
  static const Window& Bounds(const SceneSettings& s) { return s.grid.window; }
  // Whether the frame holds values around q (its window).
  static bool Covers(const SceneSettings& s, Vec2 q) { return s.grid.window.Contains(q); }
  // The order a batch is best answered in (OrderByTile).
  static std::vector<uint32_t> Order(const SceneSettings& s, const std::vector<Vec2>& points) {
    return OrderByTile(s.grid, points);
  }
  // What a scene's raster costs per pixel: the GL id and depth targets (8 bytes), their
  // read-back (8) and the published frame's ids and distances (8). Measured: a 4096x4096
  // scene of one site added 16 to 25 bytes per pixel to the server's resident memory.
  static constexpr uint64_t kBytesPerPixel = 24;
  static uint64_t RasterBytes(const SceneSettings& s) {
    return uint64_t{s.grid.width} * s.grid.height * kBytesPerPixel;
  }
};
template <>
struct SceneFrames<Kernel3> {
  using Frame = Volume;
  using Grid = Grid3;
  static std::shared_ptr<const Frame> Empty(const SceneSettings& s,
                                            std::shared_ptr<const SiteSnapshot3> sites) {
    return Volume::Empty(s.grid3(), s.diagram, std::move(sites));
  }
  static Grid3 GridOf(const SceneSettings& s) { return s.grid3(); }
  static Box3 Bounds(const SceneSettings& s) { return s.grid3().box; }
  static bool Covers(const SceneSettings& s, Vec3 q) { return s.grid3().box.Contains(q); }
  static std::vector<uint32_t> Order(const SceneSettings&, const std::vector<Vec3>&) { return {}; }
  // A volume's ids and values (8 bytes a voxel), and the copies of the slices a render
  // writes while the published volume is read (8 more).
  static constexpr uint64_t kBytesPerVoxel = 16;
  static uint64_t RasterBytes(const SceneSettings& s) {
    return s.grid3().voxel_count() * kBytesPerVoxel;
  }
};

// Thread-safe. Threading rules:
//  - the sites are an immutable SiteSnapshot, published in a SharedCell: readers (queries, the
//    render thread) copy the pointer and never wait for a writer's work;
//  - writers (Upsert, Delete, Retire) take the writer lock, build the next snapshot from the
//    current one, make it durable (Persist: the store's commit of the change set) and publish
//    it, so a durable commit blocks only other writers of the same scene;
//  - the render thread publishes frames, each holding the snapshot it was rendered from;
//    readers of frame() never wait for a render;
//  - waiters for a frame are resumed through the executor, never on the render thread.
//
// A template on the kernel (render/kernel/kernel2.h): Scene is the plane's, whose frames are
// Frames; Scene3 is space's, whose frames are Volumes (SceneFrames).
template <class K>
class BasicScene {
 public:
  using Kernel = K;
  using Site = typename K::Site;
  using Point = typename K::Point;
  using Snapshot = BasicSiteSnapshot<K>;
  using Builder = BasicSnapshotBuilder<K>;
  using Frame = typename SceneFrames<K>::Frame;
  // Called exactly once: with a frame of at least the awaited version, or with the reason
  // there will be none (scene deleted, render failed, call cancelled).
  using FrameCallback = std::function<void(absl::StatusOr<std::shared_ptr<const Frame>>)>;

  // A new scene at version 1 with no sites and an empty frame. Frame waiters are resumed
  // through `executor` (null: on the publishing thread).
  explicit BasicScene(SceneSettings settings, Executor executor = nullptr);
  // A scene restored from the store, at its stored version.
  BasicScene(SceneSettings settings, uint64_t version, std::vector<Site> sites,
             Executor executor = nullptr);

  // Makes a change durable before it is published (SceneStore::Commit): called under the
  // writer lock only, with the change and the version it brings the scene to; an error
  // cancels the change.
  using Persist = std::function<absl::Status(const ChangeSet& changes)>;

  const SceneSettings& settings() const { return settings_; }
  const std::string& id() const { return settings_.id; }

  // Inserts or replaces sites, atomically; returns the new version. If the scene would then
  // hold more than max_sites sites, or `persist` fails, or the scene was deleted, changes
  // nothing and says why.
  // CONTRACT: sites are valid and their ids distinct.
  absl::StatusOr<uint64_t> Upsert(std::vector<Site> sites, size_t max_sites,
                                  const Persist& persist = nullptr);
  // Removes the sites, atomically. If ids[i] is unknown, or `persist` fails, removes nothing
  // and says why (NotFound naming ids[i]). CONTRACT: ids are distinct.
  absl::StatusOr<uint64_t> Delete(const std::vector<std::string>& ids,
                                  const Persist& persist = nullptr);
  // Publishes a change that is durable already (committed by another server, say): the same
  // last step as Upsert's and Delete's, after their commit. FAILED_PRECONDITION unless it
  // follows the scene's version (ChangeSet::base) and brings it further; NOT_FOUND if it
  // removes an unknown id or the scene was deleted. Changes nothing then.
  absl::StatusOr<uint64_t> Apply(const ChangeSet& committed);

  // The latest snapshot of the sites. Never waits for a writer.
  std::shared_ptr<const Snapshot> snapshot() const { return snapshot_.load(); }
  uint64_t version() const { return snapshot()->version(); }
  size_t site_count() const { return snapshot()->size(); }

  // The bytes of a scene of these settings with no sites (SceneFrames::RasterBytes).
  static uint64_t RasterBytes(const SceneSettings& settings) {
    return SceneFrames<K>::RasterBytes(settings);
  }
  // The bytes the scene holds now: its raster and its latest sites (SiteSnapshot::bytes).
  // What the memory budget (--max-memory) charges it.
  uint64_t memory_bytes() const { return RasterBytes(settings_) + snapshot()->bytes(); }

  // Exact best sites at the current version, which it returns, all read from one snapshot.
  // In a NEAREST scene of plain sites: when the latest frame was rendered from that snapshot
  // and q lies in the window, the frame's answer bounds the search (paper sec. 6.3: the
  // raster's site is an upper bound) and the snapshot's index supplies every site within it;
  // otherwise the index alone finds the nearest.
  // With weighted, bounded or one-sided sites, the value found there (the frame's, or the
  // site nearest by distance's) bounds the search through the least weights; where neither
  // gives a finite value, and in FARTHEST scenes, every site is scored (O(sites) per point).
  // Concurrent calls do not block each other.
  // CONTRACT: the scene has sites.
  // found = false: no site is a candidate at the point (site_id empty).
  struct ExactAnswer {
    std::string site_id;
    double distance = INFINITY;
    FeatureKind feature_kind = FeatureKind::kVertex;
    uint32_t feature_index = 0;
    Point closest;  // the site's point nearest to q (FeatureHit::closest)
    bool found = false;
    uint32_t slot = 0;  // the site's slot in the answering version's table
    // The rounding of measuring curves (Snapshot::CurveError): 0 without curves.
    double error_bound = 0;
  };
  // `cancelled`, when given, is polled every few thousand points; once it says true the
  // answers are left incomplete and the call returns 0.
  // Without `features`, feature_kind, feature_index and closest are left at their defaults.
  uint64_t NearestExact(const std::vector<Point>& points, std::vector<ExactAnswer>* answers,
                        const std::function<bool()>& cancelled = nullptr,
                        bool features = true) const;

  // The site whose geometry is nearest to q by Euclidean distance (weights, sides,
  // max_distance and the diagram do not apply: selection, paper sec. 7.2), exact, at the
  // current version; found = false when there are no sites or the nearest is farther than
  // max_distance. O(log n).
  struct Picked {
    bool found = false;
    std::shared_ptr<const Site> site;  // the site picked, as stored (null when not found)
    double distance = 0;
    FeatureKind feature_kind = FeatureKind::kVertex;
    uint32_t feature_index = 0;
    Point closest;  // the site's point nearest to q
    uint64_t version = 0;
  };
  Picked Pick(Point q, double max_distance) const;

  // A value computed from `frame` by `make` (a pure function of the frame), kept for the
  // latest frame asked about, one per type T: repeated questions about one frame (its hidden
  // sites, its clearance field) compute it once. Concurrent first calls may each compute it.
  template <class T, class Make>
  std::shared_ptr<const T> Derived(const std::shared_ptr<const Frame>& frame, Make&& make) const {
    const std::type_index key(typeid(T));
    {
      std::lock_guard<std::mutex> lock(derived_mu_);
      auto it = derived_.find(key);
      if (it != derived_.end() && it->second.frame == frame) {
        return std::static_pointer_cast<const T>(it->second.value);
      }
    }
    auto value = std::make_shared<const T>(make(*frame));
    std::lock_guard<std::mutex> lock(derived_mu_);
    derived_[key] = {frame, value};
    return value;
  }

  struct SitePage {
    std::vector<Site> sites;
    std::string last_id;  // id of the last site returned, when there are more
    uint64_t version = 0;
  };
  // Up to `limit` sites with ids greater than `after`, in id order.
  SitePage ListSites(std::string_view after, size_t limit) const;

  // Seconds since the latest frame was published.
  double frame_age_seconds() const;
  // The time spent rendering the scene so far (render threads add to it): its render cost.
  void AddRenderSeconds(double seconds) { render_seconds_.fetch_add(seconds); }
  double render_seconds() const { return render_seconds_.load(); }

  // The latest published frame. Never waits for a render.
  std::shared_ptr<const Frame> frame() const { return frame_.load(); }
  // Publishes a newer frame and hands it to the waiters it satisfies (through the executor).
  void Publish(std::shared_ptr<const Frame> frame);
  // Fails every waiter (the render failed, or the scene is being deleted).
  void FailWaiters(const absl::Status& status);
  // The token the next waiter will get: those registered before have smaller ones.
  uint64_t waiter_mark();
  // Fails the waiters registered before `mark` that wait for a version above `version`
  // (a version a replica's store has not reached).
  void FailWaitersBeyond(uint64_t version, uint64_t mark, const absl::Status& status);

  // Calls `done` with a frame of version >= min_version: at once, on this thread, when the
  // latest frame is new enough; else from the thread that publishes one. Returns a token for
  // Cancel() (0 when done was called at once). CONTRACT: min_version <= version(), or
  // the version is awaited from a store other servers write (FailWaitersBeyond ends it).
  uint64_t WhenRendered(uint64_t min_version, FrameCallback done);
  // The same once the scene holds a snapshot of version >= min_version, rendered or not:
  // `done` gets the latest frame, which may be older. For a replica's reads of a version its
  // store has and it has not read yet (FailWaitersBeyond ends them like frame waiters).
  uint64_t WhenCommitted(uint64_t min_version, FrameCallback done);
  // If the waiter is still pending, removes it and calls it with `why`.
  void Cancel(uint64_t token, const absl::Status& why);

  // Live events (WatchScene): `listener` is called with every frame published from now on,
  // on the publishing thread, holding no lock of the scene, and with null once when the
  // scene is deleted (then never again). It must be quick: note the frame, schedule work.
  // The watch ends with Unwatch(token) or the deletion. Many listeners cost O(listeners) per
  // publication.
  using FrameListener = std::function<void(const std::shared_ptr<const Frame>&)>;
  uint64_t Watch(FrameListener listener);
  // After it returns, the listener is not called again (unless a call was already under
  // way on another thread, which it then waits for). CONTRACT: not from the listener.
  void Unwatch(uint64_t token);
  // Whether a listener watches the scene now (its renderer then renders each change at once).
  bool watched() const { return watched_.load(std::memory_order_relaxed); }

  // Deletes the scene: under the writer lock, runs `persist` (the store's delete) and, if it
  // succeeds, marks the scene deleted, after which every write is refused (NOT_FOUND), and
  // tells the listeners. NOT_FOUND when it was deleted already. `reloaded`: the scene is not
  // gone but replaced by another object of its id, read again from a store that went back in
  // time (listeners are told alike; reloaded() says which).
  absl::Status Retire(const std::function<absl::Status()>& persist = nullptr,
                      bool reloaded = false);
  bool deleted() const { return deleted_; }
  bool reloaded() const { return reloaded_; }

 private:
  struct Waiter {
    uint64_t min_version;
    FrameCallback done;
    bool committed = false;  // WhenCommitted's: a snapshot of min_version is enough
    std::optional<RenderWait> render;  // WhenRendered's: renders run at a caller's priority
  };
  // Hands `frame` to `done`, through the executor when there is one.
  void Resume(FrameCallback done, std::shared_ptr<const Frame> frame);

  // Builds, persists and publishes the next snapshot; `edit` fills the builder and may
  // refuse. Takes the writer lock.
  absl::StatusOr<uint64_t> Write(const std::function<absl::Status(Builder&)>& edit,
                                 const Persist& persist);
  // Publishes the builder's snapshot at `version` (built already when `next` is given) and
  // takes back the slots it freed: where every write ends. Under the writer lock.
  uint64_t Install(Builder& builder, std::shared_ptr<const Snapshot> next, uint64_t version);
  absl::Status Gone() const;  // NOT_FOUND: the scene was deleted (ABORTED: reloaded)

  const SceneSettings settings_;
  const Executor executor_;
  std::atomic<bool> deleted_{false};
  std::atomic<bool> reloaded_{false};  // set before deleted_
  SharedCell<const Snapshot> snapshot_;
  SharedCell<const Frame> frame_;
  std::atomic<int64_t> published_ns_{0};  // steady_clock
  std::atomic<double> render_seconds_{0};

  std::mutex writer_mu_;  // held by one writer from building a snapshot to publishing it
  std::vector<uint32_t> free_slots_;  // slots free in the latest snapshot; guarded by writer_mu_

  std::mutex waiters_mu_;  // guards the two below
  uint64_t next_token_ = 1;
  std::map<uint64_t, Waiter> waiters_;

  // Listeners are called under listeners_call_mu_ (so that Unwatch can wait for a call under
  // way), never under listeners_mu_, which guards the map.
  std::mutex listeners_call_mu_;
  std::mutex listeners_mu_;
  uint64_t next_listener_ = 1;
  std::map<uint64_t, std::shared_ptr<const FrameListener>> listeners_;
  std::atomic<bool> watched_{false};  // !listeners_.empty(), set under listeners_mu_
  // Calls every listener with `frame` (null: the scene is gone, and the listeners with it).
  void Notify(const std::shared_ptr<const Frame>& frame, bool last);

  struct DerivedValue {
    std::shared_ptr<const Frame> frame;  // keeps the frame's address from being reused
    std::shared_ptr<const void> value;
  };
  mutable std::mutex derived_mu_;  // guards derived_
  mutable std::map<std::type_index, DerivedValue> derived_;
};

// The plane's scenes and space's, instantiated in scene.cc.
extern template class BasicScene<Kernel2>;
using Scene = BasicScene<Kernel2>;
using FrameCallback = Scene::FrameCallback;
extern template class BasicScene<Kernel3>;
using Scene3 = BasicScene<Kernel3>;
// The scene that holds sites of type SiteT: Scene for Site, Scene3 for Site3.
template <class SiteT>
using SceneOfSites = std::conditional_t<std::is_same_v<SiteT, Site3>, Scene3, Scene>;

}  // namespace gvd
