// Calls that wait for a scene's frame: the job that waits (or answers exact queries at once)
// and the unary reactor around it. Shared by the service's source files.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/strings/str_cat.h"
#include "render/scene/cpu_pool.h"
#include "server/grpc/call_scope.h"
#include "server/grpc/convert.h"
#include "render/scene/scene.h"

namespace gvd {

// A validated FindNearest request.
struct NearestQuery {
  std::shared_ptr<CallScope> scope;  // the call stays in flight while the query lives
  grpc::CallbackServerContext* ctx = nullptr;  // valid while the call lives
  std::shared_ptr<Scene> scene;
  std::vector<Vec2> points;
  bool exact = false;
  bool skip_refinement = false;  // leave ambiguous raster answers as they are
  // The packed columns asked for: bit f for v1::FindNearestRequest::Field f.
  uint32_t fields = kAllFields;
  static constexpr uint32_t kAllFields = 0x3e;  // SITE .. FEATURE
  bool wants(v1::FindNearestRequest::Field f) const { return fields & (1u << f); }
  uint64_t min_version = 0;
  // When set, the job hands the frame to this instead of answering points (RenderImage).
  std::function<grpc::Status(const Frame&)> on_frame;
  // Or to this, which calls `done` exactly once, when it likes (on a worker thread): the
  // analysis calls. The job and the frame stay alive until then.
  using Done = std::function<void(const grpc::Status&)>;
  std::function<void(std::shared_ptr<const Frame>, Done)> on_frame_async;
};

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

// Resolves a query's answers: at once when they are exact or the latest frame is new
// enough, else when the render thread publishes the awaited version. The frame callback and
// Cancel race safely: whichever removes the waiter from the scene finishes the job.
class NearestJob : public std::enable_shared_from_this<NearestJob> {
 public:
  explicit NearestJob(NearestQuery query) : query_(std::move(query)) {}

  // Calls done exactly once; `rows()` and `version()` are valid once it has been called
  // with OK.
  void Start(std::function<void(const grpc::Status&)> done) {
    auto self = shared_from_this();  // done() may release the job's last other owner
    done_ = [this, done = std::move(done)](const grpc::Status& s) {
      query_.scope->Record(s);
      done(s);
    };
    if (query_.exact) {
      version_ = query_.scene->NearestExact(query_.points, &exact_answers_,
                                            [this] { return query_.ctx->IsCancelled(); },
                                            query_.wants(v1::FindNearestRequest::FEATURE));
      if (version_ == 0) {
        done_(grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled"));
        return;
      }
      rows_.reserve(exact_answers_.size());
      for (const auto& a : exact_answers_) {
        rows_.push_back({a.found ? &a.site_id : nullptr, a.slot, a.distance, 0, true,
                         a.feature_kind, a.feature_index});
      }
      done_(grpc::Status::OK);
      return;
    }
    uint64_t token = query_.scene->WhenRendered(
        query_.min_version, [self](auto frame) { self->OnFrame(frame); });
    std::lock_guard<std::mutex> lock(mu_);
    token_ = token;
    if (cancelled_) query_.scene->Cancel(token, absl::CancelledError("call cancelled"));
  }

  void Cancel() {
    std::lock_guard<std::mutex> lock(mu_);
    cancelled_ = true;
    if (token_ != 0) {
      query_.scene->Cancel(token_, absl::DeadlineExceededError(
                                       "cancelled or past its deadline while waiting for the "
                                       "scene's min_version to be rendered"));
    }
  }

  const std::vector<AnswerRow>& rows() const { return rows_; }
  uint32_t fields() const { return query_.fields; }
  uint64_t version() const { return version_; }

 private:
  void OnFrame(const absl::StatusOr<std::shared_ptr<const Frame>>& frame) {
    if (!frame.ok()) {
      done_(ToGrpc(frame.status()));
      return;
    }
    frame_ = *frame;
    if (frame_->empty()) {
      done_(grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                   absl::StrCat("scene \"", query_.scene->id(), "\" has no sites at version ",
                                frame_->version())));
      return;
    }
    version_ = frame_->version();
    if (query_.on_frame) {
      done_(query_.on_frame(*frame_));
      return;
    }
    if (query_.on_frame_async) {
      auto self = shared_from_this();
      query_.on_frame_async(frame_, [self](const grpc::Status& s) { self->done_(s); });
      return;
    }
    rows_.resize(query_.points.size());
    const bool features = query_.wants(v1::FindNearestRequest::FEATURE);
    std::atomic<bool> missing{false}, cancelled{false};
    // Large batches are answered tile by tile of the frame, so that each tile's pixels and
    // sites stay in cache while its points are looked up.
    const std::vector<uint32_t> order = OrderByTile(frame_->grid(), query_.points);
    ParallelFor(rows_.size(), 8192, [&](size_t begin, size_t end) {
      for (size_t k = begin; k < end; ++k) {
        const size_t i = order.empty() ? k : order[k];
        if (k % 4096 == 0 && (cancelled || query_.ctx->IsCancelled())) {
          cancelled = true;
          return;
        }
        auto a = frame_->Nearest(query_.points[i]);
        if (!a) {
          missing = true;
          return;
        }
        if (!query_.skip_refinement && a->ambiguous()) a = frame_->Refine(query_.points[i], *a);
        if (!a->found) {
          rows_[i] = {nullptr, 0, INFINITY, 0, true, FeatureKind::kVertex, 0};
          continue;
        }
        const Site& site = *frame_->sites().get(a->site_index);
        FeatureHit f = std::holds_alternative<PointSite>(site.geometry) || !features
                           ? FeatureHit{}
                           : NearestFeature(query_.points[i], site);
        rows_[i] = {&site.id, a->site_index, a->distance, a->error_bound,
                    a->error_bound == 0, f.kind, f.index};
      }
    });
    if (cancelled) {
      done_(grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled"));
      return;
    }
    if (missing) {
      done_(grpc::Status(grpc::StatusCode::INTERNAL, "frame has no site at a query point"));
      return;
    }
    done_(grpc::Status::OK);
  }

  NearestQuery query_;
  std::function<void(const grpc::Status&)> done_;
  std::shared_ptr<const Frame> frame_;  // owns the ids the rows point to
  std::vector<Scene::ExactAnswer> exact_answers_;
  std::vector<AnswerRow> rows_;
  uint64_t version_ = 0;
  std::mutex mu_;
  uint64_t token_ = 0;
  bool cancelled_ = false;
};

// A unary call that waits for its frame like a query, then hands it to NearestQuery::on_frame
// (or on_frame_async): RenderImage and the analysis calls.
class FrameReactor final : public grpc::ServerUnaryReactor {
 public:
  explicit FrameReactor(NearestQuery query) : job_(std::make_shared<NearestJob>(std::move(query))) {}
  // After Start, this object may already be finished and deleted.
  void Start() {
    auto job = job_;
    job->Start([this](const grpc::Status& s) { Finish(s); });
  }
  void OnCancel() override { job_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  std::shared_ptr<NearestJob> job_;
};

}  // namespace gvd
