// gvd-server: serves generalized Voronoi diagrams over gRPC from a headless GL context.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <sys/stat.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <vector>
#include <string>
#include <string_view>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "server/grpc/auth.h"
#include "server/http/http.h"
#include "server/log.h"
#include "server/app/memory.h"
#include "server/metrics.h"
#include "render/gl/render_loop.h"
#include "server/app/registry.h"
#include "server/grpc/service.h"
#include "server/http/web_app.h"
#include "server/grpc/legacy_records.h"
#include "server/store/sqlite_store.h"

namespace {

constexpr const char* kUsage = R"(usage: gvd-server [flags]

  --listen HOST:PORT          address to serve on (default 127.0.0.1:50051; port 0 picks one)
  --port-file PATH            write the bound port to PATH once serving (for scripts and
                              tests), and the HTTP port on a second line when it serves one
  --data DIR                  where scenes and sites are stored (SQLite, WAL, synchronous=FULL);
                              default $XDG_STATE_HOME/gvd or ~/.local/state/gvd; ":memory:"
                              keeps nothing across restarts
  --egl-device auto|hardware|software
                              which EGL device renders (default auto: a GPU if there is one,
                              else Mesa's software rasterizer)
  --software-render-threads N rasterizer threads of Mesa's llvmpipe (default 0: rasterize on
                              the render thread itself, which keeps query latency low and
                              incremental updates fast; more threads speed up full renders).
                              Ignored on a GPU, and when LP_NUM_THREADS is set.
  --render-threads N          render threads, each with a GL context of its own (default 2):
                              a long render holds up only its own scene while the others
                              render on the other threads
  --shutdown-grace-ms N       on SIGTERM, how long calls in flight may take to finish
                              (default 5000)
  --log-level debug|info|warn|error   (default info)
  --max-scenes N              (default 1000)
  --max-memory BYTES          what the scenes may hold together ("4G", "512M", bytes):
                              their rasters, 24 bytes a pixel, and their sites; a change past
                              it is refused with RESOURCE_EXHAUSTED (default: 3/4 of the
                              cgroup's memory limit, else of the physical memory)
  --max-sites-per-scene N     (default 1000000)
  --max-side-px N             largest width_px or height_px (default 8192)
  --max-points-per-query N    (default 1000000)
  --max-sites-per-request N   sites (or ids) in one UpsertSites or DeleteSites (default 100000)
  --max-vertices-per-site N   points of one polyline or polygon (default 100000)
  --max-message-bytes N       gRPC message size limit (default 268435456)
  --analysis-threads N        boundaries, neighbours, Delaunay, zoom windows, clearance
                              and planning calls run at once on the CPU pool (default 2)
  --max-queued-analyses N     such calls waiting for their turn before RESOURCE_EXHAUSTED
                              (default 64)
  --max-queued-writes N       writes (CreateScene, DeleteScene, UpsertSites, DeleteSites)
                              waiting for a commit thread before RESOURCE_EXHAUSTED
                              (default 1024)
  --metrics-listen HOST:PORT  serve Prometheus metrics at http://HOST:PORT/metrics (default off)
  --http-listen HOST:PORT     also serve every call over HTTP/1.1 in the Connect protocol
                              (JSON: POST /gvd.v1.Voronoi/METHOD), and the web app at /
                              (default off; the same tokens, TLS, limits and metrics)
  --http-cors-origins LIST    origins whose pages may call the HTTP port, comma-separated
                              ("https://app.example.com"; "*" for any); default none
  --tokens FILE               require bearer tokens: one "TOKEN read" or "TOKEN write" per line
  --tls-cert FILE, --tls-key FILE
                              serve TLS with this certificate chain and private key (PEM)
  --tls-client-ca FILE        also require client certificates signed by this CA (PEM)
  --config FILE               read flags from FILE, one "--flag value" per line (# comments);
                              flags on the command line after --config override it
  --help

By default the server listens on loopback only, without TLS and without authentication.
)";

struct Flags {
  std::string listen = "127.0.0.1:50051";
  std::string port_file;
  std::string memory_source;  // where limits.max_memory came from
  int render_threads = 2;
  std::string data;
  std::string egl_device = "auto";
  std::string log_level = "info";
  uint32_t software_render_threads = 0;
  uint32_t grace_ms = 5000;
  std::string tokens, tls_cert, tls_key, tls_client_ca, metrics_listen, http_listen;
  std::vector<std::string> cors_origins;
  gvd::ServerLimits limits;
};

[[noreturn]] void Die(const std::string& message) {
  std::fprintf(stderr, "gvd-server: %s\n%s", message.c_str(), kUsage);
  std::exit(2);
}

template <class T>
void ParseCount(const std::string& flag, const std::string& value, T* out) {
  uint64_t v = 0;
  if (!absl::SimpleAtoi(value, &v) || v == 0 || v > std::numeric_limits<T>::max()) {
    Die(absl::StrCat(flag, " needs a positive integer, not \"", value, "\""));
  }
  *out = static_cast<T>(v);
}

// The arguments with each --config FILE replaced by the flags it holds.
std::vector<std::string> ExpandConfig(int argc, char** argv) {
  std::vector<std::string> out;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    std::string file;
    if (arg == "--config" && i + 1 < argc) {
      file = argv[++i];
    } else if (arg.rfind("--config=", 0) == 0) {
      file = arg.substr(9);
    } else {
      out.push_back(arg);
      continue;
    }
    std::ifstream in(file);
    if (!in) Die(absl::StrCat("cannot read --config file ", file));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      std::istringstream words(line);
      std::string flag, value;
      if (!(words >> flag) || flag[0] == '#') continue;
      if (flag.rfind("--", 0) != 0) Die(absl::StrCat(file, ":", n, ": expected --flag value"));
      out.push_back(flag);
      if (flag.find('=') == std::string::npos && (words >> value)) out.push_back(value);
    }
  }
  return out;
}

std::string ReadFile(const std::string& flag, const std::string& path) {
  std::ifstream in(path);
  if (!in) Die(absl::StrCat(flag, ": cannot read ", path));
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

Flags ParseFlags(int argc, char** argv) {
  Flags f;
  std::vector<std::string> args = ExpandConfig(argc, argv);
  for (size_t i = 0; i < args.size(); ++i) {
    std::string arg = args[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    std::string value;
    if (auto eq = arg.find('='); eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    } else if (i + 1 < args.size()) {
      value = args[++i];
    } else {
      Die(absl::StrCat(arg, " needs a value"));
    }
    if (arg == "--listen") f.listen = value;
    else if (arg == "--tokens") f.tokens = value;
    else if (arg == "--metrics-listen") f.metrics_listen = value;
    else if (arg == "--http-listen") f.http_listen = value;
    else if (arg == "--http-cors-origins") {
      f.cors_origins = absl::StrSplit(value, ',', absl::SkipWhitespace());
    }
    else if (arg == "--tls-cert") f.tls_cert = value;
    else if (arg == "--tls-key") f.tls_key = value;
    else if (arg == "--tls-client-ca") f.tls_client_ca = value;
    else if (arg == "--port-file") f.port_file = value;
    else if (arg == "--data") f.data = value;
    else if (arg == "--shutdown-grace-ms") ParseCount(arg, value, &f.grace_ms);
    else if (arg == "--egl-device") f.egl_device = value;
    else if (arg == "--log-level") f.log_level = value;
    else if (arg == "--software-render-threads") {
      if (!absl::SimpleAtoi(value, &f.software_render_threads) || f.software_render_threads > 64) {
        Die(absl::StrCat("--software-render-threads needs 0 to 64, not \"", value, "\""));
      }
    }
    else if (arg == "--max-scenes") ParseCount(arg, value, &f.limits.max_scenes);
    else if (arg == "--render-threads") ParseCount(arg, value, &f.render_threads);
    else if (arg == "--max-memory") {
      auto bytes = gvd::ParseBytes(value);
      if (!bytes) Die(absl::StrCat("--max-memory needs a size such as 4G, 512M or 1073741824, not \"", value, "\""));
      f.limits.max_memory = *bytes;
      f.memory_source = "--max-memory";
    }
    else if (arg == "--max-sites-per-scene") ParseCount(arg, value, &f.limits.max_sites_per_scene);
    else if (arg == "--max-side-px") ParseCount(arg, value, &f.limits.max_side_px);
    else if (arg == "--max-points-per-query") ParseCount(arg, value, &f.limits.max_points_per_query);
    else if (arg == "--max-sites-per-request") ParseCount(arg, value, &f.limits.max_sites_per_request);
    else if (arg == "--max-vertices-per-site") ParseCount(arg, value, &f.limits.max_vertices_per_site);
    else if (arg == "--max-message-bytes") ParseCount(arg, value, &f.limits.max_message_bytes);
    else if (arg == "--analysis-threads") ParseCount(arg, value, &f.limits.analysis_threads);
    else if (arg == "--max-queued-analyses") ParseCount(arg, value, &f.limits.max_queued_analyses);
    else if (arg == "--max-queued-writes") ParseCount(arg, value, &f.limits.max_queued_writes);
    else Die(absl::StrCat("unknown flag ", arg));
  }
  f.limits.max_scene_pixels = uint64_t{f.limits.max_side_px} * f.limits.max_side_px;
  if (f.memory_source.empty()) f.limits.max_memory = gvd::DefaultMaxMemory("/sys/fs/cgroup", &f.memory_source);
  if (f.data.empty()) {
    const char* state = std::getenv("XDG_STATE_HOME");
    const char* home = std::getenv("HOME");
    if (state && *state) {
      f.data = std::string(state) + "/gvd";
    } else if (home && *home) {
      f.data = std::string(home) + "/.local/state/gvd";
    } else {
      Die("--data is needed: neither XDG_STATE_HOME nor HOME is set");
    }
  }
  return f;
}

// mkdir -p for the parents of `dir`.
void MakeParents(const std::string& dir) {
  for (size_t i = 1; i < dir.size(); ++i) {
    if (dir[i] == '/') mkdir(dir.substr(0, i).c_str(), 0700);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Flags flags = ParseFlags(argc, argv);
  gvd::LogLevel level;
  if (!gvd::ParseLogLevel(flags.log_level, &level)) {
    Die(absl::StrCat("--log-level must be debug, info, warn or error, not \"", flags.log_level,
                     "\""));
  }
  gvd::SetLogLevel(level);
  auto preference = gvd::ParseDevicePreference(flags.egl_device);
  if (!preference.ok()) Die(std::string(preference.status().message()));

  // Signals are taken by sigwait below; every thread started from here inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  // llvmpipe reads this when the context is made.
  setenv("LP_NUM_THREADS", absl::StrCat(flags.software_render_threads).c_str(), /*overwrite=*/0);

  gvd::Metrics metrics;
  gvd::RenderLoop renderer(flags.render_threads);
  renderer.set_observer({
      [&metrics](const gvd::Scene& scene, uint64_t version, const gvd::RenderStats& stats,
                 double seconds) {
        metrics.ObserveRender(stats, seconds);
        const gvd::PixelRect& w = stats.window;
        gvd::Log(gvd::LogLevel::kDebug, "rendered",
                 {{"scene", scene.id()}, {"version", absl::StrCat(version)},
                  {"sites", absl::StrCat(scene.site_count())},
                  {"full", stats.full ? "true" : "false"},
                  {"window", absl::StrCat(w.x0, ",", w.y0, ",", w.x1, ",", w.y1)},
                  {"sites_drawn", absl::StrCat(stats.sites_drawn)},
                  {"coverage_ms", absl::StrCat(stats.coverage_seconds * 1e3)},
                  {"draw_ms", absl::StrCat(stats.draw_seconds * 1e3)},
                  {"readback_ms", absl::StrCat(stats.readback_seconds * 1e3)},
                  {"total_ms", absl::StrCat(seconds * 1e3)}});
      },
      [](const gvd::Scene& scene, uint64_t version, const absl::Status& error) {
        gvd::Log(gvd::LogLevel::kError, "render_failed",
                 {{"scene", scene.id()}, {"version", absl::StrCat(version)},
                  {"error", error.ToString()}});
      }});
  if (auto s = renderer.Start(*preference); !s.ok()) {
    gvd::Log(gvd::LogLevel::kError, "no_render_context", {{"error", s.ToString()}});
    return 1;
  }
  gvd::Log(gvd::LogLevel::kInfo, "render_context",
           {{"platform", renderer.device().platform},
            {"device_index", absl::StrCat(renderer.device().device_index)},
            {"software", renderer.device().software ? "true" : "false"},
            {"drm_node", renderer.device().drm_node},
            {"gl_renderer", renderer.device().gl_renderer},
            {"gl_version", renderer.device().gl_version},
            {"render_threads", absl::StrCat(renderer.lanes())}});

  if (flags.data != ":memory:") MakeParents(flags.data);
  auto store = gvd::SqliteStore::Open(flags.data, gvd::LegacyRecords(flags.limits));
  if (!store.ok()) {
    gvd::Log(gvd::LogLevel::kError, "store_failed", {{"error", store.status().ToString()}});
    return 1;
  }
  std::optional<gvd::TokenAuth> auth;
  if (!flags.tokens.empty()) {
    auto loaded = gvd::TokenAuth::Load(flags.tokens);
    if (!loaded.ok()) Die(std::string(loaded.status().message()));
    auth = std::move(*loaded);
  }
  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
  if (!flags.tls_cert.empty() || !flags.tls_key.empty()) {
    if (flags.tls_cert.empty() || flags.tls_key.empty()) Die("--tls-cert and --tls-key go together");
    grpc::SslServerCredentialsOptions tls(
        flags.tls_client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                    : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
    tls.pem_key_cert_pairs.push_back(
        {ReadFile("--tls-key", flags.tls_key), ReadFile("--tls-cert", flags.tls_cert)});
    if (!flags.tls_client_ca.empty()) tls.pem_root_certs = ReadFile("--tls-client-ca", flags.tls_client_ca);
    credentials = grpc::SslServerCredentials(tls);
  } else if (!flags.tls_client_ca.empty()) {
    Die("--tls-client-ca needs --tls-cert and --tls-key");
  }
  gvd::Log(gvd::LogLevel::kInfo, "security",
           {{"tls", flags.tls_cert.empty() ? "off" : "on"},
            {"client_certificates", flags.tls_client_ca.empty() ? "not required" : "required"},
            {"tokens", auth ? absl::StrCat(auth->size()) : "off"}});
  auto registry =
      std::make_unique<gvd::SceneRegistry>(store->get(), &renderer, flags.limits, &metrics);
  gvd::VoronoiService service(registry.get(), auth ? &*auth : nullptr, &metrics);
  metrics.SetMemoryLimit(flags.limits.max_memory);
  gvd::Log(gvd::LogLevel::kInfo, "memory_budget",
           {{"max_memory", absl::StrCat(flags.limits.max_memory)},
            {"human", gvd::FormatBytes(flags.limits.max_memory)}, {"from", flags.memory_source}});
  if (!flags.metrics_listen.empty()) {
    auto port = metrics.Serve(flags.metrics_listen, [&registry] { return registry->Sample(); });
    if (!port.ok()) {
      gvd::Log(gvd::LogLevel::kError, "metrics_failed", {{"error", port.status().ToString()}});
      return 1;
    }
    gvd::Log(gvd::LogLevel::kInfo, "metrics", {{"address", flags.metrics_listen},
                                               {"port", absl::StrCat(*port)}});
  }
  // What goes, in this order, once the server stops serving: the render threads (so that no
  // frame is published into the core), the metrics' view of the scenes, the core (which
  // finishes the work its lanes still hold: a write cut short by the grace period still
  // commits), and last the store, closed cleanly.
  auto stop = [&] {
    renderer.Stop();
    metrics.StopSampling();
    registry.reset();
    store->reset();
  };
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(flags.listen, credentials, &port);
  builder.SetMaxReceiveMessageSize(flags.limits.max_message_bytes);
  builder.SetMaxSendMessageSize(flags.limits.max_message_bytes);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    gvd::Log(gvd::LogLevel::kError, "listen_failed", {{"address", flags.listen}});
    return 1;
  }
  // Not serving until every stored scene is rebuilt; calls meanwhile get UNAVAILABLE.
  server->GetHealthCheckService()->SetServingStatus(false);
  gvd::Log(gvd::LogLevel::kInfo, "listening",
           {{"address", flags.listen}, {"port", absl::StrCat(port)}});
  // HTTP: the same service, reached over an in-process channel.
  std::unique_ptr<gvd::HttpServer> http;
  if (!flags.http_listen.empty()) {
    gvd::HttpOptions options;
    options.listen = flags.http_listen;
    options.cors_origins = flags.cors_origins;
    options.max_body_bytes = flags.limits.max_message_bytes;
    options.files = gvd::WebApp();
    if (!flags.tls_cert.empty()) {
      options.tls_cert = ReadFile("--tls-cert", flags.tls_cert);
      options.tls_key = ReadFile("--tls-key", flags.tls_key);
      if (!flags.tls_client_ca.empty()) {
        options.tls_client_ca = ReadFile("--tls-client-ca", flags.tls_client_ca);
      }
    }
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    args.SetMaxSendMessageSize(-1);
    auto started = gvd::HttpServer::Start(std::move(options), server->InProcessChannel(args));
    if (!started.ok()) {
      gvd::Log(gvd::LogLevel::kError, "http_failed", {{"error", started.status().ToString()}});
      server->Shutdown();
      stop();
      return 1;
    }
    http = std::move(*started);
    const auto colon = flags.http_listen.rfind(':');
    std::string host = flags.http_listen.substr(0, colon);
    if (host == "0.0.0.0" || host == "[::]" || host.empty()) host = "127.0.0.1";
    gvd::Log(gvd::LogLevel::kInfo, "http_listening",
             {{"address", flags.http_listen},
              {"port", absl::StrCat(http->port())},
              {"url", absl::StrCat(flags.tls_cert.empty() ? "http" : "https", "://", host, ":",
                                   http->port(), "/")},
              {"tls", flags.tls_cert.empty() ? "off" : "on"},
              {"cors_origins", absl::StrJoin(flags.cors_origins, ",")}});
  }
  if (auto s = registry->Load(); !s.ok()) {
    gvd::Log(gvd::LogLevel::kError, "store_load_failed", {{"error", s.ToString()}});
    server->Shutdown();
    stop();
    return 1;
  }
  server->GetHealthCheckService()->SetServingStatus(true);
  if (!flags.port_file.empty()) {
    std::string tmp = flags.port_file + ".tmp";
    std::ofstream out(tmp);
    out << port << "\n";
    if (http) out << http->port() << "\n";
    out.close();
    std::rename(tmp.c_str(), flags.port_file.c_str());
  }

  int sig = 0;
  sigwait(&signals, &sig);
  gvd::Log(gvd::LogLevel::kInfo, "shutting_down",
           {{"signal", strsignal(sig)}, {"in_flight", absl::StrCat(service.in_flight())}});
  // Drain: health says NOT_SERVING, new calls are refused, calls in flight get the grace
  // period to finish; whatever is left then is cancelled.
  server->GetHealthCheckService()->SetServingStatus(false);
  int left = service.Drain(std::chrono::milliseconds(flags.grace_ms));
  // HTTP connections finish the response under way, idle ones close.
  if (http) http->Shutdown(std::chrono::milliseconds(std::min<uint32_t>(flags.grace_ms, 1000)));
  server->Shutdown(std::chrono::system_clock::now());
  stop();
  gvd::Log(gvd::LogLevel::kInfo, "stopped", {{"cancelled_calls", absl::StrCat(left)}});
  return 0;
}
