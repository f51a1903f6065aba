#include "server/app/call.h"

namespace gvd {

void Call::Cancel() {
  std::vector<std::function<void()>> hooks;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (cancelled_.exchange(true, std::memory_order_acq_rel)) return;
    hooks.swap(hooks_);
  }
  for (auto& hook : hooks) hook();
}

void Call::OnCancel(std::function<void()> hook) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!cancelled()) {
      hooks_.push_back(std::move(hook));
      return;
    }
  }
  hook();
}

CallScope::CallScope(CallCounter* counter, const char* method)
    : counter_(counter), method_(method), start_(std::chrono::steady_clock::now()) {
  ++counter_->in_flight;
  if (counter_->metrics) counter_->metrics->RpcStarted(method_);
}

CallScope::~CallScope() {
  Record(absl::OkStatus());
  if (counter_->metrics) counter_->metrics->RpcEnded(method_);
  --counter_->in_flight;
}

void CallScope::Record(const absl::Status& s) {
  if (recorded_.exchange(true) || !counter_->metrics) return;
  counter_->metrics->ObserveRpc(
      method_, s.code(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
}

}  // namespace gvd
