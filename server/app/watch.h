// WatchScene's streams: one per watcher, fed by its scene's frame listener. Events a slow
// reader has not taken yet are merged into the next one; a stream ends when its scene is
// deleted (OK, after a last event saying so), when the caller goes, or when the server drains
// (UNAVAILABLE).
#pragma once

#include <memory>
#include <mutex>
#include <set>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/scene/scene.h"
#include "server/app/call.h"
#include "server/app/scene_handle.h"

namespace gvd {

// What a stream has yet to tell: the newest frame noted since its last event, with the
// changed parts of every frame noted since joined. Not thread-safe.
class PendingEvent {
 public:
  // For a stream of events after version `after`.
  explicit PendingEvent(uint64_t after) : sent_(after) {}

  // Notes a frame: ignored unless newer than the last event and the frames noted since.
  // `whole`: count the whole window as changed (the first frame a stream takes, as it cannot
  // tell what changed since `after`).
  void Note(const Frame& frame, bool whole = false);
  // A 3D scene's volume: the whole box counts as changed.
  void Note(const Volume& volume, bool whole = false);
  bool ready() const { return version_ > sent_; }
  // Writes what is pending into `event` (version, site count, changed window in the scene
  // units of `grid`) and starts afresh. CONTRACT: ready().
  void Take(const Grid& grid, v1::WatchSceneResponse* event);
  void Take(const Grid3& grid, v1::WatchSceneResponse* event);
  // The version of the last event taken (or `after`).
  uint64_t sent() const { return sent_; }

 private:
  uint64_t sent_;
  uint64_t version_ = 0;
  uint64_t sites_ = 0;
  PixelRect changed_;
  bool box_changed_ = false;  // a volume's
};

// A stream, as the set of open ones knows it (watch.cc's WatchStream, a template on the scene).
class WatchStreamBase {
 public:
  virtual ~WatchStreamBase() = default;
  // Ends the stream with `status` once the write under way, if any, is done.
  virtual void End(const absl::Status& status) = 0;
};

// The streams open now. Thread-safe.
class Watches {
 public:
  Watches() = default;
  Watches(const Watches&) = delete;
  Watches& operator=(const Watches&) = delete;

  // Streams the events of `scene`'s frames newer than `after` into `out`, counted in `scope`
  // until it ends; it ends when `call` is cancelled too.
  void Start(CallPtr call, std::shared_ptr<CallScope> scope, const SceneHandle& scene,
             uint64_t after, StreamWriter<v1::WatchSceneResponse>* out);
  // Ends every open stream with `status` (the drain), and every stream started from now on.
  void EndAll(const absl::Status& status);

 private:
  template <class S>
  friend class WatchStream;
  void Remove(WatchStreamBase* stream);

  std::mutex mu_;
  std::set<std::shared_ptr<WatchStreamBase>> open_;
  bool ended_ = false;
  absl::Status end_status_;
};

}  // namespace gvd
