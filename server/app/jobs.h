// The calls that read a frame, one plain job type per call shape: nearest-site queries
// (NearestJob), images (ImageJob) and analyses (AnalysisJob). No transport: the gRPC layer
// wraps each in a reactor of its own, and finishes it when the job says it is done.
//
// Where the work runs. A job waits for a frame of its scene at the version it asks for (at
// once when the latest frame is new enough), then:
//  - NearestJob answers a small batch (kInlinePoints raster answers, or kInlineExactPoints
//    exact ones in a scene where each costs O(log n)) on the thread that started it or that
//    delivered the frame, and every other batch on the CPU pool (SceneRegistry::answers());
//  - ImageJob encodes on the CPU pool, always;
//  - AnalysisJob works on the analyses lane (SceneRegistry::analyses()).
// So a transport's thread never runs an exact search over a large batch nor an encode.
#pragma once

#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/kernel/exact2.h"
#include "render/scene/batch.h"
#include "render/image/image.h"
#include "render/kernel/site2.h"
#include "render/scene/frame.h"
#include "render/scene/scene.h"
#include "server/app/registry.h"

namespace gvd {

// What every job does: waits for its frame, runs its work, and calls `done` exactly once.
// Cancel() and the frame's arrival race safely: whichever removes the job's waiter from the
// scene finishes it. Thread-safe. The job keeps itself alive until `done` has been called.
// A template on the scene (a 2D or a 3D one), whose frames (Frames or Volumes) it waits for.
template <class S>
class BasicFrameJob : public std::enable_shared_from_this<BasicFrameJob<S>> {
 public:
  using Frame = typename S::Frame;
  using Done = std::function<void(const absl::Status&)>;
  virtual ~BasicFrameJob() = default;
  BasicFrameJob(const BasicFrameJob&) = delete;
  BasicFrameJob& operator=(const BasicFrameJob&) = delete;

  // Starts the job. CONTRACT: called once.
  void Start(Done done);
  // The call was cancelled or its deadline passed: a job still waiting for its frame ends
  // with DEADLINE_EXCEEDED; work under way notices through `cancelled`.
  void Cancel();
  // The version the job answered from; valid once `done` was called with OK.
  uint64_t version() const { return version_; }

 protected:
  // `cancelled` (may be empty) says whether the caller has gone.
  BasicFrameJob(SceneRegistry* registry, std::shared_ptr<S> scene, uint64_t min_version,
                std::function<bool()> cancelled);

  // How the job begins: by default it waits for its frame (WaitForFrame).
  virtual void Begin() { WaitForFrame(); }
  // The work on a frame of at least min_version with sites; ends with Finish. `on_caller`:
  // this is the thread that started the job (the frame was ready at once).
  virtual void Run(std::shared_ptr<const Frame> frame, bool on_caller) = 0;

  void WaitForFrame();
  // Begins again once the scene holds min_version (a replica that has not read it yet).
  void WaitForCommit();
  void Finish(const absl::Status& status);
  bool cancelled() const { return cancelled_fn_ && cancelled_fn_(); }

  SceneRegistry* const registry_;
  const std::shared_ptr<S> scene_;
  const uint64_t min_version_;
  const std::function<bool()> cancelled_fn_;
  uint64_t version_ = 0;

 private:
  void OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame, bool on_caller);

  // Registers the job's waiter through `wait` (a scene's WhenRendered or WhenCommitted) as
  // the one Cancel ends.
  void Await(const std::function<uint64_t()>& wait);

  Done done_;
  std::mutex mu_;  // guards the three below
  uint64_t token_ = 0;
  uint64_t waits_ = 0;  // Await calls begun: a later one's token supersedes
  bool cancelled_ = false;
};

using FrameJob = BasicFrameJob<Scene>;

// A nearest-site query of a batch of points (Vec2 or Vec3).
template <class P>
struct BasicNearestQuery {
  std::vector<P> points;
  bool exact = false;            // certify every answer (no raster bound)
  bool skip_refinement = false;  // leave ambiguous raster answers as they are
  bool features = true;          // find each answer's nearest feature
  uint64_t min_version = 0;      // SceneRegistry::ReadVersion's
  bool closest = false;          // find each answer's nearest point (NearestJob::closest)
};
using NearestQuery = BasicNearestQuery<Vec2>;

// One answer, pointing into storage its NearestJob keeps alive.
struct AnswerRow {
  const std::string* site_id;  // null: no site is a candidate at the point
  uint32_t slot;               // the site's slot in the answering version's table
  double distance;
  double error_bound;
  bool exact;
  FeatureKind feature_kind;
  uint32_t feature_index;
};

// Answers a query: raster answers from the frame (refined where ambiguous), or exact ones
// from the scene's latest snapshot, whose render it need not wait for (a replica that has
// not reached min_version first waits until it has read that version from its store). A
// raster query whose min_version is committed but not yet rendered gets exact answers too,
// when it has at most kInlineExactPoints points and the scene is a NEAREST one of plain
// sites (each answer O(log n) through the index); any other waits for the frame.
// NearestJob is a 2D scene's; a 3D scene's frames are volumes.
template <class S>
class BasicNearestJob final : public BasicFrameJob<S> {
 public:
  using Point = typename S::Point;
  using Frame = typename S::Frame;
  using Query = BasicNearestQuery<Point>;
  // Batches up to these sizes are answered on the thread that has them (see above).
  static constexpr size_t kInlinePoints = 1024;
  static constexpr size_t kInlineExactPoints = 64;

  static std::shared_ptr<BasicNearestJob> Make(SceneRegistry* registry, std::shared_ptr<S> scene,
                                               Query query, std::function<bool()> cancelled);
  // The answers in the order of the points; valid once `done` was called with OK.
  const std::vector<AnswerRow>& rows() const { return rows_; }
  // The query points, in order.
  const std::vector<Point>& points() const { return query_.points; }
  // Each answer's site's point nearest to its query point, when the query asked for them
  // (NearestQuery::closest; else empty); NaN for an empty answer.
  const std::vector<Point>& closest() const { return closest_; }

 private:
  BasicNearestJob(SceneRegistry* registry, std::shared_ptr<S> scene, Query query,
                  std::function<bool()> cancelled);
  void Begin() override;
  void Run(std::shared_ptr<const Frame> frame, bool on_caller) override;
  void BeginExact();
  void AnswerExact();
  void AnswerFrom(const std::shared_ptr<const Frame>& frame);

  const Query query_;
  std::shared_ptr<const Frame> frame_;  // owns the ids the rows point to
  std::vector<typename S::ExactAnswer> exact_answers_;
  std::vector<AnswerRow> rows_;
  std::vector<Point> closest_;
};
using NearestJob = BasicNearestJob<Scene>;

// A layer of the frame as an image: of a 2D scene's frame (ImageJob), or of a slice of a 3D
// scene's volume (ImageOptions::slice).
template <class S>
class BasicImageJob final : public BasicFrameJob<S> {
 public:
  using Frame = typename S::Frame;
  static std::shared_ptr<BasicImageJob> Make(SceneRegistry* registry, std::shared_ptr<S> scene,
                                             uint64_t min_version, ImageOptions options,
                                             std::function<bool()> cancelled);
  // Valid once `done` was called with OK: the image, and the window it shows.
  const EncodedImage& image() const { return image_; }
  const Window& window() const { return window_; }

 private:
  BasicImageJob(SceneRegistry* registry, std::shared_ptr<S> scene, uint64_t min_version,
                ImageOptions options, std::function<bool()> cancelled);
  void Run(std::shared_ptr<const Frame> frame, bool on_caller) override;
  void Encode(const Frame& frame);

  const ImageOptions options_;
  EncodedImage image_;
  Window window_;
};
using ImageJob = BasicImageJob<Scene>;

// A structure or planning call: `work` runs on the frame on the analyses lane, and its status
// ends the job (RESOURCE_EXHAUSTED, naming --max-queued-analyses, when the lane is full). Of
// a 2D scene's frame (AnalysisJob) or a 3D scene's volume.
template <class S>
class BasicAnalysisJob final : public BasicFrameJob<S> {
 public:
  using Frame = typename S::Frame;
  using Work = std::function<absl::Status(const std::shared_ptr<const Frame>& frame)>;
  static std::shared_ptr<BasicAnalysisJob> Make(SceneRegistry* registry, std::shared_ptr<S> scene,
                                                uint64_t min_version, Work work,
                                                std::function<bool()> cancelled);

 private:
  BasicAnalysisJob(SceneRegistry* registry, std::shared_ptr<S> scene, uint64_t min_version,
                   Work work, std::function<bool()> cancelled);
  void Run(std::shared_ptr<const Frame> frame, bool on_caller) override;

  const Work work_;
};
using AnalysisJob = BasicAnalysisJob<Scene>;

// ---- The jobs' definitions: templates on the scene, instantiated where they are used. ----
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
  Await([&] {
    return scene_->WhenRendered(min_version_, [self, caller](auto frame) {
      self->OnFrame(frame, std::this_thread::get_id() == caller);
    });
  });
}

template <class S>
void BasicFrameJob<S>::WaitForCommit() {
  auto self = this->shared_from_this();
  Await([&] {
    return scene_->WhenCommitted(min_version_, [self](auto frame) {
      if (frame.ok()) {
        self->Begin();
      } else {
        self->Finish(frame.status());
      }
    });
  });
}

template <class S>
void BasicFrameJob<S>::Await(const std::function<uint64_t()>& wait) {
  uint64_t mine;
  {
    std::lock_guard<std::mutex> lock(mu_);
    mine = ++waits_;
  }
  // The waiter may be resumed before this returns, and Begin a later wait: that one's token
  // is then the one to cancel.
  const uint64_t token = wait();
  std::lock_guard<std::mutex> lock(mu_);
  if (waits_ != mine) return;
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
  // A replica behind min_version waits for the log, then begins again (its waiters end when
  // the store has the version, or fail when the store has not reached it either).
  if (this->scene_->version() < this->min_version_) {
    this->WaitForCommit();
    return;
  }
  // Exact answers come from the latest version.
  if (query_.exact) {
    BeginExact();
    return;
  }
  // A raster read of a version committed but not yet drawn: where the index answers each
  // point in O(log n), it answers at once, exactly, rather than wait for the render.
  if (this->min_version_ > 0 && query_.points.size() <= kInlineExactPoints &&
      this->scene_->frame()->version() < this->min_version_) {
    const auto snapshot = this->scene_->snapshot();
    if (!snapshot->empty() && snapshot->plain() &&
        this->scene_->settings().diagram == Diagram::kNearest) {
      AnswerExact();
      return;
    }
  }
  this->WaitForFrame();
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
    rows_.push_back({a.found ? &a.site_id : nullptr, a.slot, a.distance, a.error_bound,
                     /*exact=*/true, a.feature_kind, a.feature_index});
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
                    a->exact, f.kind, f.index};
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

namespace jobs_internal {

// The part of the plane a rect of a frame's pixels (a volume's slice's voxels) covers.
inline Window AreaOf(const Frame& frame, PixelRect rect) { return frame.grid().Area(rect); }
inline Window AreaOf(const Volume& volume, PixelRect rect) {
  const Box3& b = volume.grid().box;
  return Grid{{b.min_x, b.min_y, b.max_x, b.max_y}, volume.grid().width, volume.grid().height}
      .Area(rect);
}

}  // namespace jobs_internal

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
  window_ = jobs_internal::AreaOf(frame, options_.rect);
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

}  // namespace gvd
