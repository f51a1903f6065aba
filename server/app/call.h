// A call as the application core serves it, whichever transport brought it: who makes it
// (the bearer token it carries), whether its caller is still there, how the core's calls end
// (Done) and how a server stream's messages leave (StreamWriter). The transports make a Call
// for each request and cancel it when the caller goes or its deadline passes.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "server/metrics.h"

namespace gvd {

// Thread-safe.
class Call {
 public:
  // `authorization`: the request's "authorization" metadata (an HTTP header), or empty.
  explicit Call(std::string authorization = "") : authorization_(std::move(authorization)) {}
  Call(const Call&) = delete;
  Call& operator=(const Call&) = delete;

  const std::string& authorization() const { return authorization_; }

  // Whether the caller has gone (or its deadline passed): work under way polls it.
  bool cancelled() const { return cancelled_.load(std::memory_order_acquire); }
  // The transport's: the caller has gone. Runs the hooks registered, once.
  void Cancel();
  // The core's: `hook` runs when the call is cancelled (at once, here, if it is already).
  void OnCancel(std::function<void()> hook);

 private:
  const std::string authorization_;
  std::atomic<bool> cancelled_{false};
  std::mutex mu_;  // guards hooks_
  std::vector<std::function<void()>> hooks_;
};
using CallPtr = std::shared_ptr<Call>;

// How a unary call of the core ends: exactly once, on any thread (the caller's own, perhaps,
// before the call returns), with the call's status; on OK the response is filled.
using Done = std::function<void(const absl::Status&)>;

// A server stream as the core writes it: the transport sends each message and tells when it
// is gone (or that the stream broke), and ends the stream with the status the core gives.
// One write at a time: Write is called again only after the last one's `written` ran.
template <class M>
class StreamWriter {
 public:
  virtual ~StreamWriter() = default;
  // Sends `*message`, which stays valid until `written` runs: with true once it is on its
  // way, false when the stream broke (then the core finishes it). `written` never runs
  // inside Write (the core calls Write from a scene's frame listener).
  virtual void Write(const M* message, std::function<void(bool)> written) = 0;
  // Ends the stream with `status`; the core's last call on the writer, made exactly once.
  virtual void Finish(const absl::Status& status) = 0;
};

// What the core counts of the calls it serves. Thread-safe.
struct CallCounter {
  explicit CallCounter(Metrics* metrics) : metrics(metrics) {}
  std::atomic<int> in_flight{0};
  Metrics* const metrics;  // null: none
};

// Counts a call in flight for as long as it lives, and records its method, status and
// duration in the metrics when it ends. Thread-safe.
class CallScope {
 public:
  CallScope(CallCounter* counter, const char* method);
  ~CallScope();  // a call that ended without a recorded status counts as OK
  CallScope(const CallScope&) = delete;
  CallScope& operator=(const CallScope&) = delete;

  // Records the call's status and duration, once, before the status goes out (so that a
  // client that has its answer finds it in the metrics).
  void Record(const absl::Status& s);

 private:
  CallCounter* const counter_;
  Metrics::Rpc* const rpc_;  // null: no metrics
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> recorded_{false};
};

}  // namespace gvd
