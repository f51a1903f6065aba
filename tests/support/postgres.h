// A PostgreSQL server of the test's own, from Debian's postgresql package: a cluster made by
// initdb in a temporary directory, listening on a Unix socket there (and on 127.0.0.1 at a
// free port), stopped and removed when the object goes. Run as the "postgres" user when
// the test runs as root (PostgreSQL refuses root). The tests that need it fail, not skip,
// when it cannot start: CI installs the package. Options put it in a network namespace of
// the test's (ip netns) and on the addresses given there; the Unix socket, a file, is
// reached from anywhere.
#pragma once

#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <netinet/in.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <glob.h>
#include <iterator>
#include <string>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"

namespace gvd::testing {

class TempPostgres {
 public:
  struct Options {
    std::string netns;                 // "": the test's own
    std::string listen = "127.0.0.1";  // listen_addresses, comma-separated
  };
  TempPostgres() : TempPostgres(Options{}) {}
  explicit TempPostgres(Options options) : options_(std::move(options)) {
    char dir[] = "/tmp/gvd-pg-XXXXXX";
    dir_ = mkdtemp(dir);
    bin_ = FindBin();
    port_ = FreePort();
    if (bin_.empty()) {
      error_ = "no PostgreSQL server (install Debian's postgresql package)";
      return;
    }
    as_ = getuid() == 0 ? "runuser -u postgres -- " : "";
    if (getuid() == 0) Sh(absl::StrCat("chown postgres '", dir_, "'"));
    if (Sh(absl::StrCat(as_, bin_, "/initdb -D '", dir_, "/data' -A trust -U gvd -E UTF8 ",
                        "--no-sync >'", dir_, "/initdb.log' 2>&1")) != 0) {
      error_ = absl::StrCat("initdb failed: see ", dir_, "/initdb.log");
      return;
    }
    // In a namespace of the test's own, any address there may connect.
    if (!options_.netns.empty()) {
      std::ofstream(dir_ + "/data/pg_hba.conf", std::ios::app) << "host all all 0.0.0.0/0 trust\n";
    }
    if (!Start()) return;
    if (Sh(absl::StrCat(as_, bin_, "/createdb -h '", dir_, "' -p ", port_, " -U gvd gvd")) != 0) {
      error_ = "createdb failed";
    }
  }
  // A streaming standby of `primary`, copied from it by pg_basebackup and started on a port of
  // its own; with `synchronous`, the primary then waits for it to flush each commit before
  // the commit returns (synchronous_standby_names). error() says when it does not stream.
  TempPostgres(const TempPostgres& primary, bool synchronous) : options_(primary.options_) {
    char dir[] = "/tmp/gvd-pg-XXXXXX";
    dir_ = mkdtemp(dir);
    bin_ = primary.bin_;
    as_ = primary.as_;
    port_ = FreePort();
    if (getuid() == 0) Sh(absl::StrCat("chown postgres '", dir_, "'"));
    if (Sh(absl::StrCat(as_, bin_, "/pg_basebackup -h '", primary.dir_, "' -p ", primary.port_,
                        " -U gvd -D '", dir_, "/data' -R -X stream -c fast --no-sync >'", dir_,
                        "/basebackup.log' 2>&1")) != 0) {
      error_ = absl::StrCat("pg_basebackup failed: see ", dir_, "/basebackup.log");
      return;
    }
    if (!Start()) return;
    if (synchronous) {
      primary.Sql("ALTER SYSTEM SET synchronous_standby_names = '*'");
      primary.Sql("SELECT pg_reload_conf()");
    }
    const std::string streaming = absl::StrCat(
        "SELECT count(*) FROM pg_stat_replication WHERE state = 'streaming'",
        synchronous ? " AND sync_state = 'sync'" : "");
    for (int i = 0; i < 300 && primary.Sql(streaming) != "1"; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (primary.Sql(streaming) != "1") error_ = "the standby does not stream from its primary";
  }
  ~TempPostgres() {
    Stop();
    Sh(absl::StrCat("rm -rf '", dir_, "'"));
  }
  TempPostgres(const TempPostgres&) = delete;
  TempPostgres& operator=(const TempPostgres&) = delete;

  // Empty when the server runs; else why it does not.
  const std::string& error() const { return error_; }
  // The URL of its database "gvd", over the Unix socket.
  std::string url() const {
    return absl::StrCat("postgresql://gvd@/gvd?host=", dir_, "&port=", port_);
  }
  // The same over TCP.
  std::string tcp_url() const {
    return absl::StrCat("postgresql://gvd@127.0.0.1:", port_, "/gvd");
  }
  int port() const { return port_; }
  // A new, empty database of the server; its URL (over the Unix socket), or "" on failure.
  std::string NewDatabase(const std::string& name) const {
    if (Sh(absl::StrCat(as_, bin_, "/createdb -h '", dir_, "' -p ", port_, " -U gvd ", name)) != 0) {
      return "";
    }
    return absl::StrCat("postgresql://gvd@/", name, "?host=", dir_, "&port=", port_);
  }

  // Starts the server (again), waiting until it takes connections.
  bool Start() {
    const std::string in = options_.netns.empty() ? "" : "ip netns exec " + options_.netns + " ";
    if (Sh(absl::StrCat(in, as_, bin_, "/pg_ctl -D '", dir_, "/data' -l '", dir_, "/server.log' ",
                        "-w -t 60 -o \"-k '", dir_, "' -p ", port_,
                        " -c listen_addresses=", options_.listen,
                        " -c fsync=off -c full_page_writes=off"
                        " -c max_connections=200\" start >/dev/null 2>&1")) != 0) {
      error_ = absl::StrCat("PostgreSQL did not start: see ", dir_, "/server.log");
      return false;
    }
    return true;
  }
  // The socket directory (a host in a libpq URL).
  const std::string& dir() const { return dir_; }
  // Runs one statement in database "gvd" with psql; what it prints, without the newline.
  std::string Sql(const std::string& statement) const {
    const std::string out = absl::StrCat(dir_, "/sql.out");
    Sh(absl::StrCat(bin_, "/psql -h '", dir_, "' -p ", port_, " -U gvd -d gvd -XAtqc \"",
                    statement, "\" >'", out, "' 2>&1"));
    std::ifstream in(out);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    while (!text.empty() && text.back() == '\n') text.pop_back();
    return text;
  }
  // Promotes a standby to a primary, waiting until it takes writes.
  bool Promote() const {
    return Sh(absl::StrCat(as_, bin_, "/pg_ctl -D '", dir_, "/data' -w promote >/dev/null 2>&1")) ==
           0;
  }
  // Copies its data directory aside as `name`, or puts that copy back in its place: a
  // backup taken and restored, the database going back in time. CONTRACT: stopped.
  bool SaveData(const std::string& name) const {
    return Sh(absl::StrCat("cp -a '", dir_, "/data' '", dir_, "/", name, "'")) == 0;
  }
  bool RestoreData(const std::string& name) const {
    return Sh(absl::StrCat("rm -rf '", dir_, "/data' && cp -a '", dir_, "/", name, "' '", dir_,
                           "/data'")) == 0;
  }
  // Stops it: "fast" (clients disconnected, a clean shutdown) or "immediate" (a crash).
  void Stop(const char* mode = "fast") {
    Sh(absl::StrCat(as_, bin_, "/pg_ctl -D '", dir_, "/data' -m ", mode,
                    " -w stop >/dev/null 2>&1"));
  }

 private:
  static int Sh(const std::string& command) { return std::system(command.c_str()); }
  static std::string FindBin() {
    glob_t g;
    std::string bin;
    if (glob("/usr/lib/postgresql/*/bin/pg_ctl", 0, nullptr, &g) == 0 && g.gl_pathc > 0) {
      bin = std::filesystem::path(g.gl_pathv[g.gl_pathc - 1]).parent_path();
    }
    globfree(&g);
    return bin;
  }
  static int FreePort() {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t n = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
    close(fd);
    return ntohs(a.sin_port);
  }

  Options options_;
  std::string dir_, bin_, as_, error_;
  int port_ = 0;
};

// One server for a whole test program (each test takes a database of its own with
// NewDatabase), stopped and removed at exit.
inline TempPostgres& SharedPostgres() {
  static TempPostgres pg;
  return pg;
}

}  // namespace gvd::testing
