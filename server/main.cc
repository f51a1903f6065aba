// gvd-server: serves generalized Voronoi diagrams over gRPC and HTTP from a headless GL
// context. main builds the store, the renderers (the GL render threads for the plane, the
// volume renderer for space) and the application core over them, then both transports.
#include <grpcpp/grpcpp.h>

#include <arpa/inet.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <vector>
#include <string>
#include <string_view>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/synchronization/mutex.h"
#include "render/gl/render_loop.h"
#include "render/plan/volume_renderer.h"
#include "render/scene/cpu_pool.h"
#include "server/app/auth.h"
#include "server/app/legacy_records.h"
#include "server/app/memory.h"
#include "server/app/registry.h"
#include "server/app/service.h"
#include "client/flags/flags.h"
#include "server/grpc/server.h"
#include "server/http/http.h"
#include "server/http/web_app.h"
#include "server/huge_pages.h"
#include "server/log.h"
#include "server/metrics.h"
#include "server/render_telemetry.h"
#include "server/store/postgres_store.h"
#include "server/store/sqlite_store.h"

// The flags (--help lists them: gvd::flags::Describe).
ABSL_FLAG(std::string, listen, "127.0.0.1:50051",
          "<HOST:PORT> address to serve on (port 0 picks one)");
ABSL_FLAG(std::string, port_file, "",
          "<PATH> write the bound port to PATH once serving (for scripts and tests), and the "
          "HTTP port on a second line when it serves one");
ABSL_FLAG(std::string, data, "",
          "<DIR> where scenes and sites are stored (SQLite, WAL, synchronous=FULL); by default "
          "$XDG_STATE_HOME/gvd or ~/.local/state/gvd; \":memory:\" keeps nothing across "
          "restarts");
ABSL_FLAG(std::string, store, "",
          "<URL> where scenes are stored: sqlite:///DIR (the same as --data DIR), or "
          "postgresql://... (a libpq URL, several hosts and target_session_attrs included) for "
          "replicas: every server on one database accepts writes, holds every scene and "
          "follows the others' changes");
ABSL_FLAG(uint32_t, relaxed_sync_ms, 100,
          "<N> how long a write sent with durability RELAXED may stay unsynced in a SQLite "
          "store, 1 to 60000: it is answered once written, survives a crash of the server at "
          "once, and a crash or power loss of the machine once synced, within N ms (on "
          "PostgreSQL it is committed as SYNC)");
ABSL_FLAG(uint32_t, store_pack_sites, 4096,
          "<N> a write of N sites or more is committed to a SQLite store as one row (a pack), "
          "folded into a row per site off the acknowledgement's path");
ABSL_FLAG(uint32_t, store_fold_after_ms, 500,
          "<N> packs are folded once none has been written for N ms, 1 to 60000");
ABSL_FLAG(std::string, egl_device, "auto",
          "<auto|hardware|software> which EGL device renders (by default auto: a GPU if there "
          "is one, else Mesa's software rasterizer)");
ABSL_FLAG(uint32_t, software_render_threads, 0,
          "<N> rasterizer threads of Mesa's llvmpipe, 0 to 64 (by default 0: rasterize on the "
          "render thread itself, which keeps query latency low and incremental updates fast; "
          "more threads speed up full renders). Ignored on a GPU, and when LP_NUM_THREADS is "
          "set.");
ABSL_FLAG(int32_t, render_threads, 2,
          "<N> render threads, each with a GL context of its own: a long render holds up only "
          "its own scene while the others render on the other threads");
ABSL_FLAG(uint32_t, shutdown_grace_ms, 5000,
          "<N> on SIGTERM, how long calls in flight may take to finish");
ABSL_FLAG(std::string, log_level, "info", "<debug|info|warn|error> the least level logged");
ABSL_FLAG(uint64_t, max_scenes, gvd::ServerLimits{}.max_scenes, "<N> scenes the server holds");
ABSL_FLAG(std::string, max_memory, "",
          "<BYTES> what the scenes may hold together (\"4G\", \"512M\", bytes): their rasters, "
          "24 bytes a pixel, and their sites; a change past it is refused with "
          "RESOURCE_EXHAUSTED (by default 3/4 of the cgroup's memory limit, else of the "
          "physical memory)");
ABSL_FLAG(uint64_t, max_sites_per_scene, gvd::ServerLimits{}.max_sites_per_scene,
          "<N> sites one scene holds");
ABSL_FLAG(uint32_t, max_side_px, gvd::ServerLimits{}.max_side_px,
          "<N> largest width_px or height_px");
ABSL_FLAG(uint64_t, max_points_per_query, gvd::ServerLimits{}.max_points_per_query,
          "<N> query points in one FindNearest");
ABSL_FLAG(uint64_t, max_sites_per_request, gvd::ServerLimits{}.max_sites_per_request,
          "<N> sites (or ids) in one UpsertSites or DeleteSites");
ABSL_FLAG(uint64_t, max_vertices_per_site, gvd::ServerLimits{}.max_vertices_per_site,
          "<N> points of one polyline or polygon");
ABSL_FLAG(uint64_t, max_voxels_per_scene, gvd::ServerLimits{}.max_voxels_per_scene,
          "<N> voxels (width_px x height_px x depth_px) of one 3D scene");
ABSL_FLAG(uint64_t, max_triangles_per_mesh, gvd::ServerLimits{}.max_triangles_per_mesh,
          "<N> triangles of one mesh site");
ABSL_FLAG(int32_t, max_message_bytes, gvd::ServerLimits{}.max_message_bytes,
          "<N> gRPC message size limit, and HTTP request bodies'");
ABSL_FLAG(uint64_t, analysis_threads, gvd::ServerLimits{}.analysis_threads,
          "<N> boundaries, neighbours, Delaunay, zoom windows, clearance and planning calls run "
          "at once on the CPU pool");
ABSL_FLAG(uint64_t, max_queued_analyses, gvd::ServerLimits{}.max_queued_analyses,
          "<N> such calls waiting for their turn before RESOURCE_EXHAUSTED");
ABSL_FLAG(uint64_t, max_queued_writes, gvd::ServerLimits{}.max_queued_writes,
          "<N> writes (CreateScene, DeleteScene, UpsertSites, DeleteSites) waiting for a commit "
          "thread before RESOURCE_EXHAUSTED");
ABSL_FLAG(std::string, metrics_listen, "",
          "<HOST:PORT> serve Prometheus metrics at http://HOST:PORT/metrics (by default off)");
ABSL_FLAG(std::string, http_listen, "",
          "<HOST:PORT> also serve every call over HTTP/1.1 in the Connect protocol (JSON: POST "
          "/gvd.v1.VoronoiService/METHOD), and the web app at / (by default off; the same tokens, TLS, "
          "limits and metrics)");
ABSL_FLAG(uint32_t, http_threads, 0,
          "<N> threads serving the HTTP port's connections, 0 to 64 (by default 0: half the "
          "machine's cores, at least one); a large request or answer is converted off them");
ABSL_FLAG(uint32_t, http_io_timeout_ms,
          static_cast<uint32_t>(gvd::HttpOptions{}.io_timeout.count()),
          "<N> how long an HTTP connection may wait idle for a request and then take to send "
          "it, and how long an answer may take to be sent, before the connection is closed");
ABSL_FLAG(std::vector<std::string>, http_cors_origins, {},
          "<LIST> origins whose pages may call the HTTP port, comma-separated "
          "(\"https://app.example.com\"; \"*\" for any); by default none");
ABSL_FLAG(std::string, tokens, "",
          "<FILE> require bearer tokens: one \"TOKEN read\" or \"TOKEN write\" per line");
ABSL_FLAG(bool, allow_unauthenticated, false,
          "serve --listen or --http-listen beyond loopback without --tokens or --tls-client-ca "
          "(refused otherwise: anyone who reaches the port could write), for a network or a "
          "proxy in front that authenticates");
ABSL_FLAG(std::string, tls_cert, "",
          "<FILE> serve TLS with this certificate chain (PEM), with --tls-key");
ABSL_FLAG(std::string, tls_key, "", "<FILE> the private key of --tls-cert (PEM)");
ABSL_FLAG(std::string, tls_client_ca, "",
          "<FILE> also require client certificates signed by this CA (PEM)");
ABSL_FLAG(std::string, config, "",
          "<FILE> read flags from FILE, one \"--flag value\" per line (# comments); flags on "
          "the command line after --config override it");

namespace {

std::string Usage() {
  return absl::StrCat("usage: gvd-server [flags]\n\n", gvd::flags::Describe("server/main.cc"),
                      "  --help\n  --version\n\nBy default the server listens on loopback only, without TLS "
                      "and without authentication; an API port beyond loopback needs --tokens or "
                      "--tls-client-ca, or --allow-unauthenticated. The metrics port serves "
                      "read-only metrics without authentication wherever it listens.\n");
}

struct Flags {
  std::string listen;
  std::string port_file;
  std::string memory_source;  // where limits.max_memory came from
  int render_threads = 2;
  std::string data;
  std::string postgres;  // --store postgresql://...
  std::string egl_device;
  std::string log_level;
  uint32_t software_render_threads = 0;
  uint32_t grace_ms = 5000;
  uint32_t relaxed_sync_ms = 100;
  uint32_t store_pack_sites = 4096;
  uint32_t store_fold_after_ms = 500;
  uint32_t http_threads = 0;
  uint32_t http_io_timeout_ms = 0;
  std::string tokens, tls_cert, tls_key, tls_client_ca, metrics_listen, http_listen;
  std::vector<std::string> cors_origins;
  gvd::ServerLimits limits;
};

[[noreturn]] void Die(const std::string& message) {
  std::fprintf(stderr, "gvd-server: %s\n%s", message.c_str(), Usage().c_str());
  std::exit(2);
}

// A count flag's value: positive.
template <class T, class Flag>
T Count(const char* name, const Flag& flag) {
  const auto v = absl::GetFlag(flag);
  if (v <= 0) Die(absl::StrCat("--", name, " needs a positive integer, not ", v));
  return static_cast<T>(v);
}

std::string ReadFile(const std::string& flag, const std::string& path) {
  std::ifstream in(path);
  if (!in) Die(absl::StrCat(flag, ": cannot read ", path));
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Whether a listening address takes connections from this machine only: a Unix socket, or a
// host that is "localhost", in 127.0.0.0/8, or ::1 ("[::1]:PORT"). 0.0.0.0, [::], a name or an
// interface's address reach further.
bool LocalOnly(const std::string& address) {
  if (absl::StartsWith(address, "unix:")) return true;
  std::string host = address.substr(0, address.rfind(':'));
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host == "localhost") return true;
  in_addr v4;
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6;
  return inet_pton(AF_INET6, host.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

Flags ParseFlags(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (gvd::flags::WantsHelp(args)) {
    std::fputs(Usage().c_str(), stdout);
    std::exit(0);
  }
  if (args == std::vector<std::string>{"--version"}) {
    std::puts("gvd-server " GVD_VERSION);
    std::exit(0);
  }
  auto expanded = gvd::flags::ExpandConfig(args);
  if (!expanded.ok()) Die(std::string(expanded.status().message()));
  if (auto parsed = gvd::flags::Parse(*expanded, /*words=*/false); !parsed.ok()) {
    Die(std::string(parsed.status().message()));
  }
  Flags f;
  f.listen = absl::GetFlag(FLAGS_listen);
  f.port_file = absl::GetFlag(FLAGS_port_file);
  f.data = absl::GetFlag(FLAGS_data);
  if (const std::string store = absl::GetFlag(FLAGS_store); !store.empty()) {
    if (!f.data.empty()) Die("--store and --data name the same thing: give one");
    if (absl::StartsWith(store, "sqlite://")) {
      f.data = store.substr(std::strlen("sqlite://"));
      if (f.data.empty()) Die("--store sqlite:// needs a directory: sqlite:///DIR");
    } else if (absl::StartsWith(store, "postgresql://") || absl::StartsWith(store, "postgres://")) {
      f.postgres = store;
    } else {
      Die(absl::StrCat("--store \"", store, "\" is neither sqlite:///DIR nor postgresql://..."));
    }
  }
  f.egl_device = absl::GetFlag(FLAGS_egl_device);
  f.log_level = absl::GetFlag(FLAGS_log_level);
  f.software_render_threads = absl::GetFlag(FLAGS_software_render_threads);
  if (f.software_render_threads > 64) {
    Die(absl::StrCat("--software-render-threads needs 0 to 64, not ", f.software_render_threads));
  }
  f.render_threads = Count<int>("render-threads", FLAGS_render_threads);
  f.grace_ms = Count<uint32_t>("shutdown-grace-ms", FLAGS_shutdown_grace_ms);
  f.relaxed_sync_ms = Count<uint32_t>("relaxed-sync-ms", FLAGS_relaxed_sync_ms);
  if (f.relaxed_sync_ms > 60000) {
    Die(absl::StrCat("--relaxed-sync-ms needs 1 to 60000, not ", f.relaxed_sync_ms));
  }
  f.store_pack_sites = Count<uint32_t>("store-pack-sites", FLAGS_store_pack_sites);
  f.store_fold_after_ms = Count<uint32_t>("store-fold-after-ms", FLAGS_store_fold_after_ms);
  if (f.store_fold_after_ms > 60000) {
    Die(absl::StrCat("--store-fold-after-ms needs 1 to 60000, not ", f.store_fold_after_ms));
  }
  f.tokens = absl::GetFlag(FLAGS_tokens);
  f.tls_cert = absl::GetFlag(FLAGS_tls_cert);
  f.tls_key = absl::GetFlag(FLAGS_tls_key);
  f.tls_client_ca = absl::GetFlag(FLAGS_tls_client_ca);
  f.metrics_listen = absl::GetFlag(FLAGS_metrics_listen);
  f.http_listen = absl::GetFlag(FLAGS_http_listen);
  f.http_threads = absl::GetFlag(FLAGS_http_threads);
  if (f.http_threads > 64) Die(absl::StrCat("--http-threads needs 0 to 64, not ", f.http_threads));
  f.http_io_timeout_ms = Count<uint32_t>("http-io-timeout-ms", FLAGS_http_io_timeout_ms);
  // An API port others can reach, open to any write, only when asked for in so many words.
  if (f.tokens.empty() && f.tls_client_ca.empty() && !absl::GetFlag(FLAGS_allow_unauthenticated)) {
    for (const auto& [flag, address] : {std::pair{"--listen", f.listen}, {"--http-listen", f.http_listen}}) {
      if (!address.empty() && !LocalOnly(address)) {
        Die(absl::StrCat(flag, " ", address,
                         " reaches beyond loopback, where anyone who reaches it could write: give "
                         "--tokens FILE (or --tls-client-ca), or --allow-unauthenticated to serve "
                         "it open on purpose"));
      }
    }
  }
  for (const std::string& origin : absl::GetFlag(FLAGS_http_cors_origins)) {
    if (const auto o = absl::StripAsciiWhitespace(origin); !o.empty()) f.cors_origins.emplace_back(o);
  }
  gvd::ServerLimits& l = f.limits;
  l.max_scenes = Count<size_t>("max-scenes", FLAGS_max_scenes);
  l.max_sites_per_scene = Count<size_t>("max-sites-per-scene", FLAGS_max_sites_per_scene);
  l.max_side_px = Count<uint32_t>("max-side-px", FLAGS_max_side_px);
  l.max_points_per_query = Count<size_t>("max-points-per-query", FLAGS_max_points_per_query);
  l.max_sites_per_request = Count<size_t>("max-sites-per-request", FLAGS_max_sites_per_request);
  l.max_vertices_per_site = Count<size_t>("max-vertices-per-site", FLAGS_max_vertices_per_site);
  l.max_voxels_per_scene = Count<uint64_t>("max-voxels-per-scene", FLAGS_max_voxels_per_scene);
  l.max_triangles_per_mesh =
      Count<size_t>("max-triangles-per-mesh", FLAGS_max_triangles_per_mesh);
  l.max_message_bytes = Count<int>("max-message-bytes", FLAGS_max_message_bytes);
  l.analysis_threads = Count<size_t>("analysis-threads", FLAGS_analysis_threads);
  l.max_queued_analyses = Count<size_t>("max-queued-analyses", FLAGS_max_queued_analyses);
  l.max_queued_writes = Count<size_t>("max-queued-writes", FLAGS_max_queued_writes);
  l.max_scene_pixels = uint64_t{l.max_side_px} * l.max_side_px;
  if (const std::string memory = absl::GetFlag(FLAGS_max_memory); !memory.empty()) {
    auto bytes = gvd::ParseBytes(memory);
    if (!bytes) {
      Die(absl::StrCat("--max-memory needs a size such as 4G, 512M or 1073741824, not \"",
                       memory, "\""));
    }
    l.max_memory = *bytes;
    f.memory_source = "--max-memory";
  } else {
    l.max_memory = gvd::DefaultMaxMemory("/sys/fs/cgroup", &f.memory_source);
  }
  if (f.data.empty() && f.postgres.empty()) {
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
  // Debian builds abseil without NDEBUG, so absl::Mutex (gRPC's lock) would record every lock
  // in a process-wide graph of lock orders, under one spin lock, to catch deadlock cycles: a
  // debugging aid that costs a one-point FindNearest over gRPC some 16% of its instructions.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
#ifdef GVD_TCMALLOC
  gvd::UseHugePages();
#endif
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

  // The renderers, both sides of the render seam, reporting through the same logs and
  // metrics: the GL render threads of 2D scenes and the CPU render thread of 3D ones.
  gvd::Metrics metrics;
  gvd::RenderTelemetry render_telemetry(&metrics);
  gvd::RenderLoop renderer(flags.render_threads, &render_telemetry);
  gvd::VolumeRenderer volumes(&render_telemetry);
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
            {"render_threads", absl::StrCat(renderer.lanes())},
            // Whether renders nobody waits for run in the background (render/scene/cpu_pool.h).
            {"background_renders", gvd::RenderWait::Background() ? "true" : "false"}});

  absl::StatusOr<std::unique_ptr<gvd::SceneStore>> store;
  if (!flags.postgres.empty()) {
    store = gvd::PostgresStore::Open(flags.postgres);
  } else {
    if (flags.data != ":memory:") MakeParents(flags.data);
    auto sqlite = gvd::SqliteStore::Open(flags.data, gvd::LegacyRecords(flags.limits));
    if (sqlite.ok()) {
      (*sqlite)->set_relaxed_sync(std::chrono::milliseconds(flags.relaxed_sync_ms));
      gvd::SqliteStore::Packing packing;
      packing.min_sites = flags.store_pack_sites;
      packing.fold_after = std::chrono::milliseconds(flags.store_fold_after_ms);
      (*sqlite)->set_packing(packing);
    }
    store = std::move(sqlite);
  }
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
      std::make_unique<gvd::SceneRegistry>(store->get(), gvd::Renderers{&renderer, &volumes},
                                            flags.limits, &metrics);
  // The application core's calls; the transports over them come below.
  gvd::Service core(registry.get(), auth ? &*auth : nullptr, &metrics);
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
    volumes.Stop();
    metrics.StopSampling();
    registry.reset();
    store->reset();
  };
  // gRPC: the core's calls, health and reflection. Not serving until every stored scene is
  // rebuilt; calls meanwhile get UNAVAILABLE.
  gvd::GrpcOptions grpc_options;
  grpc_options.listen = flags.listen;
  grpc_options.credentials = credentials;
  grpc_options.max_message_bytes = flags.limits.max_message_bytes;
  auto grpc_started = gvd::GrpcServer::Start(std::move(grpc_options), &core);
  if (!grpc_started.ok()) {
    gvd::Log(gvd::LogLevel::kError, "listen_failed", {{"address", flags.listen}});
    stop();
    return 1;
  }
  std::unique_ptr<gvd::GrpcServer> server = std::move(*grpc_started);
  const int port = server->port();
  gvd::Log(gvd::LogLevel::kInfo, "listening",
           {{"address", flags.listen}, {"port", absl::StrCat(port)}, {"version", GVD_VERSION}});
  // HTTP: the same core's calls, over the Connect protocol.
  std::unique_ptr<gvd::HttpServer> http;
  if (!flags.http_listen.empty()) {
    gvd::HttpOptions options;
    options.listen = flags.http_listen;
    options.cors_origins = flags.cors_origins;
    options.max_body_bytes = flags.limits.max_message_bytes;
    options.files = gvd::WebApp();
    options.threads = static_cast<int>(flags.http_threads);
    options.io_timeout = std::chrono::milliseconds(flags.http_io_timeout_ms);
    if (!flags.tls_cert.empty()) {
      options.tls_cert = ReadFile("--tls-cert", flags.tls_cert);
      options.tls_key = ReadFile("--tls-key", flags.tls_key);
      if (!flags.tls_client_ca.empty()) {
        options.tls_client_ca = ReadFile("--tls-client-ca", flags.tls_client_ca);
      }
    }
    auto started = gvd::HttpServer::Start(std::move(options), &core);
    if (!started.ok()) {
      gvd::Log(gvd::LogLevel::kError, "http_failed", {{"error", started.status().ToString()}});
      server->Shutdown(std::chrono::system_clock::now());
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
    server->Shutdown(std::chrono::system_clock::now());
    stop();
    return 1;
  }
  server->SetServing(true);
  // "liveness": the process serves, whatever its store does (for a liveness probe that must
  // not restart a replica that waits for its database); "" (the server as a whole) is
  // readiness.
  server->SetServing("liveness", true);
  gvd::Log(gvd::LogLevel::kInfo, "store", {{"store", (*store)->Describe()},
                                           {"shared", (*store)->shared() ? "true" : "false"}});
  // A replica follows the store; its health says NOT_SERVING while it cannot read the store
  // and until it has caught up again.
  std::atomic<bool> stopping{false};
  std::thread health;
  if ((*store)->shared()) {
    registry->StartFollowing();
    health = std::thread([&] {
      bool serving = true;
      while (!stopping) {
        const bool now = registry->caught_up();
        if (now != serving) server->SetServing("", now);
        serving = now;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    });
  }
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
           {{"signal", strsignal(sig)}, {"in_flight", absl::StrCat(core.in_flight())}});
  // Drain: health says NOT_SERVING, new calls are refused, calls in flight get the grace
  // period to finish; whatever is left then is cancelled.
  stopping = true;
  if (health.joinable()) health.join();
  server->SetServing(false);
  int left = core.Drain(std::chrono::milliseconds(flags.grace_ms));
  // HTTP connections finish the response under way, idle ones close.
  if (http) http->Shutdown(std::chrono::milliseconds(std::min<uint32_t>(flags.grace_ms, 1000)));
  server->Shutdown(std::chrono::system_clock::now());
  stop();
  gvd::Log(gvd::LogLevel::kInfo, "stopped", {{"cancelled_calls", absl::StrCat(left)}});
  return 0;
}
