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

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "render/image/image.h"
#include "render/kernel/site2.h"
#include "render/scene/frame.h"
#include "render/scene/scene.h"
#include "server/app/registry.h"

namespace gvd {

// What every job does: waits for its frame, runs its work, and calls `done` exactly once.
// Cancel() and the frame's arrival race safely: whichever removes the job's waiter from the
// scene finishes it. Thread-safe. The job keeps itself alive until `done` has been called.
// A template on the scene (Scene or Scene3), whose frames (Frames or Volumes) it waits for.
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
  void Finish(const absl::Status& status);
  bool cancelled() const { return cancelled_fn_ && cancelled_fn_(); }

  SceneRegistry* const registry_;
  const std::shared_ptr<S> scene_;
  const uint64_t min_version_;
  const std::function<bool()> cancelled_fn_;
  uint64_t version_ = 0;

 private:
  void OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame, bool on_caller);

  Done done_;
  std::mutex mu_;  // guards the two below
  uint64_t token_ = 0;
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
// from the scene's latest snapshot, whose first render it need not wait for (a replica that
// has not reached min_version waits for that version's frame, then answers from its latest
// snapshot). NearestJob is a 2D scene's, NearestJob3 a 3D scene's (its frames are volumes).
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
using NearestJob3 = BasicNearestJob<Scene3>;

// A layer of the frame as an image: of a 2D scene's frame (ImageJob), or of a slice of a 3D
// scene's volume (ImageJob3, ImageOptions::slice).
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
using ImageJob3 = BasicImageJob<Scene3>;

// A structure or planning call: `work` runs on the frame on the analyses lane, and its status
// ends the job (RESOURCE_EXHAUSTED, naming --max-queued-analyses, when the lane is full). Of
// a 2D scene's frame (AnalysisJob) or a 3D scene's volume (AnalysisJob3).
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
using AnalysisJob3 = BasicAnalysisJob<Scene3>;

extern template class BasicFrameJob<Scene>;
extern template class BasicFrameJob<Scene3>;
extern template class BasicNearestJob<Scene>;
extern template class BasicNearestJob<Scene3>;
extern template class BasicImageJob<Scene>;
extern template class BasicImageJob<Scene3>;
extern template class BasicAnalysisJob<Scene>;
extern template class BasicAnalysisJob<Scene3>;

}  // namespace gvd
