// Every method of gvd.v1.VoronoiService by name, over protobuf's generic messages: how a
// transport that reads a request by its method's descriptor (HTTP's JSON and binary bodies,
// gRPC's bytes) hands it to the core's function (service.h) of that method.
#pragma once

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string_view>

#include "absl/status/status.h"
#include "server/app/call.h"
#include "server/app/service.h"

namespace gvd {

// A server stream's messages as a transport sends them: it encodes each one (before `written`
// runs, the message is no longer read) and tells the core when it is on its way.
class StreamOut {
 public:
  virtual ~StreamOut() = default;
  // Sends `message`, which stays valid until `written` runs; the StreamWriter contract
  // (call.h) holds: one at a time, `written` never inside this call.
  virtual void Message(const google::protobuf::Message& message,
                       std::function<void(bool)> written) = 0;
  // Ends the stream with the core's status: the last call on it.
  virtual void End(const absl::Status& status) = 0;
};

struct Method {
  using Unary = std::function<void(Service*, CallPtr, const google::protobuf::Message&,
                                   google::protobuf::Message*, Done)>;
  using Streaming = std::function<void(Service*, CallPtr, const google::protobuf::Message&,
                                       std::shared_ptr<StreamOut>)>;
  const google::protobuf::MethodDescriptor* descriptor = nullptr;
  Unary unary;          // set for a unary method
  Streaming streaming;  // set for a server-streaming one
};

// The service's full name, "gvd.v1.VoronoiService".
extern const char* const kServiceName;
// The method of that name ("FindNearest"), or null where the service has none.
const Method* FindMethod(std::string_view name);
// A test hook of the transports, which convert large messages off the threads that serve
// every other call: when this environment variable names a path, a large conversion waits
// in HoldConversions while a file exists at that path (or until `stopping`), and a file at
// that path + ".waiting" exists while it waits; so tests can hold one for as long as they
// need and see the other calls served meanwhile.
inline constexpr const char* kHoldConversionsVariable = "GVD_TEST_HOLD_CONVERSIONS";
void HoldConversions(const std::atomic<bool>& stopping);

// A new empty message of `type` (a method's input or output type).
std::unique_ptr<google::protobuf::Message> NewMessage(const google::protobuf::Descriptor* type);

}  // namespace gvd
