#include "render/scene/codec.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <array>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/kernel/exact3.h"
#include "render/kernel/path2.h"

namespace gvd {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the stored form is little-endian and written as the host's bytes");

// Format bytes: a change of layout takes a new one, and decoders keep reading the old ones.
constexpr uint8_t kSiteFormat = 1;
constexpr uint8_t kSettingsFormat = 1;
// A 3D scene's settings: format 1's fields, then its depth and z range. 2D scenes keep
// format 1, which every release reads.
constexpr uint8_t kSettingsFormat3 = 2;

// Geometry tags, one per alternative of Geometry; never reused.
// kApproximatePath: a path with an approximation (PathSite::approximation), which follows its
// tolerance; kPath has none.
enum Tag : uint8_t {
  kPoint = 1,
  kSegment = 2,
  kPolyline = 3,
  kPolygon = 4,
  kBezier = 5,
  kPath = 10,
  kApproximatePath = 11,
};
// And one per alternative of Geometry3.
enum Tag3 : uint8_t { kPoint3 = 6, kSegment3 = 7, kTriangle3 = 8, kMesh3 = 9 };

// Writes a record's bytes at `out`, which has room for them, or with `out` null only counts
// them: a record is put twice, counted and then written where its string has made room, so
// that each field is one copy and the string grows once a record.
class Writer {
 public:
  explicit Writer(char* out) : out_(out) {}
  size_t bytes() const { return bytes_; }
  template <class T>
  void Put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    Copy(&v, sizeof v);
  }
  void Put(Vec2 p) {
    Put(p.x);
    Put(p.y);
  }
  void Put(Vec3 p) {
    Put(p.x);
    Put(p.y);
    Put(p.z);
  }
  template <class T>
  void PutArray(const std::vector<T>& values) {
    Put(static_cast<uint32_t>(values.size()));
    Copy(values.data(), values.size() * sizeof(T));
  }
  void Put(std::string_view s) {
    Put(static_cast<uint32_t>(s.size()));
    Copy(s.data(), s.size());
  }
  void Put(const std::vector<Vec2>& points) {
    Put(static_cast<uint32_t>(points.size()));
    for (Vec2 p : points) Put(p);
  }

 private:
  void Copy(const void* from, size_t n) {
    if (out_ != nullptr && n != 0) std::memcpy(out_ + bytes_, from, n);
    bytes_ += n;
  }
  char* const out_;
  size_t bytes_ = 0;
};

// `put(writer)`'s bytes appended to `out`.
template <class F>
void Append(std::string* out, F&& put) {
  Writer count(nullptr);
  put(count);
  const size_t at = out->size();
  out->resize(at + count.bytes());
  Writer w(out->data() + at);
  put(w);
}

// Reads what Writer wrote; the first failure sticks and later reads return zeros.
class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  template <class T>
  T Get() {
    T v{};
    if (!Need(sizeof v)) return v;
    std::memcpy(&v, in_.data(), sizeof v);
    in_.remove_prefix(sizeof v);
    return v;
  }
  Vec2 GetVec2() {
    double x = Get<double>();
    return {x, Get<double>()};
  }
  Vec3 GetVec3() {
    const double x = Get<double>(), y = Get<double>();
    return {x, y, Get<double>()};
  }
  template <class T>
  std::vector<T> GetArray() {
    const uint32_t n = Get<uint32_t>();
    if (!Need(uint64_t{n} * sizeof(T))) return {};
    std::vector<T> values(n);
    std::memcpy(static_cast<void*>(values.data()), in_.data(), n * sizeof(T));
    in_.remove_prefix(n * sizeof(T));
    return values;
  }
  std::string GetString() { return std::string(GetView()); }
  // A string, as a view into what is read.
  std::string_view GetView() {
    uint32_t n = Get<uint32_t>();
    if (!Need(n)) return {};
    std::string_view s = in_.substr(0, n);
    in_.remove_prefix(n);
    return s;
  }
  // Whether everything was read, or a read failed.
  bool AtEnd() const { return !ok_ || in_.empty(); }
  std::vector<Vec2> GetPoints() {
    uint32_t n = Get<uint32_t>();
    if (!Need(uint64_t{n} * 16)) return {};
    std::vector<Vec2> points(n);
    for (Vec2& p : points) p = GetVec2();
    return points;
  }
  void Fail() { ok_ = false; }
  bool ok() const { return ok_; }
  // OK when every read fitted and nothing is left over.
  absl::Status Done(const char* what) const {
    if (ok_ && in_.empty()) return absl::OkStatus();
    return absl::DataLossError(absl::StrCat("a stored ", what, " is damaged"));
  }

 private:
  bool Need(uint64_t n) {
    if (!ok_ || n > in_.size()) ok_ = false;
    return ok_;
  }
  std::string_view in_;
  bool ok_ = true;
};

bool Finite(Vec2 p) { return std::isfinite(p.x) && std::isfinite(p.y); }
bool Finite(const std::vector<Vec2>& points) {
  for (Vec2 p : points) {
    if (!Finite(p)) return false;
  }
  return true;
}

// What every site's bytes begin with, in either dimension: the format, the id, the weights
// and the reach.
template <class S>
void PutHeader(Writer& w, const S& site) {
  w.Put(kSiteFormat);
  w.Put(std::string_view(site.id));
  w.Put(site.additive);
  w.Put(site.multiplicative);
  w.Put(site.max_distance);
}
template <class S>
void GetHeader(Reader& r, S* site) {
  if (r.Get<uint8_t>() != kSiteFormat) r.Fail();
  site->id = r.GetString();
  site->additive = r.Get<double>();
  site->multiplicative = r.Get<double>();
  site->max_distance = r.Get<double>();
}

// The id and weights every accepted site had.
template <class S>
bool WeightsKeepContract(const S& site) {
  return !site.id.empty() && std::isfinite(site.additive) && site.additive >= 0 &&
         std::isfinite(site.multiplicative) && site.multiplicative > 0 && site.max_distance > 0;
}

// Whether a decoded site keeps the contracts of Site and its geometry (render/kernel/site2.h), as
// every accepted site did: a stored one that does not was damaged after it was written.
bool KeepsContract(const Site& site) {
  if (!WeightsKeepContract(site)) return false;
  return std::visit(
      [](const auto& g) {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, PointSite>) return Finite(g.p);
        if constexpr (std::is_same_v<T, SegmentSite>) return Finite(g.a) && Finite(g.b);
        if constexpr (std::is_same_v<T, PolylineSite>) return g.points.size() >= 2 && Finite(g.points);
        if constexpr (std::is_same_v<T, PolygonSite>) return g.vertices.size() >= 3 && Finite(g.vertices);
        if constexpr (std::is_same_v<T, BezierSite>) {
          // A curve bent past what a double holds has an infinite tolerance (MakeBezier).
          return (g.control.size() == 3 || g.control.size() == 4) && Finite(g.control) &&
                 g.tolerance >= 0 && g.flat.size() >= 2 && Finite(g.flat);
        }
        if constexpr (std::is_same_v<T, PathSite>) return true;  // checked as decoded
      },
      site.geometry);
}

bool Finite(Vec3 p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

}  // namespace

namespace {

void PutSite(Writer& w, const Site3& site) {
  PutHeader(w, site);
  std::visit(
      [&w](const auto& g) {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, PointSite3>) {
          w.Put(kPoint3);
          w.Put(g.p);
        } else if constexpr (std::is_same_v<T, SegmentSite3>) {
          w.Put(kSegment3);
          w.Put(g.a);
          w.Put(g.b);
        } else if constexpr (std::is_same_v<T, TriangleSite3>) {
          w.Put(kTriangle3);
          w.Put(g.a);
          w.Put(g.b);
          w.Put(g.c);
        } else {
          static_assert(std::is_same_v<T, MeshSite3>);
          // The vertices and triangles as given; the edge tables and the tree are made again.
          w.Put(kMesh3);
          w.PutArray(g.vertices);
          w.PutArray(g.triangles);
        }
      },
      site.geometry);
}

void PutSite(Writer& w, const Site& site) {
  PutHeader(w, site);
  std::visit(
      [&w](const auto& g) {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, PointSite>) {
          w.Put(kPoint);
          w.Put(g.p);
        } else if constexpr (std::is_same_v<T, SegmentSite>) {
          w.Put(kSegment);
          w.Put(g.a);
          w.Put(g.b);
        } else if constexpr (std::is_same_v<T, PolylineSite>) {
          w.Put(kPolyline);
          w.Put(g.points);
        } else if constexpr (std::is_same_v<T, PolygonSite>) {
          w.Put(kPolygon);
          w.Put(static_cast<uint8_t>(g.side));
          w.Put(g.vertices);
        } else if constexpr (std::is_same_v<T, BezierSite>) {
          w.Put(kBezier);
          w.Put(g.tolerance);
          w.Put(g.control);
          w.Put(g.flat);
        } else {
          // Its subpaths as MakePath left them and its tolerance, from which MakePath
          // derives the rest again, and its approximation where it has one.
          static_assert(std::is_same_v<T, PathSite>);
          w.Put(g.approximation == 0 ? kPath : kApproximatePath);
          w.Put(static_cast<uint8_t>(g.fill));
          w.Put(static_cast<uint8_t>(g.side));
          w.Put(g.tolerance);
          if (g.approximation != 0) w.Put(g.approximation);
          w.Put(static_cast<uint32_t>(g.subpaths.size()));
          for (const Subpath& s : g.subpaths) {
            w.Put(static_cast<uint8_t>(s.closed));
            w.PutArray(s.degrees);
            w.Put(s.points);
          }
        }
      },
      site.geometry);
}

// A pack's entry: the id, then the site's bytes after their length.
template <class S>
void PutEntry(const S& site, std::string* pack) {
  Writer count(nullptr);
  PutSite(count, site);
  Append(pack, [&](Writer& w) {
    w.Put(std::string_view(site.id));
    w.Put(static_cast<uint32_t>(count.bytes()));
    PutSite(w, site);
  });
}

}  // namespace

std::string EncodeSite(const Site3& site) {
  std::string out;
  Append(&out, [&](Writer& w) { PutSite(w, site); });
  return out;
}

template <>
absl::StatusOr<Site3> DecodeSite<Site3>(std::string_view bytes) {
  Reader r(bytes);
  Site3 site;
  GetHeader(r, &site);
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  bool mesh = false;
  switch (r.Get<uint8_t>()) {
    case kPoint3:
      site.geometry = PointSite3{r.GetVec3()};
      break;
    case kSegment3: {
      const Vec3 a = r.GetVec3();
      site.geometry = SegmentSite3{a, r.GetVec3()};
      break;
    }
    case kTriangle3: {
      const Vec3 a = r.GetVec3(), b = r.GetVec3();
      site.geometry = TriangleSite3{a, b, r.GetVec3()};
      break;
    }
    case kMesh3:
      vertices = r.GetArray<Vec3>();
      triangles = r.GetArray<std::array<uint32_t, 3>>();
      mesh = true;
      break;
    default:
      r.Fail();
  }
  if (auto s = r.Done("site"); !s.ok()) return s;
  const absl::Status damaged = absl::DataLossError("a stored site is damaged");
  if (!WeightsKeepContract(site)) return damaged;
  if (mesh) {
    std::vector<double> xyz;
    xyz.reserve(vertices.size() * 3);
    for (Vec3 v : vertices) xyz.insert(xyz.end(), {v.x, v.y, v.z});
    std::vector<uint32_t> indices;
    indices.reserve(triangles.size() * 3);
    for (const auto& t : triangles) indices.insert(indices.end(), t.begin(), t.end());
    auto made = MakeMesh(xyz, indices, triangles.size());
    if (!made.ok()) return damaged;
    site.geometry = *std::move(made);
    return site;
  }
  const bool finite = std::visit(
      [](const auto& g) {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, PointSite3>) return Finite(g.p);
        if constexpr (std::is_same_v<T, SegmentSite3>) return Finite(g.a) && Finite(g.b);
        if constexpr (std::is_same_v<T, TriangleSite3>) return Finite(g.a) && Finite(g.b) && Finite(g.c);
        return true;
      },
      site.geometry);
  if (!finite) return damaged;
  return site;
}

std::string EncodeSite(const Site& site) {
  std::string out;
  Append(&out, [&](Writer& w) { PutSite(w, site); });
  return out;
}

template <>
absl::StatusOr<Site> DecodeSite<Site>(std::string_view bytes) {
  Reader r(bytes);
  Site site;
  GetHeader(r, &site);
  switch (const uint8_t tag = r.Get<uint8_t>(); tag) {
    case kPoint:
      site.geometry = PointSite{r.GetVec2()};
      break;
    case kSegment: {
      Vec2 a = r.GetVec2();
      site.geometry = SegmentSite{a, r.GetVec2()};
      break;
    }
    case kPolyline:
      site.geometry = PolylineSite{r.GetPoints()};
      break;
    case kPolygon: {
      uint8_t side = r.Get<uint8_t>();
      if (side > static_cast<uint8_t>(Side::kInside)) r.Fail();
      site.geometry = PolygonSite{r.GetPoints(), static_cast<Side>(side)};
      break;
    }
    case kBezier: {
      BezierSite b;
      b.tolerance = r.Get<double>();
      b.control = r.GetPoints();
      b.flat = r.GetPoints();
      site.geometry = std::move(b);
      break;
    }
    case kPath:
    case kApproximatePath: {
      const uint8_t fill = r.Get<uint8_t>(), side = r.Get<uint8_t>();
      const double tolerance = r.Get<double>();
      const double approximation = tag == kApproximatePath ? r.Get<double>() : 0.0;
      if (fill > static_cast<uint8_t>(FillRule::kEvenOdd) ||
          side > static_cast<uint8_t>(Side::kInside) || !(tolerance > 0) ||
          (tag == kApproximatePath && !(approximation > 0 && std::isfinite(approximation)))) {
        r.Fail();
      }
      // One by one: each takes bytes, so a damaged count cannot allocate past the input.
      std::vector<Subpath> subpaths;
      for (uint32_t n = r.Get<uint32_t>(); n > 0 && r.ok(); --n) {
        Subpath& s = subpaths.emplace_back();
        const uint8_t closed = r.Get<uint8_t>();
        if (closed > 1) r.Fail();
        s.closed = closed != 0;
        s.degrees = r.GetArray<uint8_t>();
        s.points = r.GetPoints();
      }
      // As MakePath left them: closed ones end at their start, and the tolerance is one it
      // keeps.
      bool as_left = r.ok() && PathContractError(subpaths, static_cast<Side>(side)).empty();
      for (const Subpath& s : subpaths) as_left = as_left && (!s.closed || s.points.back() == s.points.front());
      if (!as_left) {
        r.Fail();
        break;
      }
      PathSite path = MakePath(std::move(subpaths), static_cast<FillRule>(fill),
                               static_cast<Side>(side), tolerance);
      if (path.tolerance != tolerance) r.Fail();
      path.approximation = approximation;
      site.geometry = std::move(path);
      break;
    }
    default:
      r.Fail();
  }
  if (auto s = r.Done("site"); !s.ok()) return s;
  if (!KeepsContract(site)) return absl::DataLossError("a stored site is damaged");
  return site;
}

std::string EncodeSettings(const SceneSettings& s) {
  std::string out;
  Append(&out, [&](Writer& w) {
    w.Put(s.three_d() ? kSettingsFormat3 : kSettingsFormat);
    w.Put(std::string_view(s.id));
    w.Put(s.grid.window.min_x);
    w.Put(s.grid.window.min_y);
    w.Put(s.grid.window.max_x);
    w.Put(s.grid.window.max_y);
    w.Put(s.grid.width);
    w.Put(s.grid.height);
    w.Put(s.eps);
    w.Put(s.cone_triangles);
    w.Put(static_cast<uint8_t>(s.mode));
    w.Put(static_cast<uint8_t>(s.diagram));
    if (s.three_d()) {
      w.Put(s.depth);
      w.Put(s.min_z);
      w.Put(s.max_z);
    }
  });
  return out;
}

absl::StatusOr<SceneSettings> DecodeSettings(std::string_view bytes) {
  Reader r(bytes);
  const uint8_t format = r.Get<uint8_t>();
  if (format != kSettingsFormat && format != kSettingsFormat3) r.Fail();
  SceneSettings s;
  s.id = r.GetString();
  s.grid.window.min_x = r.Get<double>();
  s.grid.window.min_y = r.Get<double>();
  s.grid.window.max_x = r.Get<double>();
  s.grid.window.max_y = r.Get<double>();
  s.grid.width = r.Get<uint32_t>();
  s.grid.height = r.Get<uint32_t>();
  s.eps = r.Get<double>();
  s.cone_triangles = r.Get<uint32_t>();
  uint8_t mode = r.Get<uint8_t>();
  uint8_t diagram = r.Get<uint8_t>();
  if (mode > static_cast<uint8_t>(RenderMode::kExact) ||
      diagram > static_cast<uint8_t>(Diagram::kFarthest)) {
    r.Fail();
  }
  s.mode = static_cast<RenderMode>(mode);
  s.diagram = static_cast<Diagram>(diagram);
  if (format == kSettingsFormat3) {
    s.depth = r.Get<uint32_t>();
    s.min_z = r.Get<double>();
    s.max_z = r.Get<double>();
    if (s.depth == 0 || !(s.max_z - s.min_z > 0) || !std::isfinite(s.max_z - s.min_z)) r.Fail();
  }
  if (auto st = r.Done("scene"); !st.ok()) return st;
  // What every accepted scene had: an id, a window of positive finite size, pixels, an error
  // bound and enough triangles to make a cone.
  const Window& w = s.grid.window;
  if (s.id.empty() || !(w.max_x - w.min_x > 0) || !std::isfinite(w.max_x - w.min_x) ||
      !(w.max_y - w.min_y > 0) || !std::isfinite(w.max_y - w.min_y) || s.grid.width == 0 ||
      s.grid.height == 0 || !(s.eps > 0) || !std::isfinite(s.eps) || s.cone_triangles < 3) {
    return absl::DataLossError("a stored scene is damaged");
  }
  return s;
}

void AppendToPack(const Site& site, std::string* pack) { PutEntry(site, pack); }

void AppendToPack(const Site3& site, std::string* pack) { PutEntry(site, pack); }

absl::StatusOr<std::vector<PackEntry>> PackEntries(std::string_view pack) {
  Reader r(pack);
  std::vector<PackEntry> entries;
  while (!r.AtEnd()) {
    const std::string_view id = r.GetView();
    entries.push_back({id, r.GetView()});
  }
  if (auto s = r.Done("pack"); !s.ok()) return s;
  return entries;
}

}  // namespace gvd
