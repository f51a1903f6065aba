// gvd-server's gRPC port: gvd.v1.VoronoiService, the standard health service
// (grpc.health.v1) and server reflection (grpc.reflection.v1alpha), a transport that only
// translates. Each call of the service is read by its method's descriptor
// (server/app/methods.h), handed to the application core (server/app/service.h) with a Call
// (the caller's "authorization" metadata; cancelled when the caller goes or its deadline
// passes) and finished with the core's status as the same gRPC code.
//
// Threads. One thread polls the server's one completion queue and starts every call: gRPC
// reads and writes the calls' bytes on it, and a call's answer from the core is sent from
// whichever thread the core answered on. One thread alone, so that no event goes from one
// poller to another (gRPC's callback API hands each event between two threads that poll one
// epoll set: 14 context switches a one-site move against 5 here). What would hold it up goes
// elsewhere: a request larger than kConvertHereBytes is parsed on a converter thread, and the
// core runs on it only what it answers at once (lookups, small writes: Service's threads).
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include <boost/asio/thread_pool.hpp>
#include <grpcpp/generic/async_generic_service.h>

#include "absl/status/statusor.h"
#include "server/app/service.h"

namespace gvd {

struct GrpcOptions {
  std::string listen = "127.0.0.1:0";  // host:port; port 0 picks one
  std::shared_ptr<grpc::ServerCredentials> credentials;  // null: plaintext
  // The largest message received or sent, its protobuf size (--max-message-bytes): a larger
  // request is refused by gRPC, a larger answer RESOURCE_EXHAUSTED naming the limit.
  size_t max_message_bytes = 64 << 20;
};

class GrpcServer {
 public:
  // The largest request parsed on the polling thread: a one-point query's is some 30 bytes, a
  // 100,000-point batch's 2 MB, whose parse would hold up every other call for milliseconds.
  static constexpr size_t kConvertHereBytes = 64 << 10;

  // Listens and serves `core`, which must outlive the server. Health says NOT_SERVING for
  // the server as a whole ("") until SetServing says otherwise.
  static absl::StatusOr<std::unique_ptr<GrpcServer>> Start(GrpcOptions options, Service* core);
  ~GrpcServer();  // Shutdown(now), unless it ran
  GrpcServer(const GrpcServer&) = delete;
  GrpcServer& operator=(const GrpcServer&) = delete;

  int port() const { return port_; }

  // grpc.health.v1: `service`'s status ("" the server as a whole), from now on; its Watch
  // streams hear each change. Without a name, every service known.
  void SetServing(const std::string& service, bool serving);
  void SetServing(bool serving);

  // Refuses new calls, lets those in flight run until `deadline`, then cancels them, and
  // returns once every call has ended and the polling thread has stopped. The core's
  // cancelled calls must still end (Service::Drain's cancellation ends them): a call's answer
  // is what it waits for.
  void Shutdown(std::chrono::system_clock::time_point deadline);

  class Exchange;  // one call (server.cc)

 private:
  GrpcServer(GrpcOptions options, Service* core);
  void Poll();
  void Request();  // one more call awaited
  void Ended();    // a call's Exchange is gone
  // grpc.health.v1's state; each Watch stream is an Exchange of its own.
  // HealthCheckResponse::ServingStatus; SERVICE_UNKNOWN for a service not known.
  int HealthStatus(const std::string& service);
  int HealthStatusLocked(const std::string& service) const;
  void Watch(Exchange* exchange, bool watching);
  void NotifyWatchesLocked();  // each watch of its service's status now

  const GrpcOptions options_;
  Service* const core_;
  grpc::AsyncGenericService generic_;
  std::unique_ptr<grpc::ServerCompletionQueue> cq_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::thread poller_;
  boost::asio::thread_pool converter_{1};

  std::atomic<bool> stopping_{false};  // set under mu_
  std::mutex mu_;  // guards what follows
  std::condition_variable ended_;
  bool stopped_ = false;
  int calls_ = 0;  // Exchanges alive, those awaiting a call included
  std::map<std::string, bool> serving_;
  std::set<Exchange*> watches_;
};

}  // namespace gvd
