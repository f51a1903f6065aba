// Protobuf messages in the proto3 JSON mapping, as the Connect protocol's JSON codec carries
// them: the mapping of protobuf's util/json_util.h (which the tests hold this against), read
// and written through descriptors and reflection over RapidJSON's reader and writer, without
// the binary round trip and type resolution that cost json_util some 60,000 instructions a
// small message each way.
//
// CONTRACT: messages whose fields are scalars, enums, strings, bytes, messages and repeated
// fields of those. Maps and the well-known types (google.protobuf.*), which the mapping
// writes specially, are not read or written: JsonCovers() says whether a message type
// avoids them, and the codec's tests hold that for every method of the service.
// Thread-safe: no state between calls.
#ifndef GVD_SERVER_HTTP_JSON_H_
#define GVD_SERVER_HTTP_JSON_H_

#include <string>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace gvd {

// `message` as JSON, as json_util's MessageToJsonString writes it by default: one line,
// fields in number order under their JSON names, fields at their proto3 default left out,
// enums by name (by number where the value has no name), 64-bit integers as strings, NaN and
// the infinities as "NaN", "Infinity" and "-Infinity", bytes in base64. Numbers take the
// shortest form that reads back to the same value (1 for 1.0; negative zero -0.0, where
// json_util writes a "-0" that reads back as 0).
std::string ToJson(const google::protobuf::Message& message);

// Reads `json`, one JSON object, into `message` (cleared first), as json_util's
// JsonStringToMessage does with ignore_unknown_fields: fields by JSON name or proto name;
// unknown fields, and enum names the type lacks, ignored; null as the field's default;
// numbers also as strings, integers also as integral floating point ("1e3"), enums also by
// number; a bare -0 as 0 and a float as the double's rounding, as json_util reads them. It
// refuses what is not JSON or not the mapping (a trailing comma, single quotes, a value where
// an array belongs, null in an array) and what json_util would drop silently (a field given
// twice, a second field of a oneof). An error names the field's path in proto names
// (`sites[0].point.x`) and what is wrong, or the byte where the JSON breaks; `message` is
// then partly written.
absl::Status FromJson(absl::string_view json, google::protobuf::Message* message);

// `text` as a quoted JSON string.
std::string JsonQuote(absl::string_view text);

// Whether messages of `type` avoid maps and well-known types (see the contract), through
// every message field; where not, `*why` names the first field that does not.
bool JsonCovers(const google::protobuf::Descriptor* type, std::string* why);

}  // namespace gvd

#endif  // GVD_SERVER_HTTP_JSON_H_
