// gvd: the command-line client of gvd-server.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include <charconv>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "gvd/client.h"

namespace {

constexpr const char* kUsage = R"(usage: gvd [--server HOST:PORT] [--scene ID] [--json] [--timeout SECONDS] COMMAND

Scenes:
  gvd scene create ID --window MIN_X,MIN_Y,MAX_X,MAX_Y --size WIDTHxHEIGHT [--max-error E]
                     [--render-mode mesh|exact]
  gvd scene get ID
  gvd scene ls
  gvd scene rm ID
Sites (of the scene named by --scene, default "default"):
  gvd sites add ID X Y [ID X Y ...]
  gvd sites add --file PATH   JSON: [{"id": "a", "point": {"x": 1, "y": 2}}, ...] or
                              {"sites": [...]}; or text lines "ID X Y"; PATH - reads stdin
  gvd sites rm ID [ID ...]
  gvd sites ls
Health:
  gvd health           the server's grpc.health.v1 status; exit 0 when SERVING

Queries:
  gvd nearest X Y [X Y ...] [--min-version V] [--exact]
      prints, per point, the nearest site, its exact distance, and the error bound: no
      site is closer than distance - error_bound; --exact certifies each answer exact

Flags:
  --server HOST:PORT   default 127.0.0.1:50051, or $GVD_SERVER
  --scene ID           default "default", or $GVD_SCENE
  --json               print responses as JSON
  --timeout SECONDS    per call (default 30)
  --token TOKEN        bearer token, or $GVD_TOKEN
  --tls-ca FILE        use TLS, trusting this CA (PEM); --tls-cert FILE --tls-key FILE add a
                       client certificate
)";

struct Args {
  std::string server = "127.0.0.1:50051";
  std::string scene = "default";
  bool json = false;
  bool exact = false;
  double timeout = 30;
  std::string token, tls_ca, tls_cert, tls_key;
  std::map<std::string, std::string> options;  // command flags such as --window
  std::vector<std::string> words;
};

[[noreturn]] void Usage(const std::string& message) {
  std::fprintf(stderr, "gvd: %s\n\n%s", message.c_str(), kUsage);
  std::exit(2);
}

Args ParseArgs(int argc, char** argv) {
  Args a;
  if (const char* s = std::getenv("GVD_SERVER")) a.server = s;
  if (const char* s = std::getenv("GVD_SCENE")) a.scene = s;
  if (const char* s = std::getenv("GVD_TOKEN")) a.token = s;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (arg.rfind("--", 0) != 0) {  // "-3.5" is a number, not a flag
      a.words.push_back(arg);
      continue;
    }
    if (arg == "--json" || arg == "--exact") {
      (arg == "--json" ? a.json : a.exact) = true;
      continue;
    }
    std::string value;
    if (auto eq = arg.find('='); eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    } else if (i + 1 < argc) {
      value = argv[++i];
    } else {
      Usage(absl::StrCat(arg, " needs a value"));
    }
    if (arg == "--server") a.server = value;
    else if (arg == "--token") a.token = value;
    else if (arg == "--tls-ca") a.tls_ca = value;
    else if (arg == "--tls-cert") a.tls_cert = value;
    else if (arg == "--tls-key") a.tls_key = value;
    else if (arg == "--scene") a.scene = value;
    else if (arg == "--timeout") {
      if (!absl::SimpleAtod(value, &a.timeout) || !(a.timeout > 0)) {
        Usage(absl::StrCat("--timeout needs a positive number of seconds, not \"", value, "\""));
      }
    } else if (arg == "--window" || arg == "--size" || arg == "--max-error" || arg == "--file" ||
               arg == "--min-version" || arg == "--render-mode") {
      a.options[arg] = value;
    } else {
      Usage(absl::StrCat("unknown flag ", arg));
    }
  }
  return a;
}

double Number(const std::string& word, const std::string& what) {
  double v;
  if (!absl::SimpleAtod(word, &v)) Usage(absl::StrCat(what, " must be a number, not \"", word, "\""));
  return v;
}

int Fail(const grpc::Status& s) {
  static const char* kNames[] = {"OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT",
                                 "DEADLINE_EXCEEDED", "NOT_FOUND", "ALREADY_EXISTS",
                                 "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
                                 "ABORTED", "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL",
                                 "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  int code = s.error_code();
  std::fprintf(stderr, "gvd: %s: %s\n", code >= 0 && code <= 16 ? kNames[code] : "?",
               s.error_message().c_str());
  return 1;
}

void PrintJson(const google::protobuf::Message& m) {
  std::string out;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(m, &out, options);
  std::cout << out;
}

// The shortest decimal form that reads back as v.
std::string Num(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

void PrintScene(const gvd::v1::Scene& s) {
  const auto& w = s.window();
  std::cout << "scene " << s.scene_id() << ": window [" << Num(w.min_x()) << ", " << Num(w.max_x())
            << "] x [" << Num(w.min_y()) << ", " << Num(w.max_y()) << "], " << s.width_px() << "x"
            << s.height_px() << " px, max_error " << Num(s.max_error()) << ", "
            << (s.render_mode() == gvd::v1::EXACT ? std::string("exact render")
                                                  : absl::StrCat(s.cone_triangles(), " triangles per cone"))
            << ", version " << s.version() << ", "
            << s.site_count() << " sites, rendered version " << s.rendered_version() << "\n";
}

// Reads sites from JSON (an array of Site, or {"sites": [...]}) or from "ID X Y" lines.
bool ReadSites(const std::string& path, gvd::v1::UpsertSitesRequest* request, std::string* error) {
  std::stringstream buffer;
  if (path == "-") {
    buffer << std::cin.rdbuf();
  } else {
    std::ifstream in(path);
    if (!in) {
      *error = absl::StrCat("cannot read ", path);
      return false;
    }
    buffer << in.rdbuf();
  }
  std::string text = buffer.str();
  size_t first = text.find_first_not_of(" \t\r\n");
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

int Run(const Args& a) {
  const auto& w = a.words;
  if (w.empty()) Usage("no command");
  gvd::ClientOptions options;
  options.timeout = std::chrono::milliseconds(static_cast<int64_t>(a.timeout * 1000));
  options.token = a.token;
  auto read = [](const std::string& flag, const std::string& path) {
    std::ifstream in(path);
    if (!in) Usage(absl::StrCat(flag, ": cannot read ", path));
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  if (!a.tls_ca.empty()) options.tls_ca = read("--tls-ca", a.tls_ca);
  if (!a.tls_cert.empty()) options.tls_cert = read("--tls-cert", a.tls_cert);
  if (!a.tls_key.empty()) options.tls_key = read("--tls-key", a.tls_key);
  auto client = gvd::Client::Connect(a.server, options);
  auto need = [&](size_t n, const char* form) {
    if (w.size() != n) Usage(absl::StrCat("usage: gvd ", form));
  };
  auto option = [&](const char* name) -> const std::string* {
    auto it = a.options.find(name);
    return it == a.options.end() ? nullptr : &it->second;
  };

  if (w[0] == "scene" && w.size() >= 2) {
    const std::string& verb = w[1];
    if (verb == "create") {
      need(3, "scene create ID --window MIN_X,MIN_Y,MAX_X,MAX_Y --size WxH [--max-error E]");
      gvd::v1::CreateSceneRequest r;
      r.set_scene_id(w[2]);
      const std::string* window = option("--window");
      const std::string* size = option("--size");
      if (!window || !size) Usage("scene create needs --window and --size");
      std::vector<std::string> c = absl::StrSplit(*window, ',');
      if (c.size() != 4) Usage(absl::StrCat("--window needs MIN_X,MIN_Y,MAX_X,MAX_Y, not ", *window));
      r.mutable_window()->set_min_x(Number(c[0], "--window MIN_X"));
      r.mutable_window()->set_min_y(Number(c[1], "--window MIN_Y"));
      r.mutable_window()->set_max_x(Number(c[2], "--window MAX_X"));
      r.mutable_window()->set_max_y(Number(c[3], "--window MAX_Y"));
      std::vector<std::string> wh = absl::StrSplit(*size, 'x');
      uint32_t width, height;
      if (wh.size() != 2 || !absl::SimpleAtoi(wh[0], &width) || !absl::SimpleAtoi(wh[1], &height)) {
        Usage(absl::StrCat("--size needs WIDTHxHEIGHT in pixels, not ", *size));
      }
      r.set_width_px(width);
      r.set_height_px(height);
      if (const std::string* e = option("--max-error")) r.set_max_error(Number(*e, "--max-error"));
      if (const std::string* m = option("--render-mode")) {
        if (*m != "mesh" && *m != "exact") Usage("--render-mode must be mesh or exact");
        r.set_render_mode(*m == "exact" ? gvd::v1::EXACT : gvd::v1::MESH);
      }
      gvd::v1::Scene scene;
      if (auto s = client->CreateScene(r, &scene); !s.ok()) return Fail(s);
      a.json ? PrintJson(scene) : PrintScene(scene);
      return 0;
    }
    if (verb == "get") {
      need(3, "scene get ID");
      gvd::v1::Scene scene;
      if (auto s = client->GetScene(w[2], &scene); !s.ok()) return Fail(s);
      a.json ? PrintJson(scene) : PrintScene(scene);
      return 0;
    }
    if (verb == "ls") {
      need(2, "scene ls");
      std::vector<gvd::v1::Scene> scenes;
      if (auto s = client->ListScenes(&scenes); !s.ok()) return Fail(s);
      gvd::v1::ListScenesResponse all;
      for (auto& s : scenes) a.json ? void(*all.add_scenes() = s) : PrintScene(s);
      if (a.json) PrintJson(all);
      return 0;
    }
    if (verb == "rm") {
      need(3, "scene rm ID");
      if (auto s = client->DeleteScene(w[2]); !s.ok()) return Fail(s);
      std::cout << "deleted scene " << w[2] << "\n";
      return 0;
    }
  }

  if (w[0] == "sites" && w.size() >= 2) {
    const std::string& verb = w[1];
    if (verb == "add") {
      gvd::v1::UpsertSitesRequest r;
      if (const std::string* file = option("--file")) {
        std::string error;
        if (!ReadSites(*file, &r, &error)) {
          std::fprintf(stderr, "gvd: %s\n", error.c_str());
          return 2;
        }
      }
      r.set_scene_id(a.scene);  // after ReadSites: parsing JSON resets the message
      if ((w.size() - 2) % 3 != 0) Usage("sites add takes triples ID X Y");
      for (size_t i = 2; i + 2 < w.size(); i += 3) {
        auto* site = r.add_sites();
        site->set_id(w[i]);
        site->mutable_point()->set_x(Number(w[i + 1], "X"));
        site->mutable_point()->set_y(Number(w[i + 2], "Y"));
      }
      if (r.sites_size() == 0) Usage("sites add needs ID X Y triples or --file");
      uint64_t version = 0;
      if (auto s = client->UpsertSites(r, &version); !s.ok()) return Fail(s);
      std::cout << "upserted " << r.sites_size() << " sites; scene " << a.scene << " is at version "
                << version << "\n";
      return 0;
    }
    if (verb == "rm") {
      if (w.size() < 3) Usage("usage: gvd sites rm ID [ID ...]");
      uint64_t version = 0;
      std::vector<std::string> ids(w.begin() + 2, w.end());
      if (auto s = client->DeleteSites(a.scene, ids, &version); !s.ok()) return Fail(s);
      std::cout << "deleted " << ids.size() << " sites; scene " << a.scene << " is at version "
                << version << "\n";
      return 0;
    }
    if (verb == "ls") {
      need(2, "sites ls");
      std::vector<gvd::v1::Site> sites;
      if (auto s = client->ListAllSites(a.scene, &sites); !s.ok()) return Fail(s);
      if (a.json) {
        gvd::v1::ListSitesResponse all;
        for (auto& s : sites) *all.add_sites() = s;
        PrintJson(all);
        return 0;
      }
      for (const auto& s : sites) {
        std::cout << s.id() << "\t" << Num(s.point().x()) << "\t" << Num(s.point().y()) << "\n";
      }
      return 0;
    }
  }

  if (w[0] == "health") {
    need(1, "health");
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

  if (w[0] == "nearest") {
    if (w.size() < 3 || (w.size() - 1) % 2 != 0) Usage("usage: gvd nearest X Y [X Y ...]");
    gvd::v1::FindNearestRequest r;
    r.set_scene_id(a.scene);
    for (size_t i = 1; i + 1 < w.size(); i += 2) {
      auto* p = r.add_points();
      p->set_x(Number(w[i], "X"));
      p->set_y(Number(w[i + 1], "Y"));
    }
    if (const std::string* v = option("--min-version")) {
      uint64_t mv;
      if (!absl::SimpleAtoi(*v, &mv)) Usage("--min-version needs a version number");
      r.set_min_version(mv);
    }
    r.set_exact(a.exact);
    gvd::v1::FindNearestResponse response;
    if (auto s = client->FindNearest(r, &response); !s.ok()) return Fail(s);
    if (a.json) {
      PrintJson(response);
      return 0;
    }
    std::cout << "x\ty\tsite\tdistance\terror_bound\texact\n";
    for (int i = 0; i < response.results_size(); ++i) {
      const auto& n = response.results(i);
      std::cout << Num(r.points(i).x()) << "\t" << Num(r.points(i).y()) << "\t" << n.site_id()
                << "\t" << Num(n.distance()) << "\t" << Num(n.error_bound()) << "\t"
                << (n.exact() ? "yes" : "no") << "\n";
    }
    return 0;
  }
  Usage(absl::StrCat("unknown command \"", absl::StrJoin(w, " "), "\""));
}

}  // namespace

int main(int argc, char** argv) { return Run(ParseArgs(argc, argv)); }
