// Three gvd-server replicas on one PostgreSQL (started by the test from Debian's package),
// under a stream of writes through each of them, while faults strike: a replica killed with
// SIGKILL and started again, the database stopped and started under load, a replica frozen
// (SIGSTOP) while 10,000 site changes land elsewhere. The oracle is the writes each writer
// made and what the server said of them: an acknowledged write must be in the final state; a
// write that failed may or may not be (the kill or the outage cut its answer), but nothing
// else may. Every replica must end up with the same sites at the same version.
#include <gtest/gtest.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "gvd/client.h"
#include "tests/support/postgres.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using testing::ServerProcess;
using testing::TempPostgres;
using Point = std::pair<double, double>;

std::unique_ptr<ServerProcess> StartReplica(const TempPostgres& pg) {
  auto server = std::make_unique<ServerProcess>(
      GVD_SERVER_PATH, std::vector<std::string>{"--store", pg.url(), "--render-threads", "1"});
  EXPECT_TRUE(server->error().empty()) << server->error();
  return server;
}

bool Eventually(const std::function<bool()>& done, int seconds = 30) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

grpc::health::v1::HealthCheckResponse::ServingStatus Health(const ServerProcess& server) {
  auto stub = grpc::health::v1::Health::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(2));
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  if (!stub->Check(&ctx, request, &response).ok()) return response.UNKNOWN;
  return response.status();
}

// What a replica holds: its version and sites.
struct Held {
  uint64_t version = 0;
  std::map<std::string, Point> sites;
  bool operator==(const Held& o) const { return version == o.version && sites == o.sites; }
};

std::optional<Held> Read(const ServerProcess& server, const std::string& scene) {
  auto client = Client::Connect(server.address());
  v1::Scene s;
  if (!client->GetScene(scene, &s).ok()) return std::nullopt;
  std::vector<v1::Site> sites;
  if (!client->ListAllSites(scene, &sites).ok()) return std::nullopt;
  Held h;
  h.version = s.version();
  for (const auto& site : sites) h.sites[site.id()] = {site.point().x(), site.point().y()};
  // The listing and the version are one state only if nothing changed between the reads.
  if (!client->GetScene(scene, &s).ok() || s.version() != h.version) return std::nullopt;
  return h;
}

// One writer: sites of its own ids, through one replica, one write at a time. Each write
// puts or removes one site; what the server answered is kept.
class Writer {
 public:
  Writer(int index) : index_(index), rng_(100 + index) {}

  // Writes until stop is set, through whichever server `server()` gives (it may be down).
  void Run(const std::function<std::string()>& address, const std::atomic<bool>& stop) {
    std::uniform_real_distribution<double> u(0, 1);
    std::unique_ptr<Client> client;
    std::string connected;
    ClientOptions options;
    // Generous: a call to the frozen replica waits for it; the server itself never lets a
    // call hang on the database (the outage's failures are checked to be UNAVAILABLE).
    options.timeout = std::chrono::seconds(120);
    while (!stop) {
      const std::string target = address();
      if (target != connected) {
        client = Client::Connect(target, options);
        connected = target;
      }
      Write w;
      w.id = "w" + std::to_string(index_) + "-" + std::to_string(rng_() % 40);
      const bool remove = held_.count(w.id) && rng_() % 3 == 0;
      if (!remove) w.point = Point{u(rng_), u(rng_)};
      const auto start = std::chrono::steady_clock::now();
      grpc::Status s;
      uint64_t version = 0;
      if (remove) {
        s = client->DeleteSites("scene", {w.id}, &version);
      } else {
        v1::UpsertSitesRequest r;
        r.set_scene_id("scene");
        auto* site = r.add_sites();
        site->set_id(w.id);
        site->mutable_point()->set_x(w.point->first);
        site->mutable_point()->set_y(w.point->second);
        s = client->UpsertSites(r, &version);
      }
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(mu_);
      slowest_ = std::max(slowest_, seconds);
      w.acknowledged = s.ok();
      if (s.ok()) {
        ++acknowledged_;
        if (w.point) {
          held_[w.id] = *w.point;
        } else {
          held_.erase(w.id);
        }
      } else {
        ++failed_;
        codes_[s.error_code()]++;
        if (s.error_code() == grpc::StatusCode::NOT_FOUND) {
          w.acknowledged = true;  // the site was not there: an earlier failed delete took it
          held_.erase(w.id);
        }
        // Overtaken by other servers' writes on every try: refused whole, nothing stored.
        if (s.error_code() == grpc::StatusCode::ABORTED) continue;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      writes_.push_back(w);
    }
  }

  // Whether `sites` (every site of this writer's ids) can be what the writes left: for each
  // id, the last acknowledged write's value (absent before any) or that of a failed write
  // made after it.
  void ExpectExplains(const std::map<std::string, Point>& sites) const {
    std::lock_guard<std::mutex> lock(mu_);
    // Each id starts absent; an acknowledged write fixes its value, a failed one may or may
    // not have taken effect.
    std::map<std::string, std::vector<std::optional<Point>>> possible;
    for (const Write& w : writes_) {
      auto& p = possible.try_emplace(w.id, std::vector<std::optional<Point>>{std::nullopt})
                    .first->second;
      if (w.acknowledged) p.clear();
      p.push_back(w.point);
    }
    const std::string prefix = "w" + std::to_string(index_) + "-";
    for (const auto& [id, point] : sites) {
      if (id.rfind(prefix, 0) != 0) continue;
      auto it = possible.find(id);
      ASSERT_NE(it, possible.end()) << id << " was never written";
      EXPECT_NE(std::find(it->second.begin(), it->second.end(), std::optional<Point>(point)),
                it->second.end())
          << id << " holds a value no write left";
    }
    for (const auto& [id, values] : possible) {
      if (sites.count(id)) continue;
      EXPECT_NE(std::find(values.begin(), values.end(), std::nullopt), values.end())
          << id << " is missing, though an acknowledged write put it and none removed it";
    }
  }

  int acknowledged() const {
    std::lock_guard<std::mutex> lock(mu_);
    return acknowledged_;
  }
  std::string Summary() const {
    std::lock_guard<std::mutex> lock(mu_);
    std::string codes;
    for (const auto& [code, n] : codes_) codes += " code" + std::to_string(code) + "x" + std::to_string(n);
    return "writer " + std::to_string(index_) + ": " + std::to_string(acknowledged_) +
           " acknowledged, " + std::to_string(failed_) + " failed (" + codes + "), slowest " +
           std::to_string(slowest_) + " s";
  }
  int failures_other_than_unavailable() const {
    std::lock_guard<std::mutex> lock(mu_);
    int n = 0;
    for (const auto& [code, count] : codes_) {
      if (code != grpc::StatusCode::UNAVAILABLE && code != grpc::StatusCode::NOT_FOUND &&
          code != grpc::StatusCode::ABORTED) {
        n += count;
      }
    }
    return n;
  }

 private:
  struct Write {
    std::string id;
    std::optional<Point> point;  // none: removed
    bool acknowledged = false;
  };
  const int index_;
  std::mt19937_64 rng_;
  mutable std::mutex mu_;
  std::vector<Write> writes_;
  std::map<std::string, Point> held_;
  std::map<int, int> codes_;
  int acknowledged_ = 0, failed_ = 0;
  double slowest_ = 0;
};

TEST(ReplicaFaults, ThreeReplicasKeepEveryAcknowledgedWrite) {
  TempPostgres pg;
  ASSERT_EQ(pg.error(), "");
  std::vector<std::unique_ptr<ServerProcess>> replicas;
  for (int i = 0; i < 3; ++i) replicas.push_back(StartReplica(pg));
  std::mutex replicas_mu;
  auto address = [&](int i) {
    return [&, i] {
      std::lock_guard<std::mutex> lock(replicas_mu);
      return replicas[i]->address();
    };
  };
  v1::Scene made;
  ASSERT_TRUE(Client::Connect(replicas[0]->address())
                  ->CreateScene(testing::UnitScene("scene", 64, 64), &made)
                  .ok());
  for (auto& r : replicas) ASSERT_TRUE(Eventually([&] { return Read(*r, "scene").has_value(); }));

  std::atomic<bool> stop{false};
  std::vector<std::unique_ptr<Writer>> writers;
  std::vector<std::thread> threads;
  // Whatever assertion ends the test, the writers stop first.
  struct Joiner {
    std::atomic<bool>& stop;
    std::vector<std::thread>& threads;
    ~Joiner() {
      stop = true;
      for (auto& t : threads) {
        if (t.joinable()) t.join();
      }
    }
  } joiner{stop, threads};
  for (int i = 0; i < 3; ++i) writers.push_back(std::make_unique<Writer>(i));
  for (int i = 0; i < 3; ++i) {
    threads.emplace_back([&, i] { writers[i]->Run(address(i), stop); });
  }
  auto progress = [&](int writes) {
    const int start = writers[0]->acknowledged() + writers[2]->acknowledged();
    return Eventually([&] {
      return writers[0]->acknowledged() + writers[2]->acknowledged() >= start + writes;
    });
  };
  ASSERT_TRUE(progress(60));

  // A replica killed in the middle of its writer's stream; the others keep serving.
  replicas[1]->Kill();
  ASSERT_TRUE(progress(60));
  {
    std::lock_guard<std::mutex> lock(replicas_mu);
    replicas[1] = StartReplica(pg);
  }
  ASSERT_TRUE(Eventually([&] { return writers[1]->acknowledged() > 0; }));
  ASSERT_TRUE(progress(60));

  // The database stopped under load: writes fail at once with UNAVAILABLE, replicas keep
  // answering reads and say NOT_SERVING; started again, they resume by themselves.
  pg.Stop();
  EXPECT_TRUE(Eventually([&] { return Health(*replicas[0]) == grpc::health::v1::HealthCheckResponse::NOT_SERVING; }, 10));
  {
    auto during = Read(*replicas[2], "scene");
    EXPECT_TRUE(during.has_value());  // reads go on from the last state
    v1::UpsertSitesRequest r;
    r.set_scene_id("scene");
    auto* site = r.add_sites();
    site->set_id("outage");
    site->mutable_point()->set_x(0.5);
    site->mutable_point()->set_y(0.5);
    uint64_t version;
    grpc::Status s = Client::Connect(replicas[2]->address())->UpsertSites(r, &version);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAVAILABLE) << s.error_message();
    v1::Scene lag;
    ASSERT_TRUE(Client::Connect(replicas[2]->address())->GetScene("scene", &lag).ok());
    EXPECT_GT(lag.store_version(), 0u);
    EXPECT_GT(lag.store_read_age_seconds(), 0.0);
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));
  ASSERT_TRUE(pg.Start()) << pg.error();
  for (auto& r : replicas) {
    EXPECT_TRUE(Eventually([&] { return Health(*r) == grpc::health::v1::HealthCheckResponse::SERVING; }));
  }
  ASSERT_TRUE(progress(60));

  // A replica frozen while 10,000 site changes land through another: thawed, it catches up
  // from the log.
  kill(replicas[2]->pid(), SIGSTOP);
  {
    auto client = Client::Connect(replicas[0]->address());
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(0, 1);
    for (int batch = 0; batch < 50; ++batch) {
      v1::UpsertSitesRequest r;
      r.set_scene_id("scene");
      for (int k = 0; k < 200; ++k) {
        auto* site = r.add_sites();
        site->set_id("bulk-" + std::to_string(batch * 200 + k));
        site->mutable_point()->set_x(u(rng));
        site->mutable_point()->set_y(u(rng));
      }
      uint64_t version;
      ASSERT_TRUE(client->UpsertSites(r, &version).ok());
    }
  }
  kill(replicas[2]->pid(), SIGCONT);
  stop = true;
  for (auto& t : threads) t.join();
  for (const auto& w : writers) {
    std::printf("%s\n", w->Summary().c_str());
    // A write that failed did so with UNAVAILABLE (the database or its replica was down),
    // never by running into the client's deadline.
    EXPECT_EQ(w->failures_other_than_unavailable(), 0) << w->Summary();
  }

  // Every replica holds the same state, which the writes explain.
  std::optional<Held> first;
  ASSERT_TRUE(Eventually([&] {
    first = Read(*replicas[0], "scene");
    if (!first) return false;
    for (auto& r : replicas) {
      auto held = Read(*r, "scene");
      if (!held || !(*held == *first)) return false;
    }
    return true;
  })) << "the replicas did not converge";
  EXPECT_FALSE(first->sites.count("outage"));
  size_t bulk = 0;
  for (const auto& [id, p] : first->sites) bulk += id.rfind("bulk-", 0) == 0;
  EXPECT_EQ(bulk, 10000u);
  for (const auto& w : writers) w->ExpectExplains(first->sites);
  for (auto& r : replicas) {
    v1::Scene s;
    ASSERT_TRUE(Client::Connect(r->address())->GetScene("scene", &s).ok());
    EXPECT_EQ(s.store_version(), s.version());
  }
}

}  // namespace
}  // namespace gvd
