#include "server/http/json.h"

#include <rapidjson/error/en.h>
#include <rapidjson/memorystream.h>
#include <rapidjson/reader.h>
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>

#include <charconv>
#include <cmath>
#include <limits>
#include <set>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace gvd {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;

// Into RapidJSON's own buffer, for which its writer reserves room for each token and then
// puts the token's bytes unchecked.
using Writer = rapidjson::Writer<rapidjson::StringBuffer>;

// A finite number in its shortest form that reads back to the same value.
template <class T>
void Number(Writer& w, T v) {
  if (std::isnan(v)) {
    w.String("NaN");
  } else if (std::isinf(v)) {
    w.String(v > 0 ? "Infinity" : "-Infinity");
  } else if (v == 0 && std::signbit(v)) {
    w.RawValue("-0.0", 4, rapidjson::kNumberType);  // "-0" reads as the integer 0
  } else {
    char buf[32];
    const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
    w.RawValue(buf, static_cast<size_t>(end - buf), rapidjson::kNumberType);
  }
}

void Write(Writer& w, const Message& m);

// Element `i` of repeated field `f`, or the singular field where i < 0.
void WriteValue(Writer& w, const Message& m, const Reflection& r, const FieldDescriptor* f, int i) {
  const bool rep = i >= 0;
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_INT32:
      w.Int(rep ? r.GetRepeatedInt32(m, f, i) : r.GetInt32(m, f));
      break;
    case FieldDescriptor::CPPTYPE_UINT32:
      w.Uint(rep ? r.GetRepeatedUInt32(m, f, i) : r.GetUInt32(m, f));
      break;
    case FieldDescriptor::CPPTYPE_INT64: {
      const std::string s = absl::StrCat(rep ? r.GetRepeatedInt64(m, f, i) : r.GetInt64(m, f));
      w.String(s.data(), static_cast<rapidjson::SizeType>(s.size()));
      break;
    }
    case FieldDescriptor::CPPTYPE_UINT64: {
      const std::string s = absl::StrCat(rep ? r.GetRepeatedUInt64(m, f, i) : r.GetUInt64(m, f));
      w.String(s.data(), static_cast<rapidjson::SizeType>(s.size()));
      break;
    }
    case FieldDescriptor::CPPTYPE_DOUBLE:
      Number(w, rep ? r.GetRepeatedDouble(m, f, i) : r.GetDouble(m, f));
      break;
    case FieldDescriptor::CPPTYPE_FLOAT:
      Number(w, rep ? r.GetRepeatedFloat(m, f, i) : r.GetFloat(m, f));
      break;
    case FieldDescriptor::CPPTYPE_BOOL:
      w.Bool(rep ? r.GetRepeatedBool(m, f, i) : r.GetBool(m, f));
      break;
    case FieldDescriptor::CPPTYPE_ENUM: {
      const int v = rep ? r.GetRepeatedEnumValue(m, f, i) : r.GetEnumValue(m, f);
      if (const auto* value = f->enum_type()->FindValueByNumber(v)) {
        w.String(value->name().data(), static_cast<rapidjson::SizeType>(value->name().size()));
      } else {
        w.Int(v);
      }
      break;
    }
    case FieldDescriptor::CPPTYPE_STRING: {
      std::string scratch;
      const std::string& s =
          rep ? r.GetRepeatedStringReference(m, f, i, &scratch) : r.GetStringReference(m, f, &scratch);
      if (f->type() == FieldDescriptor::TYPE_BYTES) {
        const std::string b64 = absl::Base64Escape(s);
        w.String(b64.data(), static_cast<rapidjson::SizeType>(b64.size()));
      } else {
        w.String(s.data(), static_cast<rapidjson::SizeType>(s.size()));
      }
      break;
    }
    case FieldDescriptor::CPPTYPE_MESSAGE:
      Write(w, rep ? r.GetRepeatedMessage(m, f, i) : r.GetMessage(m, f));
      break;
  }
}

void Write(Writer& w, const Message& m) {
  const Reflection& r = *m.GetReflection();
  std::vector<const FieldDescriptor*> fields;
  r.ListFields(m, &fields);  // the fields present, in number order
  w.StartObject();
  for (const FieldDescriptor* f : fields) {
    const std::string& name = f->json_name();
    w.Key(name.data(), static_cast<rapidjson::SizeType>(name.size()));
    if (f->is_repeated()) {
      w.StartArray();
      for (int i = 0, n = r.FieldSize(m, f); i < n; ++i) WriteValue(w, m, r, f, i);
      w.EndArray();
    } else {
      WriteValue(w, m, r, f, -1);
    }
  }
  w.EndObject();
}

// The value text of a JSON number or string, and which of the two it was.
struct Scalar {
  absl::string_view text;
  bool quoted;
};

// What RapidJSON's reader reports, written into the message as it comes: a stack of the
// messages open, each with the field its current key names.
class Reader : public rapidjson::BaseReaderHandler<rapidjson::UTF8<>, Reader> {
 public:
  static constexpr size_t kMaxDepth = 100;  // as json_util's parser

  explicit Reader(Message* root) : root_(root) {}

  const std::string& error() const { return error_; }

  bool StartObject() {
    if (skipping_ > 0) return ++skipping_, true;
    if (stack_.empty()) {  // the root (RapidJSON refuses a second one)
      stack_.push_back({root_});
      return true;
    }
    if (stack_.size() >= kMaxDepth) {
      return Fail(Path(), absl::StrCat("messages nested deeper than ", kMaxDepth));
    }
    Open& o = stack_.back();
    const FieldDescriptor* f = o.field;
    if (f->cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE) return Wrong("an object");
    if (f->is_repeated() && !o.in_array) return Wrong("an object");
    if (!Claim()) return false;
    const Reflection& r = *o.message->GetReflection();
    Message* sub = f->is_repeated() ? r.AddMessage(o.message, f) : r.MutableMessage(o.message, f);
    stack_.push_back({sub});
    return true;
  }
  bool Key(const char* s, rapidjson::SizeType n, bool) {
    if (skipping_ > 0) return true;
    Open& o = stack_.back();
    const absl::string_view key(s, n);
    if (key.empty()) return Fail(Path(), "a member with an empty name");
    const Descriptor* d = o.message->GetDescriptor();
    const std::string name(key);
    const FieldDescriptor* f = d->FindFieldByName(name);
    if (f == nullptr) f = d->FindFieldByCamelcaseName(name);
    if (f != nullptr && f->json_name() != key && f->name() != key) f = nullptr;
    o.field = f;
    o.in_array = false;
    o.index = 0;
    if (f == nullptr) {
      skipping_ = 1;  // its value, whatever it holds
      return true;
    }
    for (const FieldDescriptor* given : o.given) {
      if (given == f) return Fail(Path(), "given twice");
    }
    o.given.push_back(f);
    return true;
  }
  bool EndObject(rapidjson::SizeType) {
    if (skipping_ > 0) return Unskip();
    stack_.pop_back();
    return stack_.empty() || Value();  // a message value, counted in its parent
  }
  bool StartArray() {
    if (skipping_ > 0) return ++skipping_, true;
    if (stack_.empty()) return Fail("", "the body is a JSON array; it must be an object");
    Open& o = stack_.back();
    if (!o.field->is_repeated() || o.in_array) return Wrong("an array");
    if (!Claim()) return false;
    o.in_array = true;
    return true;
  }
  bool EndArray(rapidjson::SizeType) {
    if (skipping_ > 0) return Unskip();
    stack_.back().in_array = false;
    return true;
  }
  bool Null() {
    if (skipping_ > 0) return Skipped();
    if (stack_.empty()) return Root();
    Open& o = stack_.back();
    if (o.in_array) return Wrong("null");
    return Claim() && Value();  // the default: nothing written
  }
  bool Bool(bool b) {
    if (skipping_ > 0) return Skipped();
    if (stack_.empty()) return Root();
    if (stack_.back().field->cpp_type() != FieldDescriptor::CPPTYPE_BOOL) {
      return Wrong(b ? "true" : "false");
    }
    if (!Claim()) return false;
    Open& o = stack_.back();
    const Reflection& r = *o.message->GetReflection();
    if (o.field->is_repeated()) {
      r.AddBool(o.message, o.field, b);
    } else {
      r.SetBool(o.message, o.field, b);
    }
    return Value();
  }
  bool RawNumber(const char* s, rapidjson::SizeType n, bool) {
    if (skipping_ > 0) {  // a number past a double's range is refused even here
      double x;
      if (!Finite(absl::string_view(s, n), &x)) {
        return Fail("", absl::StrCat(absl::string_view(s, n), " is past a double's range"));
      }
      return Skipped();
    }
    if (stack_.empty()) return Root();
    return Set({absl::string_view(s, n), false});
  }
  bool String(const char* s, rapidjson::SizeType n, bool) {
    if (skipping_ > 0) return Skipped();
    if (stack_.empty()) return Root();
    return Set({absl::string_view(s, n), true});
  }

 private:
  struct Open {
    Message* message;
    const FieldDescriptor* field = nullptr;  // the current key's
    bool in_array = false;                   // inside the current key's array
    int index = 0;                           // the array's elements so far
    std::vector<const FieldDescriptor*> given;  // the fields named so far
  };

  // A scalar value for the current key (an element, inside its array).
  bool Set(Scalar v) {
    Open& o = stack_.back();
    const FieldDescriptor* f = o.field;
    if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
      return Wrong(v.quoted ? "a string" : "a number");
    }
    if (f->is_repeated() && !o.in_array) return Wrong(v.quoted ? "a string" : "a number");
    const Reflection& r = *o.message->GetReflection();
    Message* m = o.message;
    const bool rep = f->is_repeated();
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_INT32: {
        int64_t x;
        if (!Integer(v, &x) || x < std::numeric_limits<int32_t>::min() ||
            x > std::numeric_limits<int32_t>::max()) {
          return Bad(v, "a 32-bit integer");
        }
        if (!Claim()) return false;
        rep ? r.AddInt32(m, f, static_cast<int32_t>(x)) : r.SetInt32(m, f, static_cast<int32_t>(x));
        break;
      }
      case FieldDescriptor::CPPTYPE_INT64: {
        int64_t x;
        if (!Integer(v, &x)) return Bad(v, "a 64-bit integer");
        if (!Claim()) return false;
        rep ? r.AddInt64(m, f, x) : r.SetInt64(m, f, x);
        break;
      }
      case FieldDescriptor::CPPTYPE_UINT32: {
        uint64_t x;
        if (!Unsigned(v, &x) || x > std::numeric_limits<uint32_t>::max()) {
          return Bad(v, "an unsigned 32-bit integer");
        }
        if (!Claim()) return false;
        rep ? r.AddUInt32(m, f, static_cast<uint32_t>(x)) : r.SetUInt32(m, f, static_cast<uint32_t>(x));
        break;
      }
      case FieldDescriptor::CPPTYPE_UINT64: {
        uint64_t x;
        if (!Unsigned(v, &x)) return Bad(v, "an unsigned 64-bit integer");
        if (!Claim()) return false;
        rep ? r.AddUInt64(m, f, x) : r.SetUInt64(m, f, x);
        break;
      }
      case FieldDescriptor::CPPTYPE_DOUBLE: {
        double x;
        if (!Real(v, &x)) return Bad(v, "a number");
        if (!Claim()) return false;
        rep ? r.AddDouble(m, f, x) : r.SetDouble(m, f, x);
        break;
      }
      case FieldDescriptor::CPPTYPE_FLOAT: {
        float x;
        if (!Real(v, &x)) return Bad(v, "a 32-bit floating-point number");
        if (!Claim()) return false;
        rep ? r.AddFloat(m, f, x) : r.SetFloat(m, f, x);
        break;
      }
      case FieldDescriptor::CPPTYPE_BOOL: {  // in a string too, as protobuf reads it
        if (!v.quoted || (v.text != "true" && v.text != "false")) return Bad(v, "true or false");
        if (!Claim()) return false;
        rep ? r.AddBool(m, f, v.text == "true") : r.SetBool(m, f, v.text == "true");
        break;
      }
      case FieldDescriptor::CPPTYPE_ENUM: {
        int number;
        if (v.quoted) {
          const auto* value = f->enum_type()->FindValueByName(std::string(v.text));
          int32_t n;
          if (value == nullptr && Bare(v.text) && absl::SimpleAtoi(v.text, &n)) {
            value = f->enum_type()->FindValueByNumber(n);  // a known number, quoted
          }
          if (value == nullptr) {  // a newer client's value: ignored, as unknown fields are
            return Claim() && Value();
          }
          number = value->number();
        } else {
          int64_t x;
          if (!Integer(v, &x) || x < std::numeric_limits<int32_t>::min() ||
              x > std::numeric_limits<int32_t>::max()) {
            return Bad(v, absl::StrCat("a value of ", f->enum_type()->name()));
          }
          number = static_cast<int>(x);
        }
        if (!Claim()) return false;
        rep ? r.AddEnumValue(m, f, number) : r.SetEnumValue(m, f, number);
        break;
      }
      case FieldDescriptor::CPPTYPE_STRING: {
        if (!v.quoted) return Bad(v, "a string");
        std::string s;
        if (f->type() == FieldDescriptor::TYPE_BYTES) {
          if (!absl::Base64Unescape(v.text, &s) && !absl::WebSafeBase64Unescape(v.text, &s)) {
            return Bad(v, "base64");
          }
        } else {
          s.assign(v.text.data(), v.text.size());
        }
        if (!Claim()) return false;
        rep ? r.AddString(m, f, std::move(s)) : r.SetString(m, f, std::move(s));
        break;
      }
      case FieldDescriptor::CPPTYPE_MESSAGE:
        break;  // refused above
    }
    return Value();
  }

  // An integer from a number or a string: decimal digits, or an integral number in any
  // JSON form ("1e3", "2.0").
  static bool Integer(Scalar v, int64_t* out) {
    if (Bare(v.text) && v.text[0] != '+' && absl::SimpleAtoi(v.text, out)) return true;
    double d;
    if (!Finite(v.text, &d) || d != std::floor(d) || d < -0x1p63 || d >= 0x1p63) return false;
    *out = static_cast<int64_t>(d);
    return true;
  }
  static bool Unsigned(Scalar v, uint64_t* out) {
    if (Bare(v.text) && v.text[0] != '-' && v.text[0] != '+' && absl::SimpleAtoi(v.text, out)) {
      return true;
    }
    double d;
    if (!Finite(v.text, &d) || d != std::floor(d) || d < 0 || d >= 0x1p64) return false;
    *out = static_cast<uint64_t>(d);
    return true;
  }
  // A number, or one of the strings "NaN", "Infinity", "-Infinity", or a number in a string;
  // a finite one past T's range is refused, one below its smallest rounds to it or to 0.
  // A float is the double's rounding, as protobuf reads it. A bare -0 is the integer 0, as
  // protobuf reads it ("-0.0" and "-0" in a string are negative zero).
  template <class T>
  static bool Real(Scalar v, T* out) {
    if (v.quoted) {
      if (v.text == "NaN") return *out = std::numeric_limits<T>::quiet_NaN(), true;
      if (v.text == "Infinity") return *out = std::numeric_limits<T>::infinity(), true;
      if (v.text == "-Infinity") return *out = -std::numeric_limits<T>::infinity(), true;
    } else if (v.text == "-0") {
      return *out = 0, true;
    }
    double d;
    if (!Finite(v.text, &d)) return false;
    *out = static_cast<T>(d);
    return std::isfinite(*out);
  }
  // A finite number written as JSON writes one (no "inf", "nan", hexadecimal or '+').
  static bool Finite(absl::string_view text, double* out) {
    return Plain(text) && absl::SimpleAtod(text, out) && std::isfinite(*out);
  }
  // Text that absl's parsers read without trimming it: not empty, no whitespace.
  static bool Bare(absl::string_view text) {
    return !text.empty() && text.find_first_of(" \t\n\r") == absl::string_view::npos;
  }
  static bool Plain(absl::string_view text) {
    return !text.empty() && text[0] != '+' &&
           text.find_first_not_of("0123456789.eE+-") == absl::string_view::npos;
  }

  // Before a value is written: a second field of a oneof is refused.
  bool Claim() {
    Open& o = stack_.back();
    const FieldDescriptor* f = o.field;
    if (o.in_array) return true;
    if (const auto* oneof = f->containing_oneof(); oneof != nullptr && !f->is_repeated()) {
      const Reflection& r = *o.message->GetReflection();
      if (const FieldDescriptor* set = r.GetOneofFieldDescriptor(*o.message, oneof);
          set != nullptr && set != f) {
        return Fail(Path(), absl::StrCat("set beside ", set->name(), ", another field of oneof ",
                                         oneof->name()));
      }
    }
    return true;
  }
  // After a value: counted in its array.
  bool Value() {
    Open& o = stack_.back();
    if (o.in_array) ++o.index;
    return true;
  }

  bool Skipped() {
    if (skipping_ == 1) skipping_ = 0;
    return true;
  }
  bool Unskip() {
    if (--skipping_ == 1) skipping_ = 0;
    return true;
  }
  bool Root() { return Fail("", "the body must be a JSON object"); }

  bool Wrong(absl::string_view what) {
    const FieldDescriptor* f = stack_.back().field;
    std::string want;
    if (f->is_repeated() && !stack_.back().in_array) {
      want = "an array";
    } else if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
      want = absl::StrCat("an object (", f->message_type()->name(), ")");
    } else {
      want = absl::StrCat("a value of type ", f->type_name());
    }
    return Fail(Path(), absl::StrCat(what, " where ", want, " belongs"));
  }
  bool Bad(Scalar v, absl::string_view want) {
    return Fail(Path(), absl::StrCat(v.quoted ? JsonQuote(v.text) : std::string(v.text),
                                     " is not ", want));
  }
  bool Fail(std::string path, std::string what) {
    error_ = path.empty() ? std::move(what) : absl::StrCat(path, ": ", what);
    return false;
  }
  // The current field's path in proto names: `sites[0].point.x`.
  std::string Path() const {
    std::string p;
    for (size_t k = 0; k < stack_.size(); ++k) {
      const Open& o = stack_[k];
      if (o.field == nullptr) break;
      if (!p.empty()) p += '.';
      p += o.field->name();
      const bool inner = k + 1 < stack_.size();
      if (o.field->is_repeated() && (o.in_array || inner)) {
        // The element being written: an open message, or the scalar at hand.
        absl::StrAppend(&p, "[", o.index, "]");
      }
    }
    return p;
  }

  Message* const root_;
  std::vector<Open> stack_;
  int skipping_ = 0;  // > 0: inside the value of an unknown field, nested skipping_ - 1 deep
  std::string error_;
};

bool Covers(const Descriptor* type, std::set<const Descriptor*>* seen, std::string* why) {
  if (!seen->insert(type).second) return true;
  if (type->file()->package() == "google.protobuf") {
    *why = absl::StrCat(type->full_name(), " is a well-known type");
    return false;
  }
  for (int i = 0; i < type->field_count(); ++i) {
    const FieldDescriptor* f = type->field(i);
    if (f->is_map()) {
      *why = absl::StrCat(f->full_name(), " is a map");
      return false;
    }
    if (f->message_type() != nullptr && !Covers(f->message_type(), seen, why)) return false;
  }
  return true;
}

}  // namespace

std::string ToJson(const Message& message) {
  rapidjson::StringBuffer out;
  Writer w(out);
  Write(w, message);
  return std::string(out.GetString(), out.GetSize());
}

absl::Status FromJson(absl::string_view json, Message* message) {
  message->Clear();
  Reader handler(message);
  rapidjson::MemoryStream in(json.data(), json.size());
  rapidjson::Reader reader;
  constexpr unsigned kFlags = rapidjson::kParseIterativeFlag |
                              rapidjson::kParseValidateEncodingFlag |
                              rapidjson::kParseNumbersAsStringsFlag;
  const rapidjson::ParseResult result = reader.Parse<kFlags>(in, handler);
  if (!handler.error().empty()) return absl::InvalidArgumentError(handler.error());
  if (result.IsError()) {
    return absl::InvalidArgumentError(
        absl::StrCat(rapidjson::GetParseError_En(result.Code()), " (byte ", result.Offset(), ")"));
  }
  // RapidJSON takes a NUL byte for the end of its input.
  if (in.Tell() != json.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("a NUL byte where the JSON should end (byte ", in.Tell(), ")"));
  }
  return absl::OkStatus();
}

std::string JsonQuote(absl::string_view text) {
  // Each byte that is not part of well-formed UTF-8 (a name cut inside a character, say)
  // becomes U+FFFD, so that the JSON is well-formed too.
  std::string valid;
  valid.reserve(text.size());
  for (size_t i = 0; i < text.size();) {
    rapidjson::MemoryStream in(text.data() + i, text.size() - i);
    unsigned code_point;
    if (rapidjson::UTF8<>::Decode(in, &code_point) && in.Tell() <= text.size() - i) {
      valid.append(text.data() + i, in.Tell());
      i += in.Tell();
    } else {
      valid += "\xEF\xBF\xBD";
      ++i;
    }
  }
  rapidjson::StringBuffer out;
  Writer w(out);
  w.String(valid.data(), static_cast<rapidjson::SizeType>(valid.size()));
  return std::string(out.GetString(), out.GetSize());
}

bool JsonCovers(const Descriptor* type, std::string* why) {
  std::set<const Descriptor*> seen;
  return Covers(type, &seen, why);
}

}  // namespace gvd
