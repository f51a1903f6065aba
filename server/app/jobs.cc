#include "server/app/jobs.h"

#include <atomic>
#include <cmath>
#include <thread>
#include <utility>
#include <variant>

#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/scene/batch.h"

namespace gvd {

template <class S>
BasicFrameJob<S>::BasicFrameJob(SceneRegistry* registry, std::shared_ptr<S> scene,
                                uint64_t min_version, std::function<bool()> cancelled)
    : registry_(registry), scene_(std::move(scene)), min_version_(min_version),
      cancelled_fn_(std::move(cancelled)) {}

template <class S>
void BasicFrameJob<S>::Start(Done done) {
  auto self = this->shared_from_this();  // Finish may release the job's last other owner
  done_ = std::move(done);
  Begin();
}

template <class S>
void BasicFrameJob<S>::WaitForFrame() {
  auto self = this->shared_from_this();
  const std::thread::id caller = std::this_thread::get_id();
  uint64_t token = scene_->WhenRendered(min_version_, [self, caller](auto frame) {
    self->OnFrame(frame, std::this_thread::get_id() == caller);
  });
  std::lock_guard<std::mutex> lock(mu_);
  token_ = token;
  if (cancelled_) scene_->Cancel(token, absl::CancelledError("the call was cancelled"));
}

template <class S>
void BasicFrameJob<S>::Cancel() {
  std::lock_guard<std::mutex> lock(mu_);
  cancelled_ = true;
  if (token_ != 0) {
    scene_->Cancel(token_, absl::DeadlineExceededError(
                               "cancelled or past its deadline while waiting for the scene's "
                               "min_version to be rendered"));
  }
}

template <class S>
void BasicFrameJob<S>::OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame,
                       bool on_caller) {
  if (!frame.ok()) {
    Finish(frame.status());
    return;
  }
  if ((*frame)->empty()) {
    Finish(absl::FailedPreconditionError(absl::StrCat(
        "scene \"", scene_->id(), "\" has no sites at version ", (*frame)->version())));
    return;
  }
  version_ = (*frame)->version();
  Run(*frame, on_caller);
}

template <class S>
void BasicFrameJob<S>::Finish(const absl::Status& status) {
  auto self = this->shared_from_this();
  Done done = std::move(done_);
  done(status);
}

// ---- NearestJob ----

template <class S>
BasicNearestJob<S>::BasicNearestJob(SceneRegistry* registry, std::shared_ptr<S> scene,
                                    Query query, std::function<bool()> cancelled)
    : BasicFrameJob<S>(registry, std::move(scene), query.min_version, std::move(cancelled)),
      query_(std::move(query)) {}

template <class S>
std::shared_ptr<BasicNearestJob<S>> BasicNearestJob<S>::Make(SceneRegistry* registry,
                                                             std::shared_ptr<S> scene, Query query,
                                                             std::function<bool()> cancelled) {
  return std::shared_ptr<BasicNearestJob>(
      new BasicNearestJob(registry, std::move(scene), std::move(query), std::move(cancelled)));
}

template <class S>
void BasicNearestJob<S>::Begin() {
  // Exact answers come from the latest version, once it has reached min_version: a replica
  // behind it waits for the log (its frame waiters end when the store has it, or fail when
  // the store has not reached it either).
  if (!query_.exact || this->scene_->version() < this->min_version_) {
    this->WaitForFrame();
    return;
  }
  BeginExact();
}

template <class S>
void BasicNearestJob<S>::BeginExact() {
  const auto snapshot = this->scene_->snapshot();
  if (snapshot->empty()) {
    this->Finish(absl::FailedPreconditionError(absl::StrCat(
        "scene \"", this->scene_->id(), "\" has no sites at version ", snapshot->version())));
    return;
  }
  // Exact answers cost O(log n) each in a NEAREST scene of plain sites; with weights, sides
  // or max_distance, or in a FARTHEST scene, one may score every site.
  const bool cheap =
      snapshot->plain() && this->scene_->settings().diagram == Diagram::kNearest;
  if (cheap && query_.points.size() <= kInlineExactPoints) {
    AnswerExact();
    return;
  }
  auto self = std::static_pointer_cast<BasicNearestJob>(this->shared_from_this());
  this->registry_->answers().Submit([self] { self->AnswerExact(); });
}

template <class S>
void BasicNearestJob<S>::AnswerExact() {
  this->version_ = this->scene_->NearestExact(query_.points, &exact_answers_, this->cancelled_fn_,
                                  query_.features || query_.closest);
  if (this->version_ == 0) {
    this->Finish(absl::CancelledError("the call was cancelled"));
    return;
  }
  rows_.reserve(exact_answers_.size());
  for (const auto& a : exact_answers_) {
    rows_.push_back({a.found ? &a.site_id : nullptr, a.slot, a.distance, 0, true,
                     a.feature_kind, a.feature_index});
    if (query_.closest) closest_.push_back(a.found ? a.closest : Point(NAN));
  }
  this->Finish(absl::OkStatus());
}

template <class S>
void BasicNearestJob<S>::Run(std::shared_ptr<const Frame> frame, bool on_caller) {
  if (query_.exact) {
    BeginExact();
    return;
  }
  if (on_caller && query_.points.size() > kInlinePoints) {
    auto self = std::static_pointer_cast<BasicNearestJob>(this->shared_from_this());
    this->registry_->answers().Submit([self, frame] { self->AnswerFrom(frame); });
    return;
  }
  AnswerFrom(frame);
}

template <class S>
void BasicNearestJob<S>::AnswerFrom(const std::shared_ptr<const Frame>& frame) {
  frame_ = frame;
  rows_.resize(query_.points.size());
  if (query_.closest) closest_.resize(query_.points.size());
  std::atomic<bool> missing{false};
  const bool answered = AnswerBatch(
      query_.points.size(), SceneFrames<typename S::Kernel>::Order(this->scene_->settings(), query_.points),
      4096, this->cancelled_fn_,
      [&](size_t i, std::vector<uint32_t>&) {
        using K = typename S::Kernel;
        const Point q = query_.points[i];
        // The answer's nearest feature comes with it (a mesh's search made once).
        const bool want_feature = query_.features || query_.closest;
        typename K::Hit f;
        auto a = want_feature ? frame_->Nearest(q, &f) : frame_->Nearest(q);
        if (!a) {
          missing = true;
          return false;
        }
        bool have_feature = want_feature && a->found;
        if (!query_.skip_refinement && a->ambiguous()) {
          const uint32_t before = a->site_index;
          a = frame_->Refine(q, *a);
          have_feature = have_feature && a->site_index == before;
        }
        if (!a->found) {
          rows_[i] = {nullptr, 0, INFINITY, 0, true, FeatureKind::kVertex, 0};
          if (query_.closest) closest_[i] = Point(NAN);
          return true;
        }
        // A point's feature is itself (vertex 0); a plain point's comes from the slot table's
        // column, without reaching the site (a cache miss an answer in a large scene).
        const auto& slots = frame_->sites();
        const typename S::Site* site = slots.get(a->site_index);
        if (const Point plain = slots.point(a->site_index); !std::isnan(plain.x)) {
          f = {};
          f.closest = plain;
        } else if (const auto point = K::PointOf(*site)) {
          f = {};
          f.closest = *point;
        } else if (want_feature && !have_feature) {
          f = K::Feature(q, *site);
        }
        rows_[i] = {&site->id, a->site_index, a->distance, a->error_bound,
                    a->error_bound == 0, f.kind, f.index};
        if (query_.closest) closest_[i] = f.closest;
        return true;
      });
  if (missing) {
    this->Finish(absl::InternalError("frame has no site at a query point"));
  } else if (!answered) {
    this->Finish(absl::CancelledError("the call was cancelled"));
  } else {
    this->Finish(absl::OkStatus());
  }
}

// ---- ImageJob ----

template <class S>
BasicImageJob<S>::BasicImageJob(SceneRegistry* registry, std::shared_ptr<S> scene,
                                uint64_t min_version, ImageOptions options,
                                std::function<bool()> cancelled)
    : BasicFrameJob<S>(registry, std::move(scene), min_version, std::move(cancelled)),
      options_(std::move(options)) {}

template <class S>
std::shared_ptr<BasicImageJob<S>> BasicImageJob<S>::Make(SceneRegistry* registry,
                                                         std::shared_ptr<S> scene,
                                                         uint64_t min_version, ImageOptions options,
                                                         std::function<bool()> cancelled) {
  return std::shared_ptr<BasicImageJob>(new BasicImageJob(
      registry, std::move(scene), min_version, std::move(options), std::move(cancelled)));
}

template <class S>
void BasicImageJob<S>::Run(std::shared_ptr<const Frame> frame, bool on_caller) {
  if (!on_caller) {  // already on the CPU pool (the frame's waiters resume there)
    Encode(*frame);
    return;
  }
  auto self = std::static_pointer_cast<BasicImageJob>(this->shared_from_this());
  this->registry_->answers().Submit([self, frame] { self->Encode(*frame); });
}

namespace {

// The part of the plane a rect of a frame's pixels (a volume's slice's voxels) covers.
Window AreaOf(const Frame& frame, PixelRect rect) { return frame.grid().Area(rect); }
Window AreaOf(const Volume& volume, PixelRect rect) {
  const Box3& b = volume.grid().box;
  return Grid{{b.min_x, b.min_y, b.max_x, b.max_y}, volume.grid().width, volume.grid().height}
      .Area(rect);
}

}  // namespace

template <class S>
void BasicImageJob<S>::Encode(const Frame& frame) {
  if (this->cancelled()) {
    this->Finish(absl::CancelledError("the call was cancelled"));
    return;
  }
  auto image = EncodeImage(frame, options_);
  if (!image.ok()) {
    this->Finish(image.status());
    return;
  }
  image_ = std::move(*image);
  window_ = AreaOf(frame, options_.rect);
  this->Finish(absl::OkStatus());
}

// ---- AnalysisJob ----

template <class S>
BasicAnalysisJob<S>::BasicAnalysisJob(SceneRegistry* registry, std::shared_ptr<S> scene,
                                      uint64_t min_version, Work work,
                                      std::function<bool()> cancelled)
    : BasicFrameJob<S>(registry, std::move(scene), min_version, std::move(cancelled)),
      work_(std::move(work)) {}

template <class S>
std::shared_ptr<BasicAnalysisJob<S>> BasicAnalysisJob<S>::Make(SceneRegistry* registry,
                                                               std::shared_ptr<S> scene,
                                                               uint64_t min_version, Work work,
                                                               std::function<bool()> cancelled) {
  return std::shared_ptr<BasicAnalysisJob>(new BasicAnalysisJob(
      registry, std::move(scene), min_version, std::move(work), std::move(cancelled)));
}

template <class S>
void BasicAnalysisJob<S>::Run(std::shared_ptr<const Frame> frame, bool) {
  auto self = std::static_pointer_cast<BasicAnalysisJob>(this->shared_from_this());
  CpuPool::Lane& lane = this->registry_->analyses();
  const bool queued = lane.Submit([self, frame] {
    if (self->cancelled()) {
      self->Finish(absl::CancelledError("the call was cancelled"));
      return;
    }
    self->Finish(self->work_(frame));
  });
  if (!queued) {
    this->Finish(absl::ResourceExhaustedError(
        absl::StrCat(lane.max_queued(),
                     " analysis calls already wait for a worker (--max-queued-analyses)")));
  }
}

template class BasicFrameJob<Scene>;
template class BasicFrameJob<Scene3>;
template class BasicNearestJob<Scene>;
template class BasicNearestJob<Scene3>;
template class BasicImageJob<Scene>;
template class BasicImageJob<Scene3>;
template class BasicAnalysisJob<Scene>;
template class BasicAnalysisJob<Scene3>;

}  // namespace gvd
