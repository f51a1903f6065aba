// How every call is accounted for: in flight while it lives, and its method, status and
// duration in the metrics when it ends. Shared by the service's source files.
#pragma once

#include <atomic>
#include <chrono>

#include <grpcpp/grpcpp.h>

#include "server/service.h"

namespace gvd {

// Counts a call in flight for as long as it lives, and records its method, status and
// duration in the metrics when it ends.
class CallScope {
 public:
  CallScope(const VoronoiService* s, const char* method)
      : s_(s), method_(method), start_(std::chrono::steady_clock::now()) {
    ++s_->in_flight_;
    if (s_->metrics_) s_->metrics_->RpcStarted(method_);
  }
  ~CallScope() {
    Record(grpc::Status::OK);  // a call that ended without a recorded status
    if (s_->metrics_) s_->metrics_->RpcEnded(method_);
    --s_->in_flight_;
  }
  CallScope(const CallScope&) = delete;
  CallScope& operator=(const CallScope&) = delete;

  // Records the call's status and duration, once, before the status goes out (so that a
  // client that has its answer finds it in the metrics).
  void Record(const grpc::Status& s) {
    if (recorded_.exchange(true) || !s_->metrics_) return;
    s_->metrics_->ObserveRpc(
        method_, s.error_code(),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
  }
  // Finishes a unary call with `status`, recording it.
  grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* ctx, const grpc::Status& status) {
    Record(status);
    auto* reactor = ctx->DefaultReactor();
    reactor->Finish(status);
    return reactor;
  }

 private:
  const VoronoiService* s_;
  const char* method_;
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> recorded_{false};
};

}  // namespace gvd
