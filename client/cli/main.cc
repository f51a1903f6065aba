// gvd: the command-line client of gvd-server.
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include <charconv>
#include <cstdio>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "client/cli/cli.h"
#include "client/cli/model.h"
#include "client/flags/flags.h"
#include "gvd/client.h"

// The CLI's flags: where to connect, and the options of its commands (gvd --help says which
// command takes which), read by gvd::flags.
ABSL_FLAG(std::string, server, "127.0.0.1:50051", "<HOST:PORT> the server (or $GVD_SERVER)");
ABSL_FLAG(std::string, scene, "default", "<ID> the scene of sites and analysis commands (or $GVD_SCENE)");
ABSL_FLAG(std::string, token, "", "<TOKEN> a bearer token (or $GVD_TOKEN)");
ABSL_FLAG(std::string, tls_ca, "", "<FILE> connect over TLS, trusting this CA (PEM)");
ABSL_FLAG(std::string, tls_cert, "", "<FILE> a client certificate (PEM), with --tls-key");
ABSL_FLAG(std::string, tls_key, "", "<FILE> the client certificate's key (PEM)");
ABSL_FLAG(double, timeout, 30, "<SECONDS> each call's deadline");
ABSL_FLAG(uint64_t, memory_limit, 2048, "<MIB> what reading one file may take");
ABSL_FLAG(bool, json, false, "print the responses as JSON");
ABSL_FLAG(bool, exact, false, "certify each answer (nearest)");
ABSL_FLAG(bool, closest, false,
          "nearest: also each answer's closest point on its site and the distance's unit gradient");
ABSL_FLAG(std::string, window, "", "<MIN_X,MIN_Y,MAX_X,MAX_Y>");
ABSL_FLAG(std::string, size, "", "<WIDTHxHEIGHT>");
ABSL_FLAG(std::string, max_error, "", "<E>");
ABSL_FLAG(std::string, file, "", "<PATH>");
ABSL_FLAG(std::string, min_version, "", "<V>");
ABSL_FLAG(std::string, after, "", "<VERSION>");
ABSL_FLAG(std::string, render_mode, "", "<mesh|exact>");
ABSL_FLAG(std::string, diagram, "", "<nearest|farthest>");
ABSL_FLAG(std::string, side, "", "<outside|inside>");
ABSL_FLAG(std::string, tolerance, "", "<T>");
ABSL_FLAG(std::string, additive, "", "<A>");
ABSL_FLAG(std::string, multiplicative, "", "<M>");
ABSL_FLAG(std::string, max_distance, "", "<R>");
ABSL_FLAG(std::string, output, "", "<OUT> (or -o)");
ABSL_FLAG(std::string, layer, "", "<ids|features|distance>");
ABSL_FLAG(std::string, format, "", "<png|exr>");
ABSL_FLAG(std::string, method, "", "<full|continuation>");
ABSL_FLAG(std::string, from, "", "<X,Y>");
ABSL_FLAG(std::string, to, "", "<X,Y>");
ABSL_FLAG(std::string, radius, "", "<R>");
ABSL_FLAG(std::string, prefer, "", "<clearance|shortest>");
ABSL_FLAG(std::string, tiles, "", "<N>");
ABSL_FLAG(std::string, seed, "", "<S>");
ABSL_FLAG(std::string, z, "", "<Z> (render: the slice of a 3D scene holding Z)");
ABSL_FLAG(std::string, slice, "", "<K> (render: slice K of a 3D scene)");
ABSL_FLAG(bool, draw_sites, false, "");
ABSL_FLAG(bool, coarse, false, "");
ABSL_FLAG(bool, adaptive, false, "");
ABSL_FLAG(bool, mean, false, "");

namespace gvd::cli {
namespace {

Args ParseArgs(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (flags::WantsHelp(args)) {
    std::fputs(kUsage, stdout);
    std::exit(0);
  }
  for (std::string& arg : args) {
    if (arg == "-o") arg = "--output";
  }
  auto parsed = flags::Parse(args, /*words=*/true);
  if (!parsed.ok()) Usage(std::string(parsed.status().message()));
  Args a;
  a.words = std::move(parsed->words);
  // Where to connect and how: the flag, else the environment, else the default.
  auto setting = [&](const char* flag, const char* env, std::string value) {
    const char* from_env = std::getenv(env);
    return parsed->given.count(flag) || from_env == nullptr ? value : std::string(from_env);
  };
  a.server = setting("server", "GVD_SERVER", absl::GetFlag(FLAGS_server));
  a.scene = setting("scene", "GVD_SCENE", absl::GetFlag(FLAGS_scene));
  a.token = setting("token", "GVD_TOKEN", absl::GetFlag(FLAGS_token));
  a.tls_ca = absl::GetFlag(FLAGS_tls_ca);
  a.tls_cert = absl::GetFlag(FLAGS_tls_cert);
  a.tls_key = absl::GetFlag(FLAGS_tls_key);
  a.json = absl::GetFlag(FLAGS_json);
  a.exact = absl::GetFlag(FLAGS_exact);
  a.timeout = absl::GetFlag(FLAGS_timeout);
  if (!(a.timeout > 0)) {
    Usage(absl::StrCat("--timeout needs a positive number of seconds, not ", a.timeout));
  }
  const uint64_t memory_mib = absl::GetFlag(FLAGS_memory_limit);
  if (memory_mib == 0 || memory_mib > (uint64_t{1} << 40)) {
    Usage(absl::StrCat("--memory-limit needs a number of MiB from 1 to 2^40, not ", memory_mib));
  }
  a.memory_limit = memory_mib << 20;
  // The commands' options, as given (each command checks its own).
  static const std::set<std::string> kGlobal = {"server", "scene", "token", "tls-ca", "tls-cert",
                                                "tls-key", "timeout", "json", "exact",
                                                "memory-limit"};
  for (const auto& [name, value] : parsed->given) {
    if (!kGlobal.count(name)) a.options["--" + name] = value;
  }
  return a;
}

void PrintScene(const gvd::v1::Scene& s) {
  const auto& w = s.window();
  const bool space = s.depth_px() > 0;
  std::cout << "scene " << s.scene_id() << ": " << (space ? "box [" : "window [") << Num(w.min_x())
            << ", " << Num(w.max_x()) << "] x [" << Num(w.min_y()) << ", " << Num(w.max_y()) << "]"
            << (space ? absl::StrCat(" x [", Num(w.min_z()), ", ", Num(w.max_z()), "]") : "")
            << ", " << s.width_px() << "x" << s.height_px()
            << (space ? absl::StrCat("x", s.depth_px(), " voxels") : std::string(" px"))
            << ", max_error " << Num(s.max_error()) << ", "
            << (s.render_mode() == gvd::v1::RENDER_MODE_EXACT || space
                    ? std::string("exact render")
                    : absl::StrCat(s.cone_triangles(), " triangles per cone"))
            << ", version " << s.version() << ", "
            << s.site_count() << " sites, rendered version " << s.rendered_version()
            << (s.store_version() > 0
                    ? absl::StrCat(", store version ", s.store_version(), " (read ",
                                   Num(std::round(s.store_read_age_seconds() * 1000) / 1000),
                                   " s ago)")
                    : "")
            << "\n";
}

// Sites from a GeoJSON FeatureCollection: Point, LineString (a polyline, or a segment
// with two points) and Polygon (its outer ring; the closing repeat of the first point is
// dropped) features.
bool ReadGeoJson(const std::string& text, const std::string& path,
                 gvd::v1::UpsertSitesRequest* request, std::string* error) {
  using google::protobuf::ListValue;
  using google::protobuf::Struct;
  using google::protobuf::Value;
  Struct doc;
  if (auto st = google::protobuf::util::JsonStringToMessage(text, &doc); !st.ok()) {
    *error = absl::StrCat(path, ": ", st.message().as_string());
    return false;
  }
  auto fail = [&](size_t i, const std::string& why) {
    *error = absl::StrCat(path, ": features[", i, "]: ", why);
    return false;
  };
  auto point = [](const Value& v, gvd::v1::Point* p) {
    const ListValue& c = v.list_value();
    if (c.values_size() < 2 || !c.values(0).has_number_value() || !c.values(1).has_number_value()) {
      return false;
    }
    p->set_x(c.values(0).number_value());
    p->set_y(c.values(1).number_value());
    return true;
  };
  const auto found = doc.fields().find("features");
  if (found == doc.fields().end() || !found->second.has_list_value()) {
    *error = absl::StrCat(path, ": a FeatureCollection needs \"features\", an array");
    return false;
  }
  const auto& features = found->second.list_value();
  for (int i = 0; i < features.values_size(); ++i) {
    const Struct& f = features.values(i).struct_value();
    auto field = [&](const Struct& s, const std::string& k) -> const Value* {
      auto it = s.fields().find(k);
      return it == s.fields().end() ? nullptr : &it->second;
    };
    const Value* geometry = field(f, "geometry");
    const Value* props = field(f, "properties");
    const Struct empty;
    const Struct& p = props && props->has_struct_value() ? props->struct_value() : empty;
    auto* site = request->add_sites();
    const Value* id = field(f, "id");
    if (!id) id = field(p, "id");
    if (!id) return fail(i, "no id (set the feature's \"id\" or properties.id)");
    site->set_id(id->has_number_value() ? Num(id->number_value()) : id->string_value());
    if (!geometry || !geometry->has_struct_value()) return fail(i, "no geometry");
    const Value* type = field(geometry->struct_value(), "type");
    const Value* coords = field(geometry->struct_value(), "coordinates");
    if (!type || !coords) return fail(i, "geometry needs type and coordinates");
    const std::string& t = type->string_value();
    bool ok = true;
    if (t == "Point") {
      ok = point(*coords, site->mutable_point());
    } else if (t == "LineString") {
      for (const Value& v : coords->list_value().values()) {
        ok = ok && point(v, site->mutable_polyline()->add_points());
      }
    } else if (t == "Polygon" || t == "MultiPolygon") {
      // A ring's points, without the repeated first point that closes it.
      auto ring = [&](const Value& r, google::protobuf::RepeatedPtrField<gvd::v1::Point>* out) {
        for (const Value& v : r.list_value().values()) ok = ok && point(v, out->Add());
        const int n = out->size();
        if (n > 1 && out->Get(0).x() == out->Get(n - 1).x() && out->Get(0).y() == out->Get(n - 1).y()) {
          out->RemoveLast();
        }
      };
      std::vector<const Value*> rings;
      if (t == "Polygon") {
        for (const Value& r : coords->list_value().values()) rings.push_back(&r);
      } else {
        for (const Value& polygon : coords->list_value().values()) {
          for (const Value& r : polygon.list_value().values()) rings.push_back(&r);
        }
      }
      if (rings.empty()) return fail(i, "a polygon needs at least one ring");
      gvd::v1::Polygon::Side side = gvd::v1::Polygon::SIDE_UNSPECIFIED;
      if (const Value* s = field(p, "side")) {
        const std::string& sv = s->string_value();
        if (sv == "outside") side = gvd::v1::Polygon::SIDE_OUTSIDE;
        else if (sv == "inside") side = gvd::v1::Polygon::SIDE_INSIDE;
        else if (!sv.empty()) return fail(i, "properties.side must be \"outside\" or \"inside\"");
      }
      if (rings.size() == 1) {  // a polygon
        ring(*rings[0], site->mutable_polygon()->mutable_vertices());
        site->mutable_polygon()->set_side(side);
      } else {  // one path of closed rings of lines: holes by the even-odd rule
        auto* path = site->mutable_path();
        for (const Value* r : rings) {
          auto* sub = path->add_subpaths();
          ring(*r, sub->mutable_points());
          sub->set_closed(true);
        }
        path->set_fill_rule(gvd::v1::Path::FILL_RULE_EVEN_ODD);
        path->set_side(side);
      }
    } else {
      return fail(i, absl::StrCat("geometry type ", t,
                                  " is not supported (Point, LineString, Polygon, MultiPolygon)"));
    }
    if (!ok) return fail(i, "coordinates must be [x, y] numbers");
    if (const Value* v = field(p, "additive_weight")) site->set_additive_weight(v->number_value());
    if (const Value* v = field(p, "multiplicative_weight")) {
      site->set_multiplicative_weight(v->number_value());
    }
    if (const Value* v = field(p, "max_distance")) site->set_max_distance(v->number_value());
  }
  return true;
}

// Reading a site list takes up to this many times its size (GeoJSON's, the most: 13.5 times
// for 400,000 points).
constexpr uint64_t kSiteListFactor = 16;

// Reads sites from JSON (an array of Site, or {"sites": [...]}), GeoJSON, or "ID X Y" lines.
bool ReadSites(const Args& a, const std::string& path, gvd::v1::UpsertSitesRequest* request,
               std::string* error) {
  std::string text;
  if (!ReadFileWithin(a, path, kSiteListFactor, &text, error)) return false;
  size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '{' &&
      text.find("\"FeatureCollection\"") != std::string::npos) {
    return ReadGeoJson(text, path, request, error);
  }
  if (first != std::string::npos && (text[first] == '[' || text[first] == '{')) {
    std::string json = text[first] == '[' ? absl::StrCat("{\"sites\": ", text, "}") : text;
    auto st = google::protobuf::util::JsonStringToMessage(json, request);
    if (!st.ok()) {
      *error = absl::StrCat(path, ": ", st.message().as_string());
      return false;
    }
    return true;
  }
  std::istringstream lines(text);
  std::string line;
  for (int n = 1; std::getline(lines, line); ++n) {
    std::vector<std::string> f = absl::StrSplit(line, absl::ByAnyChar(" \t,"), absl::SkipEmpty());
    if (f.empty() || f[0][0] == '#') continue;
    double x, y;
    if (f.size() != 3 || !absl::SimpleAtod(f[1], &x) || !absl::SimpleAtod(f[2], &y)) {
      *error = absl::StrCat(path, ":", n, ": expected \"ID X Y\", got \"", line, "\"");
      return false;
    }
    auto* site = request->add_sites();
    site->set_id(f[0]);
    site->mutable_point()->set_x(x);
    site->mutable_point()->set_y(y);
  }
  return true;
}

// The client's options from the flags: the timeout, the token and the TLS files, read.
ClientOptions OptionsOf(const Args& a) {
  ClientOptions options;
  options.timeout = std::chrono::milliseconds(static_cast<int64_t>(a.timeout * 1000));
  options.token = a.token;
  auto read = [&](const std::string& flag, const std::string& path) {
    std::string text, error;
    if (!ReadFileWithin(a, path, 1, &text, &error)) Usage(absl::StrCat(flag, ": ", error));
    return text;
  };
  if (!a.tls_ca.empty()) options.tls_ca = read("--tls-ca", a.tls_ca);
  if (!a.tls_cert.empty()) options.tls_cert = read("--tls-cert", a.tls_cert);
  if (!a.tls_key.empty()) options.tls_key = read("--tls-key", a.tls_key);
  return options;
}

[[noreturn]] void Unknown(const Args& a) {
  Usage(absl::StrCat("unknown command \"", absl::StrJoin(a.words, " "), "\""));
}

// Usage naming the command's form unless it has exactly n words.
void Need(const Args& a, size_t n, const char* form) {
  if (a.words.size() != n) Usage(absl::StrCat("usage: gvd ", form));
}

int SceneCommand(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() < 2) Unknown(a);
  const std::string& verb = w[1];
  if (verb == "create") {
    Need(a, 3, "scene create ID --window MIN_X,MIN_Y,MAX_X,MAX_Y --size WxH [--max-error E]");
    gvd::v1::CreateSceneRequest r;
    r.set_scene_id(w[2]);
    const std::string* window = Option(a, "--window");
    const std::string* size = Option(a, "--size");
    if (!window || !size) Usage("scene create needs --window and --size");
    ParseWindow(*window, r.mutable_window());
    uint32_t width, height, depth;
    ParseSize(*size, &width, &height, &depth);
    r.set_width_px(width);
    r.set_height_px(height);
    r.set_depth_px(depth);
    if (const std::string* e = Option(a, "--max-error")) r.set_max_error(Number(*e, "--max-error"));
    if (const std::string* m = Option(a, "--render-mode")) {
      if (*m != "mesh" && *m != "exact") Usage("--render-mode must be mesh or exact");
      r.set_render_mode(*m == "exact" ? gvd::v1::RENDER_MODE_EXACT : gvd::v1::RENDER_MODE_MESH);
    }
    if (const std::string* d = Option(a, "--diagram")) {
      if (*d != "nearest" && *d != "farthest") Usage("--diagram must be nearest or farthest");
      r.set_diagram(*d == "farthest" ? gvd::v1::DIAGRAM_FARTHEST : gvd::v1::DIAGRAM_NEAREST);
    }
    gvd::v1::Scene scene;
    if (auto s = client.CreateScene(r, &scene); !s.ok()) return Fail(s);
    a.json ? PrintJson(scene) : PrintScene(scene);
    return 0;
  }
  if (verb == "get") {
    Need(a, 3, "scene get ID");
    gvd::v1::Scene scene;
    if (auto s = client.GetScene(w[2], &scene); !s.ok()) return Fail(s);
    a.json ? PrintJson(scene) : PrintScene(scene);
    return 0;
  }
  if (verb == "ls") {
    Need(a, 2, "scene ls");
    std::vector<gvd::v1::Scene> scenes;
    if (auto s = client.ListScenes(&scenes); !s.ok()) return Fail(s);
    gvd::v1::ListScenesResponse all;
    for (auto& s : scenes) a.json ? void(*all.add_scenes() = s) : PrintScene(s);
    if (a.json) PrintJson(all);
    return 0;
  }
  if (verb == "rm") {
    Need(a, 3, "scene rm ID");
    if (auto s = client.DeleteScene(w[2]); !s.ok()) return Fail(s);
    std::cout << "deleted scene " << w[2] << "\n";
    return 0;
  }
  Unknown(a);
}

int WatchCommand(const Args& a, Client& client) {
  const auto& w = a.words;
  Need(a, 2, "watch SCENE [--after VERSION]");
  gvd::v1::WatchSceneRequest r;
  r.set_scene_id(w[1]);
  if (const std::string* after = Option(a, "--after")) {
    uint64_t v;
    if (!absl::SimpleAtoi(*after, &v)) Usage(absl::StrCat("--after needs a version, not \"", *after, "\""));
    r.set_after_version(v);
  }
  auto s = client.WatchScene(r, [&](const gvd::v1::WatchSceneResponse& e) {
    if (a.json) {
      std::string line;
      google::protobuf::util::JsonPrintOptions o;
      (void)google::protobuf::util::MessageToJsonString(e, &line, o);
      std::cout << line << std::endl;
    } else if (e.deleted()) {
      std::cout << "scene " << e.scene_id() << " deleted" << std::endl;
    } else if (e.reloaded()) {
      std::cout << "scene " << e.scene_id()
                << " reloaded: the store went back in time; watch it again" << std::endl;
    } else {
      std::cout << "version " << e.version() << ": ";
      if (e.has_changed()) {
        const auto& c = e.changed();
        std::cout << "changed [" << c.min_x() << ", " << c.max_x() << "] x [" << c.min_y()
                  << ", " << c.max_y() << "]";
      } else {
        std::cout << "nothing changed";
      }
      std::cout << ", " << e.site_count() << " sites" << std::endl;
    }
    return true;
  });
  return s.ok() ? 0 : Fail(s);
}

int SitesCommand(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() < 2) Unknown(a);
  const std::string& verb = w[1];
  if (verb == "add") {
    gvd::v1::UpsertSitesRequest r;
    static const std::set<std::string> kSpace = {"point", "triangle", "mesh"};
    const std::string* file = Option(a, "--file");
    // "point" and "triangle" name 3D kinds when their points are X,Y,Z words; otherwise
    // they may be a point site's id ("sites add point 1 2").
    const bool space_kind = w.size() >= 3 && kSpace.count(w[2]) > 0 &&
                            (w[2] == "mesh" || (w.size() >= 5 && absl::StrContains(w[4], ',')));
    std::string model;  // the model file a mesh came from
    if (space_kind) {
      // 3D sites: ID and X,Y,Z points; a mesh from a model file.
      if (w.size() < 4) Usage(absl::StrCat("sites add ", w[2], " needs an ID"));
      auto* site = r.add_sites();
      site->set_id(w[3]);
      if (w[2] == "mesh") {
        if (!file || w.size() != 4) Usage("usage: gvd sites add mesh ID --file MODEL");
        std::string error;
        if (!ReadModel({.path = *file}, {.memory_bytes = a.memory_limit}, site->mutable_mesh(), &error)) {
          std::fprintf(stderr, "gvd: %s\n", error.c_str());
          return 2;
        }
        model = *file;
      } else {
        if (file) Usage(absl::StrCat("sites add ", w[2], " takes no --file"));
        const size_t n = w[2] == "point" ? 1 : 3;
        if (w.size() != 4 + n) Usage(absl::StrCat("usage: gvd sites add ", w[2], " ID", n == 1 ? " X,Y,Z" : " X,Y,Z X,Y,Z X,Y,Z"));
        if (n == 1) {
          ParsePoint3(w[4], site->mutable_point());
        } else {
          ParsePoint3(w[4], site->mutable_triangle()->mutable_a());
          ParsePoint3(w[5], site->mutable_triangle()->mutable_b());
          ParsePoint3(w[6], site->mutable_triangle()->mutable_c());
        }
      }
      file = nullptr;
    }
    if (file) {
      std::string error;
      if (!ReadSites(a, *file, &r, &error)) {
        std::fprintf(stderr, "gvd: %s\n", error.c_str());
        return 2;
      }
    }
    r.set_scene_id(a.scene);  // after ReadSites: parsing JSON resets the message
    static const std::set<std::string> kKinds = {"segment", "polyline", "polygon", "bezier"};
    if (w.size() >= 3 && kKinds.count(w[2])) {
      if (w.size() < 5) Usage(absl::StrCat("sites add ", w[2], " needs ID and points X,Y"));
      auto* site = r.add_sites();
      site->set_id(w[3]);
      std::vector<gvd::v1::Point> pts;
      for (size_t i = 4; i < w.size(); ++i) {
        std::vector<std::string> xy = absl::StrSplit(w[i], ',');
        pts.emplace_back();
        if (xy.size() == 3 && w[2] == "segment") {  // a 3D scene's segment
          ParsePoint3(w[i], &pts.back());
          continue;
        }
        if (xy.size() != 2) Usage(absl::StrCat("points are X,Y, not \"", w[i], "\""));
        pts.back().set_x(Number(xy[0], "X"));
        pts.back().set_y(Number(xy[1], "Y"));
      }
      if (w[2] == "segment") {
        if (pts.size() != 2) Usage("sites add segment ID X,Y X,Y");
        *site->mutable_segment()->mutable_a() = pts[0];
        *site->mutable_segment()->mutable_b() = pts[1];
      } else if (w[2] == "polyline") {
        for (auto& q : pts) *site->mutable_polyline()->add_points() = q;
      } else if (w[2] == "polygon") {
        for (auto& q : pts) *site->mutable_polygon()->add_vertices() = q;
        if (const std::string* side = Option(a, "--side")) {
          if (*side != "outside" && *side != "inside") Usage("--side must be outside or inside");
          site->mutable_polygon()->set_side(*side == "outside" ? gvd::v1::Polygon::SIDE_OUTSIDE
                                                               : gvd::v1::Polygon::SIDE_INSIDE);
        }
      } else {
        for (auto& q : pts) *site->mutable_bezier()->add_control_points() = q;
        if (const std::string* t = Option(a, "--tolerance")) {
          site->mutable_bezier()->set_tolerance(Number(*t, "--tolerance"));
        }
      }
    } else if (!space_kind) {
      if ((w.size() - 2) % 3 != 0) Usage("sites add takes triples ID X Y");
      for (size_t i = 2; i + 2 < w.size(); i += 3) {
        auto* site = r.add_sites();
        site->set_id(w[i]);
        site->mutable_point()->set_x(Number(w[i + 1], "X"));
        site->mutable_point()->set_y(Number(w[i + 2], "Y"));
      }
    }
    if (r.sites_size() == 0) Usage("sites add needs ID X Y triples, a kind, or --file");
    for (auto& site : *r.mutable_sites()) {
      if (const std::string* v = Option(a, "--additive")) site.set_additive_weight(Number(*v, "--additive"));
      if (const std::string* v = Option(a, "--multiplicative")) {
        site.set_multiplicative_weight(Number(*v, "--multiplicative"));
      }
      if (const std::string* v = Option(a, "--max-distance")) site.set_max_distance(Number(*v, "--max-distance"));
    }
    uint64_t version = 0;
    if (auto s = client.UpsertSites(r, &version); !s.ok()) {
      // A model refused (over a limit, say) names its file too.
      if (!model.empty()) {
        return Fail(grpc::Status(s.error_code(), absl::StrCat(model, ": ", s.error_message())));
      }
      return Fail(s);
    }
    std::cout << "upserted " << r.sites_size() << " sites; scene " << a.scene << " is at version "
              << version << "\n";
    return 0;
  }
  if (verb == "rm") {
    if (w.size() < 3) Usage("usage: gvd sites rm ID [ID ...]");
    uint64_t version = 0;
    std::vector<std::string> ids(w.begin() + 2, w.end());
    if (auto s = client.DeleteSites(a.scene, ids, &version); !s.ok()) return Fail(s);
    std::cout << "deleted " << ids.size() << " sites; scene " << a.scene << " is at version "
              << version << "\n";
    return 0;
  }
  if (verb == "ls") {
    Need(a, 2, "sites ls");
    std::vector<gvd::v1::Site> sites;
    if (auto s = client.ListAllSites(a.scene, &sites); !s.ok()) return Fail(s);
    if (a.json) {
      gvd::v1::ListSitesResponse all;
      for (auto& s : sites) *all.add_sites() = s;
      PrintJson(all);
      return 0;
    }
    auto xyz = [](const gvd::v1::Point& p) {
      return absl::StrCat(Num(p.x()), ",", Num(p.y()), ",", Num(p.z()));
    };
    for (const auto& s : sites) {
      // 3D sites: a point or a segment with a z, a triangle, a mesh (its size).
      const bool space = (s.has_point() && s.point().z() != 0) ||
                         (s.has_segment() && (s.segment().a().z() != 0 || s.segment().b().z() != 0));
      if (space && s.has_point()) {
        std::cout << s.id() << "\tpoint\t" << xyz(s.point()) << "\n";
        continue;
      }
      if (space) {
        std::cout << s.id() << "\tsegment\t" << xyz(s.segment().a()) << "\t" << xyz(s.segment().b()) << "\n";
        continue;
      }
      if (s.has_triangle()) {
        std::cout << s.id() << "\ttriangle\t" << xyz(s.triangle().a()) << "\t" << xyz(s.triangle().b())
                  << "\t" << xyz(s.triangle().c()) << "\n";
        continue;
      }
      if (s.has_mesh()) {
        std::cout << s.id() << "\tmesh\t" << s.mesh().xyz_size() / 3 << " vertices\t"
                  << s.mesh().triangles_size() / 3 << " triangles\n";
        continue;
      }
      if (s.has_point()) {
        std::cout << s.id() << "\t" << Num(s.point().x()) << "\t" << Num(s.point().y()) << "\n";
        continue;
      }
      if (s.has_path()) {  // as SVG's path data: M start, then L, Q or C a piece; Z closes
        std::cout << s.id() << "\tpath\t";
        auto at = [](const gvd::v1::Point& q) { return absl::StrCat(Num(q.x()), ",", Num(q.y())); };
        const char* space = "";
        for (const auto& sub : s.path().subpaths()) {
          std::cout << space << "M " << at(sub.points(0));
          int k = 1;
          for (uint32_t d : sub.degrees()) {
            // A closed subpath's last line, back to its start, is its Z.
            if (sub.closed() && d == 1 && k + 1 == sub.points_size()) break;
            std::cout << " " << (d == 1 ? "L" : d == 2 ? "Q" : "C");
            for (uint32_t i = 0; i < d; ++i) std::cout << " " << at(sub.points(k++));
          }
          if (sub.closed()) std::cout << " Z";
          space = " ";
        }
        std::cout << "\n";
        continue;
      }
      std::vector<gvd::v1::Point> pts;
      std::string kind;
      if (s.has_segment()) {
        kind = "segment";
        pts = {s.segment().a(), s.segment().b()};
      } else if (s.has_polyline()) {
        kind = "polyline";
        pts.assign(s.polyline().points().begin(), s.polyline().points().end());
      } else if (s.has_polygon()) {
        kind = "polygon";
        pts.assign(s.polygon().vertices().begin(), s.polygon().vertices().end());
      } else if (s.has_bezier()) {
        kind = "bezier";
        pts.assign(s.bezier().control_points().begin(), s.bezier().control_points().end());
      }
      std::cout << s.id() << "\t" << kind;
      for (const auto& q : pts) std::cout << "\t" << Num(q.x()) << "," << Num(q.y());
      std::cout << "\n";
    }
    return 0;
  }
  Unknown(a);
}

int HealthCommand(const Args& a, Client&) {
  const ClientOptions options = OptionsOf(a);
  Need(a, 1, "health");
  grpc::ChannelArguments args;
  auto channel = grpc::CreateCustomChannel(
      a.server,
      options.tls_ca.empty() ? grpc::InsecureChannelCredentials()
                             : grpc::SslCredentials({options.tls_ca, options.tls_key, options.tls_cert}),
      args);
  auto stub = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + options.timeout);
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  if (auto s = stub->Check(&ctx, request, &response); !s.ok()) return Fail(s);
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()) << "\n";
  return response.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

int NearestCommand(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() < 3) Usage("usage: gvd nearest X Y [X Y ...] (X Y Z in a 3D scene)");
  // A 3D scene's points are X Y Z triples: the scene says which.
  gvd::v1::Scene scene;
  if (auto s = client.GetScene(a.scene, &scene); !s.ok()) return Fail(s);
  const size_t dims = scene.depth_px() > 0 ? 3 : 2;
  if (w.size() < 1 + dims || (w.size() - 1) % dims != 0) {
    Usage(dims == 3 ? "usage: gvd nearest X Y Z [X Y Z ...] (a 3D scene)"
                    : "usage: gvd nearest X Y [X Y ...]");
  }
  gvd::v1::FindNearestRequest r;
  r.set_scene_id(a.scene);
  for (size_t i = 1; i + dims - 1 < w.size(); i += dims) {
    auto* p = r.add_points();
    p->set_x(Number(w[i], "X"));
    p->set_y(Number(w[i + 1], "Y"));
    if (dims == 3) p->set_z(Number(w[i + 2], "Z"));
  }
  if (const std::string* v = Option(a, "--min-version")) {
    uint64_t mv;
    if (!absl::SimpleAtoi(*v, &mv)) Usage("--min-version needs a version number");
    r.set_min_version(mv);
  }
  r.set_exact(a.exact);
  const bool closest = absl::GetFlag(FLAGS_closest);
  if (closest) {
    r.add_fields(gvd::v1::NEAREST_FIELD_CLOSEST);
    r.add_fields(gvd::v1::NEAREST_FIELD_GRADIENT);
  }
  gvd::v1::FindNearestResponse response;
  if (auto s = client.FindNearest(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
    return 0;
  }
  std::cout << (dims == 3 ? "x\ty\tz" : "x\ty") << "\tsite\tdistance\terror_bound\texact\tfeature"
            << (closest ? "\tclosest\tgradient\n" : "\n");
  // X,Y or X,Y,Z.
  auto point = [&](const gvd::v1::Point& p) {
    return dims == 3 ? absl::StrCat(Num(p.x()), ",", Num(p.y()), ",", Num(p.z()))
                     : absl::StrCat(Num(p.x()), ",", Num(p.y()));
  };
  for (int i = 0; i < response.results_size(); ++i) {
    const auto& n = response.results(i);
    std::cout << Num(r.points(i).x()) << "\t" << Num(r.points(i).y()) << "\t";
    if (dims == 3) std::cout << Num(r.points(i).z()) << "\t";
    if (n.empty()) {
      std::cout << "(none)\tinf\t0\tyes\t-" << (closest ? "\t-\t-\n" : "\n");
      continue;
    }
    std::string kind = n.feature_kind() == gvd::v1::FEATURE_KIND_EDGE    ? "edge"
                       : n.feature_kind() == gvd::v1::FEATURE_KIND_CURVE ? "curve"
                       : n.feature_kind() == gvd::v1::FEATURE_KIND_FACE  ? "face"
                                                            : "vertex";
    std::cout << n.site_id() << "\t" << Num(n.distance()) << "\t" << Num(n.error_bound())
              << "\t" << (n.exact() ? "yes" : "no") << "\t" << kind << " "
              << n.feature_index();
    if (closest) {
      std::cout << "\t" << point(n.closest()) << "\t" << point(n.gradient());
    }
    std::cout << "\n";
  }
  return 0;
}

int RenderCommand(const Args& a, Client& client) {
  const auto& w = a.words;
  Need(a, 2, "render SCENE -o OUT [--layer ids|features|distance] [--format png|exr]");
  const std::string* out = Option(a, "--output");
  if (!out) Usage("render needs -o OUT");
  gvd::v1::RenderImageRequest r;
  r.set_scene_id(w[1]);
  std::string layer = Option(a, "--layer") ? *Option(a, "--layer") : "ids";
  if (layer == "ids") r.set_layer(gvd::v1::RenderImageRequest::LAYER_IDS);
  else if (layer == "features") r.set_layer(gvd::v1::RenderImageRequest::LAYER_FEATURES);
  else if (layer == "distance") r.set_layer(gvd::v1::RenderImageRequest::LAYER_DISTANCE);
  else Usage("--layer must be ids, features or distance");
  std::string format = Option(a, "--format") ? *Option(a, "--format")
                       : out->size() > 4 && out->substr(out->size() - 4) == ".exr" ? "exr"
                                                                                   : "png";
  if (format != "png" && format != "exr") Usage("--format must be png or exr");
  r.set_format(format == "exr" ? gvd::v1::RenderImageRequest::FORMAT_EXR
                               : gvd::v1::RenderImageRequest::FORMAT_PNG);
  if (const std::string* window = Option(a, "--window")) ParseWindow(*window, r.mutable_window());
  r.set_draw_sites(Option(a, "--draw-sites") != nullptr);
  if (const std::string* z = Option(a, "--z")) r.set_z(Number(*z, "--z"));
  if (const std::string* k = Option(a, "--slice")) {
    uint32_t slice;
    if (!absl::SimpleAtoi(*k, &slice)) Usage(absl::StrCat("--slice needs a slice index, not ", *k));
    r.set_slice(slice);
  }
  if (const std::string* v = Option(a, "--min-version")) {
    uint64_t mv;
    if (!absl::SimpleAtoi(*v, &mv)) Usage("--min-version needs a version number");
    r.set_min_version(mv);
  } else {  // the scene as it is now, once rendered
    gvd::v1::Scene scene;
    if (auto s = client.GetScene(w[1], &scene); !s.ok()) return Fail(s);
    r.set_min_version(scene.version());
  }
  gvd::v1::RenderImageResponse response;
  if (auto s = client.RenderImage(r, &response); !s.ok()) return Fail(s);
  if (int e = WriteBytes(*out, response.image())) return e;
  std::cout << "wrote " << *out << ": " << response.width_px() << "x" << response.height_px()
            << " " << layer << " of scene " << w[1]
            << (r.has_z() || r.has_slice()
                    ? absl::StrCat(", slice ", response.slice(), " (z ", Num(response.slice_z()), ")")
                    : "")
            << " at version " << response.version() << "\n";
  return 0;
}

// The commands, by name: their words and flags as gvd --help says.
const std::map<std::string_view, Command>& Commands() {
  static const auto* commands = new std::map<std::string_view, Command>{
      {"scene", SceneCommand},   {"watch", WatchCommand},  {"sites", SitesCommand},
      {"health", HealthCommand}, {"nearest", NearestCommand}, {"render", RenderCommand},
      {"boundaries", Boundaries}, {"neighbors", Neighbors}, {"neighbours", Neighbors},
      {"delaunay", Delaunay},    {"zoom", Zoom},           {"clearance", Clearance},
      {"plan", Plan},            {"pick", Pick},           {"mosaic", Mosaic},
      {"volume", Volume},
  };
  return *commands;
}

int Run(const Args& a) {
  if (a.words.empty()) Usage("no command");
  auto command = Commands().find(a.words[0]);
  if (command == Commands().end()) Unknown(a);
  auto client = Client::Connect(a.server, OptionsOf(a));
  return command->second(a, *client);
}

}  // namespace
}  // namespace gvd::cli

int main(int argc, char** argv) { return gvd::cli::Run(gvd::cli::ParseArgs(argc, argv)); }
