// The reactors of the service's call shapes, each around the application core's work:
//  - JobReactor<Job>: a unary call around one job of server/app/jobs.h (nearest queries,
//    images, analyses), finished when the job is done;
//  - LaneReactor: a unary call whose work runs on a lane of the core (writes on the commit
//    threads, heavier reads on the CPU pool), never on gRPC's threads.
// (FindNearestStream's reactor, and WatchScene's, are their own: service.cc, watch.h.)
#pragma once

#include <functional>
#include <memory>

#include <grpcpp/grpcpp.h>

#include "absl/strings/str_cat.h"
#include "render/scene/cpu_pool.h"
#include "server/grpc/call_scope.h"
#include "server/grpc/convert.h"

namespace gvd {

// Starts the job, and once it is done, lets `respond` fill the response (on OK) and finishes
// with the job's status, recorded in the call's scope. A cancelled call cancels the job.
template <class Job>
class JobReactor final : public grpc::ServerUnaryReactor {
 public:
  using Respond = std::function<void(const Job&)>;
  JobReactor(std::shared_ptr<CallScope> scope, std::shared_ptr<Job> job, Respond respond)
      : scope_(std::move(scope)), job_(std::move(job)), respond_(std::move(respond)) {}

  // Starts the call's job. After it returns, this object may already be finished and gone.
  static grpc::ServerUnaryReactor* Start(std::shared_ptr<CallScope> scope,
                                         std::shared_ptr<Job> job, Respond respond) {
    auto* reactor = new JobReactor(std::move(scope), job, std::move(respond));
    job->Start([reactor](const absl::Status& s) { reactor->Done(s); });
    return reactor;
  }
  void OnCancel() override { job_->Cancel(); }
  void OnDone() override { delete this; }

 private:
  void Done(const absl::Status& s) {
    if (s.ok() && respond_) respond_(*job_);
    const grpc::Status status = ToGrpc(s);
    scope_->Record(status);
    Finish(status);
  }

  std::shared_ptr<CallScope> scope_;
  std::shared_ptr<Job> job_;
  Respond respond_;
};

// Runs `work` on `lane` and finishes with its status. When the lane's queue is full, the call
// is refused with RESOURCE_EXHAUSTED naming `limit` (the flag that sets the queue's size).
class LaneReactor final : public grpc::ServerUnaryReactor {
 public:
  static grpc::ServerUnaryReactor* Start(std::shared_ptr<CallScope> scope, CpuPool::Lane& lane,
                                         const char* limit, std::function<grpc::Status()> work) {
    auto* reactor = new LaneReactor(std::move(scope));
    const bool queued = lane.Submit([reactor, work = std::move(work)] { reactor->Done(work()); });
    if (!queued) {
      reactor->Done(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                 absl::StrCat(lane.max_queued(), " calls already wait for their turn (",
                                              limit, ")")));
    }
    return reactor;
  }
  void OnDone() override { delete this; }

 private:
  explicit LaneReactor(std::shared_ptr<CallScope> scope) : scope_(std::move(scope)) {}
  void Done(const grpc::Status& status) {
    scope_->Record(status);
    Finish(status);
  }

  std::shared_ptr<CallScope> scope_;
};

}  // namespace gvd
