#include "server/grpc/watch.h"

#include <optional>
#include <type_traits>

namespace gvd {

void PendingEvent::Note(const Frame& frame, bool whole) {
  if (frame.version() <= std::max(sent_, version_)) return;
  version_ = frame.version();
  sites_ = frame.site_count();
  changed_ = changed_.Union(whole ? frame.grid().all() : frame.changed());
}

void PendingEvent::Note(const Volume& volume, bool) {
  if (volume.version() <= std::max(sent_, version_)) return;
  version_ = volume.version();
  sites_ = volume.snapshot().size();
  box_changed_ = true;
}

void PendingEvent::Take(const Grid3& grid, v1::SceneEvent* event) {
  event->set_version(version_);
  event->set_site_count(sites_);
  if (box_changed_) {
    v1::Window* changed = event->mutable_changed();
    changed->set_min_x(grid.box.min_x);
    changed->set_min_y(grid.box.min_y);
    changed->set_min_z(grid.box.min_z);
    changed->set_max_x(grid.box.max_x);
    changed->set_max_y(grid.box.max_y);
    changed->set_max_z(grid.box.max_z);
  }
  sent_ = version_;
  box_changed_ = false;
}

void PendingEvent::Take(const Grid& grid, v1::SceneEvent* event) {
  event->set_version(version_);
  event->set_site_count(sites_);
  if (!changed_.empty()) {
    const Window w = grid.Area(changed_);
    v1::Window* changed = event->mutable_changed();
    changed->set_min_x(w.min_x);
    changed->set_min_y(w.min_y);
    changed->set_max_x(w.max_x);
    changed->set_max_y(w.max_y);
  }
  sent_ = version_;
  changed_ = {};
}

// One WatchScene stream. It writes one event at a time; frames published meanwhile are
// merged into the next event (the newest version, the changed parts joined). The scene's
// listener only notes frames and starts writes; the stream is finished from gRPC's threads
// (a write's completion, a cancellation) or the drain, never from the listener.
template <class S>
class WatchStream final : public grpc::ServerWriteReactor<v1::SceneEvent>, public WatchStreamBase {
 public:
  using Frame = typename S::Frame;
  WatchStream(Watches* owner, std::shared_ptr<CallScope> scope, std::shared_ptr<S> scene,
              uint64_t after)
      : owner_(owner), scope_(std::move(scope)), scene_(std::move(scene)), pending_(after) {}

  // Listens from now on, then takes the latest frame (the whole window changed, as far as
  // the stream can tell) and a deletion that came first.
  void Begin() {
    token_ = scene_->Watch([this](const std::shared_ptr<const Frame>& f) { OnFrame(f); });
    auto current = scene_->frame();
    {
      std::lock_guard<std::mutex> lock(mu_);
      pending_.Note(*current, /*whole=*/true);
    }
    if (scene_->deleted()) {
      OnFrame(nullptr);
    } else {
      std::lock_guard<std::mutex> lock(mu_);
      Next();
    }
  }

  void End(const grpc::Status& status) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (finished_ || end_) return;
    end_ = status;
    if (!writing_) FinishWith(status);
  }

  void OnWriteDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok) {
      FinishWith(grpc::Status(grpc::StatusCode::CANCELLED, "the client stopped reading"));
    } else if (end_) {
      FinishWith(*end_);
    } else if (deletion_sent_) {
      FinishWith(grpc::Status::OK);
    } else {
      Next();
    }
  }
  void OnCancel() override {
    std::lock_guard<std::mutex> lock(mu_);
    if (!writing_) FinishWith(grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled"));
  }
  void OnDone() override {
    scene_->Unwatch(token_);
    owner_->Remove(this);
    delete this;
  }

 private:
  // The listener: a newer frame, or null once the scene is deleted.
  void OnFrame(const std::shared_ptr<const Frame>& frame) {
    std::lock_guard<std::mutex> lock(mu_);
    if (finished_) return;
    if (frame == nullptr) {
      deleted_ = true;
    } else {
      pending_.Note(*frame);
    }
    Next();
  }

  // Writes the pending event, or the deletion, when no write is under way. Under mu_.
  void Next() {
    if (writing_ || finished_ || end_) return;
    event_.Clear();
    event_.set_scene_id(scene_->id());
    if (pending_.ready()) {
      if constexpr (std::is_same_v<S, Scene3>) {
        pending_.Take(scene_->settings().grid3(), &event_);
      } else {
        pending_.Take(scene_->settings().grid, &event_);
      }
    } else if (deleted_ && !deletion_sent_) {
      event_.set_version(std::max(pending_.sent(), scene_->version()));
      event_.set_deleted(true);
      deletion_sent_ = true;
    } else {
      return;
    }
    writing_ = true;
    StartWrite(&event_);
  }

  // Under mu_.
  void FinishWith(const grpc::Status& status) {
    if (finished_) return;
    finished_ = true;
    scope_->Record(status);
    Finish(status);
  }

  Watches* const owner_;
  const std::shared_ptr<CallScope> scope_;
  const std::shared_ptr<S> scene_;
  uint64_t token_ = 0;

  std::mutex mu_;  // guards everything below
  PendingEvent pending_;
  bool deleted_ = false, deletion_sent_ = false;
  bool writing_ = false, finished_ = false;
  std::optional<grpc::Status> end_;
  v1::SceneEvent event_;
};

namespace {

class RefusedWatch final : public grpc::ServerWriteReactor<v1::SceneEvent> {
 public:
  RefusedWatch(std::shared_ptr<CallScope> scope, const grpc::Status& status)
      : scope_(std::move(scope)) {
    scope_->Record(status);
    Finish(status);
  }
  void OnDone() override { delete this; }

 private:
  std::shared_ptr<CallScope> scope_;
};

}  // namespace

template <class S>
grpc::ServerWriteReactor<v1::SceneEvent>* Watches::Start(std::shared_ptr<CallScope> scope,
                                                         std::shared_ptr<S> scene,
                                                         uint64_t after) {
  auto* stream = new WatchStream<S>(this, std::move(scope), std::move(scene), after);
  grpc::Status ended;
  {
    std::lock_guard<std::mutex> lock(mu_);
    open_.insert(stream);
    if (ended_) ended = end_status_;
  }
  stream->Begin();
  if (!ended.ok()) stream->End(ended);
  return stream;
}

grpc::ServerWriteReactor<v1::SceneEvent>* Watches::Refuse(std::shared_ptr<CallScope> scope,
                                                          const grpc::Status& status) {
  return new RefusedWatch(std::move(scope), status);
}

void Watches::EndAll(const grpc::Status& status) {
  std::lock_guard<std::mutex> lock(mu_);
  ended_ = true;
  end_status_ = status;
  for (WatchStreamBase* s : open_) s->End(status);
}

void Watches::Remove(WatchStreamBase* stream) {
  std::lock_guard<std::mutex> lock(mu_);
  open_.erase(stream);
}

template grpc::ServerWriteReactor<v1::SceneEvent>* Watches::Start<Scene>(
    std::shared_ptr<CallScope>, std::shared_ptr<Scene>, uint64_t);
template grpc::ServerWriteReactor<v1::SceneEvent>* Watches::Start<Scene3>(
    std::shared_ptr<CallScope>, std::shared_ptr<Scene3>, uint64_t);

}  // namespace gvd
