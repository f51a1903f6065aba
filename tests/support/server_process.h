// Starts the real gvd-server binary on a loopback port chosen by the kernel, for
// integration tests; stops it with SIGTERM.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include <gtest/gtest.h>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "gvd/client.h"
#include "tests/support/test_scenes.h"

namespace gvd::testing {

class ServerProcess {
 public:
  // Starts `binary` with --listen 127.0.0.1:0 and the extra flags (a --listen among them
  // wins: "unix:PATH" becomes the address), under the command `prefix` when one is given
  // (such as {"ip", "netns", "exec", NAME}); waits until it has written its port. On
  // failure, error() says why.
  ServerProcess(const std::string& binary, std::vector<std::string> flags = {},
                std::vector<std::string> prefix = {}) {
    char dir_template[] = "/tmp/gvd-test-XXXXXX";
    dir_ = mkdtemp(dir_template);
    std::string port_file = dir_ + "/port";
    log_ = dir_ + "/server.log";
    std::vector<std::string> args = {binary, "--listen", "127.0.0.1:0", "--port-file", port_file};
    if (std::find(flags.begin(), flags.end(), "--data") == flags.end() &&
        std::find(flags.begin(), flags.end(), "--store") == flags.end()) {
      args.insert(args.end(), {"--data", dir_ + "/data"});
    }
    args.insert(args.end(), flags.begin(), flags.end());
    if (auto listen = std::find(flags.begin(), flags.end(), "--listen");
        listen != flags.end() && listen + 1 != flags.end() && listen[1].rfind("unix:", 0) == 0) {
      unix_address_ = listen[1];
    }
    args.insert(args.begin(), prefix.begin(), prefix.end());
    pid_ = fork();
    if (pid_ == 0) {
      setenv("GVD_TEST_HOLD_RENDERS", hold_renders_path().c_str(), 1);
      setenv("GVD_TEST_HOLD_CONVERSIONS", hold_conversions_path().c_str(), 1);
      FILE* log = std::fopen(log_.c_str(), "w");
      dup2(fileno(log), STDERR_FILENO);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execvp(argv[0], argv.data());
      _exit(127);
    }
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline) {
      std::ifstream in(port_file);
      if (in >> port_) {
        in >> http_port_;  // the second line, when the server serves HTTP
        return;
      }
      int status;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        error_ = "gvd-server exited at start: " + log();
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    error_ = "gvd-server wrote no port within 60 s: " + log();
  }

  // While a file exists here, the server renders no scene (its test hook
  // GVD_TEST_HOLD_RENDERS): see HoldRenders.
  std::string hold_renders_path() const { return dir_ + "/hold-renders"; }
  // While a file exists here, a large conversion of either transport waits (their test hook
  // GVD_TEST_HOLD_CONVERSIONS), a file at this path + ".waiting" existing meanwhile.
  std::string hold_conversions_path() const { return dir_ + "/hold-conversions"; }

  // Stops the server with SIGTERM and fails the running test unless it exits 0: a crash at
  // shutdown, or a sanitizer report (they change the exit status), is a failure.
  ~ServerProcess() {
    if (pid_ > 0) {
      int status = Stop();
      if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
        ADD_FAILURE() << "gvd-server did not exit cleanly (wait status " << status << "):\n" << log();
      }
    }
    std::system(("rm -rf " + dir_).c_str());
  }

  // Kills the server with SIGKILL, as a crash would.
  void Kill() {
    if (pid_ <= 0) return;
    kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }

  // Sends SIGTERM and waits; returns the exit status as waitpid reports it.
  int Stop() {
    Terminate();
    return Wait();
  }
  // Sends SIGTERM: the server drains and exits in its own time (see Wait).
  void Terminate() {
    if (pid_ > 0) kill(pid_, SIGTERM);
  }
  // Waits for the server to exit; returns the exit status as waitpid reports it.
  int Wait() {
    if (pid_ <= 0) return -1;
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return status;
  }

  const std::string& error() const { return error_; }
  std::string address() const {
    return unix_address_.empty() ? "127.0.0.1:" + std::to_string(port_) : unix_address_;
  }
  // The HTTP port (--http-listen), 0 when none.
  int http_port() const { return http_port_; }
  const std::string& dir() const { return dir_; }
  pid_t pid() const { return pid_; }
  std::string log() const {
    std::ifstream in(log_);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

 private:
  std::string dir_, log_, error_, unix_address_;
  pid_t pid_ = -1;
  int port_ = 0, http_port_ = 0;
};

// Holds a server's renders from construction to destruction, so that a version stays
// unrendered for as long as a test needs, however fast the machine renders.
class HoldRenders {
 public:
  explicit HoldRenders(const ServerProcess& server) : path_(server.hold_renders_path()) {
    std::ofstream(path_) << "held\n";
  }
  ~HoldRenders() { std::remove(path_.c_str()); }
  HoldRenders(const HoldRenders&) = delete;
  HoldRenders& operator=(const HoldRenders&) = delete;

 private:
  std::string path_;
};

// Waits up to two minutes for a file to exist at `path`; whether it came. A test hook's
// ".waiting" file says that what it holds has begun.
inline bool WaitForFile(const std::string& path) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(2);
  while (access(path.c_str(), F_OK) != 0) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

// Waits up to two minutes for the held render of `scene` to begin: the render that waits while
// a file exists at the hook's path + "." + the scene's id (see RenderLoop's test hook);
// whether it began.
inline bool WaitForHeldRender(const ServerProcess& server, const std::string& scene) {
  return WaitForFile(server.hold_renders_path() + "." + scene + ".waiting");
}

// The version of the scene's newest frame.
inline uint64_t RenderedVersion(Client& client, const std::string& scene) {
  v1::Scene s;
  EXPECT_TRUE(client.GetScene(scene, &s).ok());
  return s.rendered_version();
}

// Waits up to 60 s for the scene's frame to reach `version`; whether it did. (A read at the
// version may be answered before its render: see FindNearestRequest.min_version.)
inline bool WaitForRender(Client& client, const std::string& scene, uint64_t version) {
  for (int k = 0; k < 6000; ++k) {
    if (RenderedVersion(client, scene) >= version) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// A suite whose tests share one gvd-server and a client of it. The server must stop cleanly
// at the end: SIGTERM is a clean shutdown, exit status 0. A suite that needs server flags
// hides SetUpTestSuite with one that calls StartServer(flags).
class SharedServerTest : public ::testing::Test {
 protected:
  static void StartServer(std::vector<std::string> flags = {}) {
    server_ = new ServerProcess(GVD_SERVER_PATH, std::move(flags));
    ASSERT_TRUE(server_->error().empty()) << server_->error();
    client_ = Client::Connect(server_->address()).release();
    ASSERT_TRUE(client_->WaitForConnected(std::chrono::seconds(10)));
  }
  static void SetUpTestSuite() { StartServer(); }
  // Upserts the sites into the scene; the version it brings, or 0 (and a failure).
  static uint64_t Upsert(const std::string& scene, const SiteTable& sites) {
    v1::UpsertSitesRequest r;
    r.set_scene_id(scene);
    for (const Site& s : sites) *r.add_sites() = ToProtoSite(s);
    uint64_t version = 0;
    auto st = client_->UpsertSites(r, &version);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return version;
  }
  static void TearDownTestSuite() {
    delete client_;
    client_ = nullptr;
    int status = server_->Stop();
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server_->log();
    delete server_;
    server_ = nullptr;
  }

  static inline ServerProcess* server_ = nullptr;
  static inline Client* client_ = nullptr;
};

}  // namespace gvd::testing
