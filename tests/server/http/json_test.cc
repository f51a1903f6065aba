// The HTTP transport's JSON codec (server/http/json.h) against protobuf's own JSON mapping
// (util/json_util.h), an implementation apart: every message of the API filled at random,
// adversarial bodies, and bodies broken at random.
#include "server/http/json.h"

#include <gtest/gtest.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/field_comparator.h>
#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/message_differencer.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gvd/v1/voronoi.pb.h"

namespace gvd {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;
namespace util = google::protobuf::util;

// Equal as messages, NaN equal to NaN.
bool Same(const Message& a, const Message& b, std::string* diff) {
  util::DefaultFieldComparator numbers;
  numbers.set_treat_nan_as_equal(true);
  util::MessageDifferencer d;
  d.set_field_comparator(&numbers);
  d.ReportDifferencesToString(diff);
  return d.Compare(a, b);
}

// Every message type of the API, nested ones included.
std::vector<const Descriptor*> ApiTypes() {
  std::vector<const Descriptor*> out;
  const auto* file = v1::FindNearestRequest::descriptor()->file();
  std::vector<const Descriptor*> open;
  for (int i = 0; i < file->message_type_count(); ++i) open.push_back(file->message_type(i));
  while (!open.empty()) {
    const Descriptor* d = open.back();
    open.pop_back();
    out.push_back(d);
    for (int i = 0; i < d->nested_type_count(); ++i) open.push_back(d->nested_type(i));
  }
  return out;
}

std::unique_ptr<Message> New(const Descriptor* d) {
  return std::unique_ptr<Message>(
      google::protobuf::MessageFactory::generated_factory()->GetPrototype(d)->New());
}

// Values chosen to find the mapping's edges: extremes, 2^53 + 1, negative zero, the
// smallest subnormal, NaN and the infinities; strings with quotes, escapes, control
// characters, non-ASCII and astral characters.
class Filler {
 public:
  explicit Filler(uint64_t seed) : rng_(seed) {}

  void Fill(Message* m, int depth) {
    const Descriptor* d = m->GetDescriptor();
    const Reflection* r = m->GetReflection();
    for (int i = 0; i < d->field_count(); ++i) {
      const FieldDescriptor* f = d->field(i);
      if (Pick(3) == 0) continue;
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE && depth >= 3) continue;
      if (f->is_repeated()) {
        for (int n = static_cast<int>(Pick(4)); n > 0; --n) Add(m, r, f, depth);
      } else {
        Set(m, r, f, depth);
      }
    }
  }

 private:
  uint64_t Pick(uint64_t n) { return rng_() % n; }
  template <class T>
  T One(std::initializer_list<T> values) {
    return values.begin()[Pick(values.size())];
  }
  int64_t Int() {
    return One<int64_t>({0, 1, -1, 7, std::numeric_limits<int32_t>::min(),
                         std::numeric_limits<int32_t>::max(), (int64_t{1} << 53) + 1,
                         std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max(),
                         static_cast<int64_t>(rng_())});
  }
  double Real() {
    return One<double>({0.0, -0.0, 0.1, 1.0, -2.5, 1e300, -1e-300, 5e-324, 1e21, 123456789012345678.0,
                        std::numeric_limits<double>::quiet_NaN(), INFINITY, -INFINITY,
                        std::numeric_limits<double>::max(),
                        std::uniform_real_distribution<double>(-1e6, 1e6)(rng_)});
  }
  float Float() {
    return One<float>({0.0f, -0.0f, 0.1f, 1.0f, 3.4028235e38f, 1.4e-45f, 1e-38f, NAN, INFINITY,
                       -INFINITY, std::uniform_real_distribution<float>(-1e3f, 1e3f)(rng_)});
  }
  std::string Text() {
    static const char* kPieces[] = {"", "a", "site-7", "\"", "\\", "/", "\n\t\r", "\x01\x1f",
                                    "\x7f", "é", "日本", "\xf0\x9f\x98\x80", "</script>", " "};
    std::string s;
    for (int n = static_cast<int>(Pick(4)); n > 0; --n) s += kPieces[Pick(std::size(kPieces))];
    return s;
  }
  std::string Bytes() {
    std::string s(Pick(9), '\0');
    for (char& c : s) c = static_cast<char>(rng_());
    return s;
  }
  int Enum(const FieldDescriptor* f) {
    if (Pick(5) == 0) return 77;  // a number the type does not name
    const auto* e = f->enum_type();
    return e->value(static_cast<int>(Pick(e->value_count())))->number();
  }

  void Set(Message* m, const Reflection* r, const FieldDescriptor* f, int depth) {
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_INT32: r->SetInt32(m, f, static_cast<int32_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_INT64: r->SetInt64(m, f, Int()); break;
      case FieldDescriptor::CPPTYPE_UINT32: r->SetUInt32(m, f, static_cast<uint32_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_UINT64: r->SetUInt64(m, f, static_cast<uint64_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_DOUBLE: r->SetDouble(m, f, Real()); break;
      case FieldDescriptor::CPPTYPE_FLOAT: r->SetFloat(m, f, Float()); break;
      case FieldDescriptor::CPPTYPE_BOOL: r->SetBool(m, f, Pick(2) == 0); break;
      case FieldDescriptor::CPPTYPE_ENUM: r->SetEnumValue(m, f, Enum(f)); break;
      case FieldDescriptor::CPPTYPE_STRING:
        r->SetString(m, f, f->type() == FieldDescriptor::TYPE_BYTES ? Bytes() : Text());
        break;
      case FieldDescriptor::CPPTYPE_MESSAGE: Fill(r->MutableMessage(m, f), depth + 1); break;
    }
  }
  void Add(Message* m, const Reflection* r, const FieldDescriptor* f, int depth) {
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_INT32: r->AddInt32(m, f, static_cast<int32_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_INT64: r->AddInt64(m, f, Int()); break;
      case FieldDescriptor::CPPTYPE_UINT32: r->AddUInt32(m, f, static_cast<uint32_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_UINT64: r->AddUInt64(m, f, static_cast<uint64_t>(Int())); break;
      case FieldDescriptor::CPPTYPE_DOUBLE: r->AddDouble(m, f, Real()); break;
      case FieldDescriptor::CPPTYPE_FLOAT: r->AddFloat(m, f, Float()); break;
      case FieldDescriptor::CPPTYPE_BOOL: r->AddBool(m, f, Pick(2) == 0); break;
      case FieldDescriptor::CPPTYPE_ENUM: r->AddEnumValue(m, f, Enum(f)); break;
      case FieldDescriptor::CPPTYPE_STRING:
        r->AddString(m, f, f->type() == FieldDescriptor::TYPE_BYTES ? Bytes() : Text());
        break;
      case FieldDescriptor::CPPTYPE_MESSAGE: Fill(r->AddMessage(m, f), depth + 1); break;
    }
  }

  std::mt19937_64 rng_;
};

// The same JSON value, as protobuf's JSON parser reads both into a google.protobuf.Value:
// the same names, the same fields left out, the same strings; numbers within a float's
// precision, since protobuf writes a float with 9 digits and the codec with the fewest that
// read back to it (the typed round trips check the numbers exactly).
void ExpectSameJson(const std::string& ours, const std::string& theirs) {
  google::protobuf::Value a, b;
  ASSERT_TRUE(util::JsonStringToMessage(ours, &a).ok()) << ours;
  ASSERT_TRUE(util::JsonStringToMessage(theirs, &b).ok()) << theirs;
  util::DefaultFieldComparator numbers;
  numbers.set_treat_nan_as_equal(true);
  numbers.set_float_comparison(util::DefaultFieldComparator::APPROXIMATE);
  numbers.SetDefaultFractionAndMargin(1e-7, 1e-37);  // subnormal floats: 1 digit
  util::MessageDifferencer d;
  d.set_field_comparator(&numbers);
  std::string diff;
  d.ReportDifferencesToString(&diff);
  EXPECT_TRUE(d.Compare(a, b)) << diff << "\nours:   " << ours << "\ntheirs: " << theirs;
}

// Every message of the API, filled at random: written as protobuf writes it (the same JSON
// value), read back whole by protobuf and by the codec; protobuf's writing, with JSON or
// proto field names, read by the codec.
TEST(Json, EveryApiMessageBothWaysAgainstProtobuf) {
  Filler filler(20261128);
  int messages = 0;
  for (const Descriptor* type : ApiTypes()) {
    SCOPED_TRACE(type->full_name());
    for (int round = 0; round < 60; ++round) {
      auto m = New(type);
      filler.Fill(m.get(), 0);
      std::string theirs, theirs_named;
      ASSERT_TRUE(util::MessageToJsonString(*m, &theirs).ok());
      util::JsonPrintOptions named;
      named.preserve_proto_field_names = true;
      ASSERT_TRUE(util::MessageToJsonString(*m, &theirs_named, named).ok());
      const std::string ours = ToJson(*m);
      ExpectSameJson(ours, theirs);

      std::string diff;
      auto back = New(type);
      ASSERT_TRUE(util::JsonStringToMessage(ours, back.get()).ok()) << ours;
      EXPECT_TRUE(Same(*m, *back, &diff)) << diff << ours;
      // The codec's writing reads back whole; protobuf's as protobuf reads it (which takes
      // its own "-0" for the integer 0).
      for (const std::string* json : std::vector<const std::string*>{&ours, &theirs, &theirs_named}) {
        auto read = New(type), want = New(type);
        const absl::Status s = FromJson(*json, read.get());
        ASSERT_TRUE(s.ok()) << s << " in " << *json;
        if (json == &ours) {
          want->CopyFrom(*m);
        } else {
          ASSERT_TRUE(util::JsonStringToMessage(*json, want.get()).ok());
        }
        EXPECT_TRUE(Same(*want, *read, &diff)) << diff << *json;
      }
      ++messages;
    }
  }
  EXPECT_GT(messages, 1000);
}

// Bodies at the mapping's edges: read as protobuf reads them (the same message, or both
// refuse), but for the cases listed after them, where the codec is stricter on purpose.
TEST(Json, AdversarialBodiesAsProtobufReadsThem) {
  const std::vector<std::string> bodies = {
      R"({})", R"( {"sceneId" : "a" } )", R"({"scene_id": "a"})",
      R"({"minVersion": "18446744073709551615"})", R"({"minVersion": 18446744073709551615})",
      R"({"minVersion": "18446744073709551616"})", R"({"minVersion": -1})",
      R"({"minVersion": "-1"})", R"({"minVersion": 1e3})", R"({"minVersion": 1.5})",
      R"({"minVersion": "12"})", R"({"minVersion": true})", R"({"minVersion": null})",
      R"({"xy": [1, 2.5, -0, 1e-320, 1e308]})", R"({"xy": [1e309]})", R"({"xy": ["NaN", "Infinity", "-Infinity"]})",
      R"({"xy": ["nan"]})", R"({"xy": ["1.5"]})", R"({"xy": [{}]})",
      R"({"points": [{"x": 1}, {"y": "2"}]})", R"({"points": [1]})", R"({"exact": "true"})",
      R"({"exact": 1})", R"({"": 1})", R"({"xy": [-1e-3000]})",
      R"({"fields": ["NEAREST_FIELD_SITE", 3, "NO_SUCH_FIELD"]})", R"({"fields": [2147483648]})",
      R"({"unknown": {"deep": [1, {"x": [null]}]}, "sceneId": "b"})", R"({"sceneId": 5})",
      R"({"sceneId": "\u00e9\ud83d\ude00"})", R"({"sceneId": "\ud800"})", R"({"sceneId": "a\u0000b"})",
      "{\"sceneId\": \"\xff\"}", R"([])", R"("x")", R"(1)", R"(null)", R"({"sceneId": "a"} {})",
      R"({"sceneId": "a" /* c */})",
      std::string("{}\0{}", 5), R"({"chunkSize": 4294967295})", R"({"chunkSize": 4294967296})",
  };
  // Stricter than protobuf here, on purpose: what is not JSON (a trailing comma, single
  // quotes), what is not the mapping (a value or an object where an array belongs, arrays in
  // arrays, null in an array), a field given twice and two fields of a oneof (protobuf keeps
  // the last: one value silently lost).
  const std::vector<std::string> stricter = {
      R"({"sceneId": "a",})", R"({'sceneId': 'a'})", R"({"xy": 1})", R"({"points": {"x": 1}})",
      R"({"xy": [[1]]})", R"({"xy": [null]})", R"({"sceneId": "a", "sceneId": "b"})",
      R"({"sceneId": "a", "scene_id": "b"})",
  };
  for (const std::string& body : bodies) {
    SCOPED_TRACE(body);
    v1::FindNearestStreamRequest theirs, ours;
    util::JsonParseOptions options;
    options.ignore_unknown_fields = true;
    const auto t = util::JsonStringToMessage(body, &theirs, options);
    const absl::Status o = FromJson(body, &ours);
    EXPECT_EQ(o.ok(), t.ok()) << "ours: " << o << "\nprotobuf: " << t;
    std::string diff;
    if (o.ok() && t.ok()) {
      EXPECT_TRUE(Same(theirs, ours, &diff)) << diff;
    }
  }
  for (const std::string& body : stricter) {
    v1::FindNearestStreamRequest ours;
    EXPECT_FALSE(FromJson(body, &ours).ok()) << body;
  }
  v1::Site site;
  EXPECT_FALSE(FromJson(R"({"id": "a", "point": {"x": 1}, "segment": {}})", &site).ok());
}

// The same bytes as protobuf reads: the sign of a zero, an enum's number in a string, a float
// rounded through a double.
template <class M>
void ExpectTheSameBytes(const std::vector<std::string>& bodies) {
  for (const std::string& body : bodies) {
    SCOPED_TRACE(body);
    M theirs, ours;
    util::JsonParseOptions options;
    options.ignore_unknown_fields = true;
    ASSERT_TRUE(util::JsonStringToMessage(body, &theirs, options).ok());
    const absl::Status o = FromJson(body, &ours);
    ASSERT_TRUE(o.ok()) << o;
    EXPECT_EQ(ours.SerializeAsString(), theirs.SerializeAsString())
        << "ours: " << ours.ShortDebugString() << "\nprotobuf: " << theirs.ShortDebugString();
  }
}

TEST(Json, ZerosEnumNumbersAndFloatsAsProtobufReadsThem) {
  ExpectTheSameBytes<v1::Site>({R"({"maxDistance": -0})", R"({"maxDistance": "-0"})",
                                R"({"maxDistance": -0.0})", R"({"maxDistance": 0})"});
  ExpectTheSameBytes<v1::FindNearestRequest>(
      {R"({"fields": ["2", "NEAREST_FIELD_SITE", "99", 3]})", R"({"fields": ["+2"]})"});
  ExpectTheSameBytes<v1::GetClearanceFieldResponse>(
      {R"({"clearance": [1.0000000596046447753906250001, 3.4028235e38, -0, 1e-46]})"});
}

// Bodies broken at random (bytes dropped, doubled, replaced by JSON's punctuation): whatever
// the codec accepts, protobuf accepts and reads as the same message.
TEST(Json, BrokenBodiesAreNeverReadOtherwiseThanProtobufReadsThem) {
  Filler filler(7);
  std::mt19937_64 rng(11);
  const std::string punctuation = "{}[]\":,\\ 0-e.nt";
  int accepted = 0, refused = 0;
  for (int round = 0; round < 20000; ++round) {
    v1::UpsertSitesRequest m;
    filler.Fill(&m, 0);
    std::string body = ToJson(m);
    for (int k = 1 + static_cast<int>(rng() % 3); k > 0 && !body.empty(); --k) {
      const size_t at = rng() % body.size();
      switch (rng() % 3) {
        case 0: body.erase(at, 1); break;
        case 1: body.insert(at, 1, body[at]); break;
        default: body[at] = punctuation[rng() % punctuation.size()];
      }
    }
    v1::UpsertSitesRequest ours, theirs;
    if (!FromJson(body, &ours).ok()) {
      ++refused;
      continue;
    }
    ++accepted;
    util::JsonParseOptions options;
    options.ignore_unknown_fields = true;
    const auto t = util::JsonStringToMessage(body, &theirs, options);
    ASSERT_TRUE(t.ok()) << t << " in " << body;
    std::string diff;
    EXPECT_TRUE(Same(theirs, ours, &diff)) << diff << body;
  }
  EXPECT_GT(accepted, 100);
  EXPECT_GT(refused, 100);
}

// An error names the field's path in proto names, the value and what belongs there.
TEST(Json, ErrorsNameTheFieldsPath) {
  v1::UpsertSitesRequest m;
  absl::Status s = FromJson(R"({"sites": [{"id": "a"}, {"id": "b", "point": {"x": []}}]})", &m);
  EXPECT_EQ(s.message(), "sites[1].point.x: an array where a value of type double belongs");
  s = FromJson(R"({"sceneId": "s", "sites": [{"polyline": {"points": [{}, {"y": "up"}]}}]})", &m);
  EXPECT_EQ(s.message(), "sites[0].polyline.points[1].y: \"up\" is not a number");
  v1::CreateSceneRequest c;
  s = FromJson(R"({"widthPx": -3})", &c);
  EXPECT_EQ(s.message(), "width_px: -3 is not an unsigned 32-bit integer");
  s = FromJson(R"({"sceneId": "a", )", &c);
  EXPECT_EQ(s.message(), "Missing a name for object member. (byte 17)");
  s = FromJson(R"({"sceneId": "a", "sceneId": "a"})", &c);
  EXPECT_EQ(s.message(), "scene_id: given twice");
  std::string deep;
  for (int i = 0; i < 200; ++i) deep += R"({"polyline": {"points": [)";
  v1::Site site;
  EXPECT_FALSE(FromJson(deep, &site).ok());
}

TEST(Json, QuotedStringsReadBackAsTheirText) {
  for (const std::string text : {"", "plain", "\"quoted\"", "back\\slash", "\x01\n\t", "日本"}) {
    google::protobuf::Value v;
    ASSERT_TRUE(util::JsonStringToMessage(JsonQuote(text), &v).ok()) << JsonQuote(text);
    EXPECT_EQ(v.string_value(), text);
  }
  // Bytes that are no UTF-8 (a name cut inside a character, a stray byte): U+FFFD each.
  google::protobuf::Value v;
  const std::string cut = JsonQuote("ab\xe6\x97|\xff");
  ASSERT_TRUE(util::JsonStringToMessage(cut, &v).ok()) << cut;
  EXPECT_EQ(v.string_value(), "ab\uFFFD\uFFFD|\uFFFD");
}

// The codec's contract holds for every message the service takes or gives.
TEST(Json, CoversEveryMethodOfTheService) {
  const auto* service = v1::FindNearestRequest::descriptor()->file()->FindServiceByName(
      "VoronoiService");
  ASSERT_NE(service, nullptr);
  for (int i = 0; i < service->method_count(); ++i) {
    std::string why;
    EXPECT_TRUE(JsonCovers(service->method(i)->input_type(), &why)) << why;
    EXPECT_TRUE(JsonCovers(service->method(i)->output_type(), &why)) << why;
  }
  std::string why;
  EXPECT_FALSE(JsonCovers(google::protobuf::Struct::descriptor(), &why));
  EXPECT_EQ(why, "google.protobuf.Struct is a well-known type");
}

}  // namespace
}  // namespace gvd
