// How every call is accounted for: in flight while it lives, and its method, status and
// duration in the metrics when it ends.
#pragma once

#include <atomic>
#include <chrono>

#include <grpcpp/grpcpp.h>

#include "server/metrics.h"

namespace gvd {

// What a service counts about its calls. Thread-safe.
struct CallCounter {
  explicit CallCounter(Metrics* metrics) : metrics(metrics) {}
  std::atomic<int> in_flight{0};
  Metrics* const metrics;  // null: none
};

// Counts a call in flight for as long as it lives, and records its method, status and
// duration in the metrics when it ends. Thread-safe.
class CallScope {
 public:
  CallScope(CallCounter* counter, const char* method)
      : counter_(counter), method_(method), start_(std::chrono::steady_clock::now()) {
    ++counter_->in_flight;
    if (counter_->metrics) counter_->metrics->RpcStarted(method_);
  }
  ~CallScope() {
    Record(grpc::Status::OK);  // a call that ended without a recorded status
    if (counter_->metrics) counter_->metrics->RpcEnded(method_);
    --counter_->in_flight;
  }
  CallScope(const CallScope&) = delete;
  CallScope& operator=(const CallScope&) = delete;

  // Records the call's status and duration, once, before the status goes out (so that a
  // client that has its answer finds it in the metrics).
  void Record(const grpc::Status& s) {
    if (recorded_.exchange(true) || !counter_->metrics) return;
    counter_->metrics->ObserveRpc(
        method_, static_cast<absl::StatusCode>(s.error_code()),
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
  CallCounter* const counter_;
  const char* method_;
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> recorded_{false};
};

}  // namespace gvd
