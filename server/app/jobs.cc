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

FrameJob::FrameJob(SceneRegistry* registry, std::shared_ptr<Scene> scene, uint64_t min_version,
                   std::function<bool()> cancelled)
    : registry_(registry), scene_(std::move(scene)), min_version_(min_version),
      cancelled_fn_(std::move(cancelled)) {}

void FrameJob::Start(Done done) {
  auto self = shared_from_this();  // Finish may release the job's last other owner
  done_ = std::move(done);
  Begin();
}

void FrameJob::WaitForFrame() {
  auto self = shared_from_this();
  const std::thread::id caller = std::this_thread::get_id();
  uint64_t token = scene_->WhenRendered(min_version_, [self, caller](auto frame) {
    self->OnFrame(frame, std::this_thread::get_id() == caller);
  });
  std::lock_guard<std::mutex> lock(mu_);
  token_ = token;
  if (cancelled_) scene_->Cancel(token, absl::CancelledError("the call was cancelled"));
}

void FrameJob::Cancel() {
  std::lock_guard<std::mutex> lock(mu_);
  cancelled_ = true;
  if (token_ != 0) {
    scene_->Cancel(token_, absl::DeadlineExceededError(
                               "cancelled or past its deadline while waiting for the scene's "
                               "min_version to be rendered"));
  }
}

void FrameJob::OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame,
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

void FrameJob::Finish(const absl::Status& status) {
  auto self = shared_from_this();
  Done done = std::move(done_);
  done(status);
}

// ---- NearestJob ----

NearestJob::NearestJob(SceneRegistry* registry, std::shared_ptr<Scene> scene, NearestQuery query,
                       std::function<bool()> cancelled)
    : FrameJob(registry, std::move(scene), query.min_version, std::move(cancelled)),
      query_(std::move(query)) {}

std::shared_ptr<NearestJob> NearestJob::Make(SceneRegistry* registry, std::shared_ptr<Scene> scene,
                                             NearestQuery query, std::function<bool()> cancelled) {
  return std::shared_ptr<NearestJob>(
      new NearestJob(registry, std::move(scene), std::move(query), std::move(cancelled)));
}

void NearestJob::Begin() {
  if (!query_.exact) {
    WaitForFrame();
    return;
  }
  const auto snapshot = scene_->snapshot();
  if (snapshot->empty()) {
    Finish(absl::FailedPreconditionError(absl::StrCat(
        "scene \"", scene_->id(), "\" has no sites at version ", snapshot->version())));
    return;
  }
  // Exact answers cost O(log n) each in a NEAREST scene of plain sites; with weights, sides
  // or max_distance, or in a FARTHEST scene, one may score every site.
  const bool cheap =
      snapshot->plain() && scene_->settings().diagram == Diagram::kNearest;
  if (cheap && query_.points.size() <= kInlineExactPoints) {
    AnswerExact();
    return;
  }
  auto self = std::static_pointer_cast<NearestJob>(shared_from_this());
  registry_->answers().Submit([self] { self->AnswerExact(); });
}

void NearestJob::AnswerExact() {
  version_ = scene_->NearestExact(query_.points, &exact_answers_, cancelled_fn_,
                                  query_.features || query_.closest);
  if (version_ == 0) {
    Finish(absl::CancelledError("the call was cancelled"));
    return;
  }
  rows_.reserve(exact_answers_.size());
  for (const auto& a : exact_answers_) {
    rows_.push_back({a.found ? &a.site_id : nullptr, a.slot, a.distance, 0, true,
                     a.feature_kind, a.feature_index});
    if (query_.closest) closest_.push_back(a.found ? a.closest : Vec2(NAN));
  }
  Finish(absl::OkStatus());
}

void NearestJob::Run(std::shared_ptr<const Frame> frame, bool on_caller) {
  if (on_caller && query_.points.size() > kInlinePoints) {
    auto self = std::static_pointer_cast<NearestJob>(shared_from_this());
    registry_->answers().Submit([self, frame] { self->AnswerFrom(frame); });
    return;
  }
  AnswerFrom(frame);
}

void NearestJob::AnswerFrom(const std::shared_ptr<const Frame>& frame) {
  frame_ = frame;
  rows_.resize(query_.points.size());
  if (query_.closest) closest_.resize(query_.points.size());
  std::atomic<bool> missing{false};
  const bool answered = AnswerBatch(
      frame_->grid(), query_.points, 4096, cancelled_fn_,
      [&](size_t i, std::vector<uint32_t>&) {
        const Vec2 q = query_.points[i];
        auto a = frame_->Nearest(q);
        if (!a) {
          missing = true;
          return false;
        }
        if (!query_.skip_refinement && a->ambiguous()) a = frame_->Refine(q, *a);
        if (!a->found) {
          rows_[i] = {nullptr, 0, INFINITY, 0, true, FeatureKind::kVertex, 0};
          if (query_.closest) closest_[i] = Vec2(NAN);
          return true;
        }
        const Site& site = *frame_->sites().get(a->site_index);
        FeatureHit f;
        if (const auto* point = std::get_if<PointSite>(&site.geometry)) {
          f.closest = point->p;  // vertex 0
        } else if (query_.features || query_.closest) {
          f = NearestFeature(q, site);
        }
        rows_[i] = {&site.id, a->site_index, a->distance, a->error_bound,
                    a->error_bound == 0, f.kind, f.index};
        if (query_.closest) closest_[i] = f.closest;
        return true;
      });
  if (missing) {
    Finish(absl::InternalError("frame has no site at a query point"));
  } else if (!answered) {
    Finish(absl::CancelledError("the call was cancelled"));
  } else {
    Finish(absl::OkStatus());
  }
}

// ---- ImageJob ----

ImageJob::ImageJob(SceneRegistry* registry, std::shared_ptr<Scene> scene, uint64_t min_version,
                   ImageOptions options, std::function<bool()> cancelled)
    : FrameJob(registry, std::move(scene), min_version, std::move(cancelled)),
      options_(std::move(options)) {}

std::shared_ptr<ImageJob> ImageJob::Make(SceneRegistry* registry, std::shared_ptr<Scene> scene,
                                         uint64_t min_version, ImageOptions options,
                                         std::function<bool()> cancelled) {
  return std::shared_ptr<ImageJob>(new ImageJob(registry, std::move(scene), min_version,
                                                std::move(options), std::move(cancelled)));
}

void ImageJob::Run(std::shared_ptr<const Frame> frame, bool on_caller) {
  if (!on_caller) {  // already on the CPU pool (the frame's waiters resume there)
    Encode(*frame);
    return;
  }
  auto self = std::static_pointer_cast<ImageJob>(shared_from_this());
  registry_->answers().Submit([self, frame] { self->Encode(*frame); });
}

void ImageJob::Encode(const Frame& frame) {
  if (cancelled()) {
    Finish(absl::CancelledError("the call was cancelled"));
    return;
  }
  auto image = EncodeImage(frame, options_);
  if (!image.ok()) {
    Finish(image.status());
    return;
  }
  image_ = std::move(*image);
  window_ = frame.grid().Area(options_.rect);
  Finish(absl::OkStatus());
}

// ---- AnalysisJob ----

AnalysisJob::AnalysisJob(SceneRegistry* registry, std::shared_ptr<Scene> scene,
                         uint64_t min_version, Work work, std::function<bool()> cancelled)
    : FrameJob(registry, std::move(scene), min_version, std::move(cancelled)),
      work_(std::move(work)) {}

std::shared_ptr<AnalysisJob> AnalysisJob::Make(SceneRegistry* registry,
                                               std::shared_ptr<Scene> scene, uint64_t min_version,
                                               Work work, std::function<bool()> cancelled) {
  return std::shared_ptr<AnalysisJob>(new AnalysisJob(registry, std::move(scene), min_version,
                                                      std::move(work), std::move(cancelled)));
}

void AnalysisJob::Run(std::shared_ptr<const Frame> frame, bool) {
  auto self = std::static_pointer_cast<AnalysisJob>(shared_from_this());
  CpuPool::Lane& lane = registry_->analyses();
  const bool queued = lane.Submit([self, frame] {
    if (self->cancelled()) {
      self->Finish(absl::CancelledError("the call was cancelled"));
      return;
    }
    self->Finish(self->work_(frame));
  });
  if (!queued) {
    Finish(absl::ResourceExhaustedError(
        absl::StrCat(lane.max_queued(),
                     " analysis calls already wait for a worker (--max-queued-analyses)")));
  }
}

}  // namespace gvd
