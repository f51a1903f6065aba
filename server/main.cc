// gvd-server: serves generalized Voronoi diagrams over gRPC from a headless GL context.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <sys/stat.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <string_view>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "server/log.h"
#include "server/render_loop.h"
#include "server/service.h"
#include "server/store.h"

namespace {

constexpr const char* kUsage = R"(usage: gvd-server [flags]

  --listen HOST:PORT          address to serve on (default 127.0.0.1:50051; port 0 picks one)
  --port-file PATH            write the bound port to PATH once serving (for scripts and tests)
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
  --shutdown-grace-ms N       on SIGTERM, how long calls in flight may take to finish
                              (default 5000)
  --log-level debug|info|warn|error   (default info)
  --max-scenes N              (default 1000)
  --max-sites-per-scene N     (default 1000000)
  --max-side-px N             largest width_px or height_px (default 8192)
  --max-points-per-query N    (default 1000000)
  --max-message-bytes N       gRPC message size limit (default 268435456)
  --help
)";

struct Flags {
  std::string listen = "127.0.0.1:50051";
  std::string port_file;
  std::string data;
  std::string egl_device = "auto";
  std::string log_level = "info";
  uint32_t software_render_threads = 0;
  uint32_t grace_ms = 5000;
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

Flags ParseFlags(int argc, char** argv) {
  Flags f;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    std::string value;
    if (auto eq = arg.find('='); eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    } else if (i + 1 < argc) {
      value = argv[++i];
    } else {
      Die(absl::StrCat(arg, " needs a value"));
    }
    if (arg == "--listen") f.listen = value;
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
    else if (arg == "--max-sites-per-scene") ParseCount(arg, value, &f.limits.max_sites_per_scene);
    else if (arg == "--max-side-px") ParseCount(arg, value, &f.limits.max_side_px);
    else if (arg == "--max-points-per-query") ParseCount(arg, value, &f.limits.max_points_per_query);
    else if (arg == "--max-message-bytes") ParseCount(arg, value, &f.limits.max_message_bytes);
    else Die(absl::StrCat("unknown flag ", arg));
  }
  f.limits.max_scene_pixels = uint64_t{f.limits.max_side_px} * f.limits.max_side_px;
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

  gvd::RenderLoop renderer;
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
            {"gl_version", renderer.device().gl_version}});

  if (flags.data != ":memory:") MakeParents(flags.data);
  auto store = gvd::Store::Open(flags.data);
  if (!store.ok()) {
    gvd::Log(gvd::LogLevel::kError, "store_failed", {{"error", store.status().ToString()}});
    return 1;
  }
  gvd::VoronoiService service(&renderer, store->get(), flags.limits);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(flags.listen, grpc::InsecureServerCredentials(), &port);
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
  if (auto s = service.Load(); !s.ok()) {
    gvd::Log(gvd::LogLevel::kError, "store_load_failed", {{"error", s.ToString()}});
    server->Shutdown();
    return 1;
  }
  server->GetHealthCheckService()->SetServingStatus(true);
  if (!flags.port_file.empty()) {
    std::string tmp = flags.port_file + ".tmp";
    std::ofstream(tmp) << port << "\n";
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
  server->Shutdown(std::chrono::system_clock::now());
  renderer.Stop();
  store->reset();  // closes the database cleanly
  gvd::Log(gvd::LogLevel::kInfo, "stopped", {{"cancelled_calls", absl::StrCat(left)}});
  return 0;
}
