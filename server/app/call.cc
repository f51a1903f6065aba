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
    : counter_(counter),
      rpc_(counter->metrics ? counter->metrics->RpcOf(method) : nullptr),
      start_(std::chrono::steady_clock::now()) {
  ++counter_->in_flight;
  if (rpc_) rpc_->Started();
}

CallScope::~CallScope() {
  Record(absl::OkStatus());
  if (rpc_) rpc_->Ended();
  --counter_->in_flight;
}

void CallScope::Record(const absl::Status& s) {
  if (recorded_.exchange(true) || !rpc_) return;
  rpc_->Observe(s.code(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
}

}  // namespace gvd
