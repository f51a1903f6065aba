#include "server/app/watch.h"

#include <algorithm>
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

void PendingEvent::Take(const Grid3& grid, v1::WatchSceneResponse* event) {
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

void PendingEvent::Take(const Grid& grid, v1::WatchSceneResponse* event) {
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
// listener only notes frames and starts writes; the stream is finished from the transport's
// threads (a write's completion, a cancellation) or the drain, never from the listener.
template <class S>
class WatchStream final : public WatchStreamBase,
                          public std::enable_shared_from_this<WatchStream<S>> {
 public:
  using Frame = typename S::Frame;
  WatchStream(Watches* owner, std::shared_ptr<CallScope> scope, std::shared_ptr<S> scene,
              uint64_t after, StreamWriter<v1::WatchSceneResponse>* out)
      : owner_(owner),
        scope_(std::move(scope)),
        scene_(std::move(scene)),
        out_(out),
        pending_(after) {}

  // Listens from now on, then takes the latest frame (the whole window changed, as far as
  // the stream can tell) and a deletion that came first.
  void Begin(const CallPtr& call) {
    std::weak_ptr<WatchStream> weak = this->shared_from_this();
    token_ = scene_->Watch([weak](const std::shared_ptr<const Frame>& f) {
      if (auto self = weak.lock()) self->OnFrame(f);
    });
    auto current = scene_->frame();
    {
      std::lock_guard<std::mutex> lock(mu_);
      pending_.Note(*current, /*whole=*/true);
    }
    if (scene_->deleted()) {
      OnFrame(nullptr);
    } else {
      Next();
    }
    call->OnCancel([weak] {
      if (auto self = weak.lock()) self->End(absl::CancelledError("the call was cancelled"));
    });
  }

  void End(const absl::Status& status) override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_ || end_) return;
      end_ = status;
      if (writing_) return;  // the write's completion ends it
    }
    FinishWith(status);
  }

 private:
  // The listener: a newer frame, or null once the scene is deleted.
  void OnFrame(const std::shared_ptr<const Frame>& frame) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_) return;
      if (frame == nullptr) {
        deleted_ = true;
      } else {
        pending_.Note(*frame);
      }
    }
    Next();
  }

  // A write is done: the next event, or the end.
  void OnWritten(bool ok) {
    std::optional<absl::Status> finish;
    {
      std::lock_guard<std::mutex> lock(mu_);
      writing_ = false;
      if (!ok) {
        finish = absl::CancelledError("the client stopped reading");
      } else if (end_) {
        finish = *end_;
      } else if (deletion_sent_) {
        finish = absl::OkStatus();
      }
    }
    if (finish) return FinishWith(*finish);
    Next();
  }

  // Writes the pending event, or the deletion, when no write is under way.
  void Next() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (writing_ || finished_ || end_) return;
      event_.Clear();
      event_.set_scene_id(scene_->id());
      if (pending_.ready()) {
        if constexpr (S::Kernel::kDimension == 3) {
          pending_.Take(scene_->settings().grid3(), &event_);
        } else {
          pending_.Take(scene_->settings().grid, &event_);
        }
      } else if (deleted_ && !deletion_sent_) {
        event_.set_version(std::max(pending_.sent(), scene_->version()));
        if (scene_->reloaded()) {
          event_.set_reloaded(true);
        } else {
          event_.set_deleted(true);
        }
        deletion_sent_ = true;
      } else {
        return;
      }
      writing_ = true;
    }
    // Outside the lock: a transport may call back before Write returns.
    std::weak_ptr<WatchStream> weak = this->shared_from_this();
    out_->Write(&event_, [weak](bool ok) {
      if (auto self = weak.lock()) self->OnWritten(ok);
    });
  }

  // Ends the stream, once: the transport's end, then the listener and the set let go.
  void FinishWith(const absl::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_) return;
      finished_ = true;
    }
    auto self = this->shared_from_this();  // Remove may drop the set's reference
    scope_->Record(status);
    out_->Finish(status);
    scene_->Unwatch(token_);
    owner_->Remove(this);
  }

  Watches* const owner_;
  const std::shared_ptr<CallScope> scope_;
  const std::shared_ptr<S> scene_;
  StreamWriter<v1::WatchSceneResponse>* const out_;
  uint64_t token_ = 0;

  std::mutex mu_;  // guards everything below
  PendingEvent pending_;
  bool deleted_ = false, deletion_sent_ = false;
  bool writing_ = false, finished_ = false;
  std::optional<absl::Status> end_;
  v1::WatchSceneResponse event_;  // the event being written (its writer reads it until `written`)
};

void Watches::Start(CallPtr call, std::shared_ptr<CallScope> scope, const SceneHandle& scene,
                    uint64_t after, StreamWriter<v1::WatchSceneResponse>* out) {
  scene.Visit([&](const auto& s) {
    using S = typename std::decay_t<decltype(s)>::element_type;
    auto stream = std::make_shared<WatchStream<S>>(this, std::move(scope), s, after, out);
    absl::Status ended;
    {
      std::lock_guard<std::mutex> lock(mu_);
      open_.insert(stream);
      if (ended_) ended = end_status_;
    }
    stream->Begin(call);
    if (!ended.ok()) stream->End(ended);
  });
}

void Watches::EndAll(const absl::Status& status) {
  std::set<std::shared_ptr<WatchStreamBase>> open;
  {
    std::lock_guard<std::mutex> lock(mu_);
    ended_ = true;
    end_status_ = status;
    open = open_;
  }
  for (const auto& s : open) s->End(status);
}

void Watches::Remove(WatchStreamBase* stream) {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto it = open_.begin(); it != open_.end(); ++it) {
    if (it->get() == stream) {
      open_.erase(it);
      return;
    }
  }
}

}  // namespace gvd
