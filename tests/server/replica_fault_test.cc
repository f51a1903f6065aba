// Three gvd-server replicas on one PostgreSQL (started by the test from Debian's package),
// under a stream of writes through each of them, while faults strike: a replica killed with
// SIGKILL and started again, the database stopped and started under load, a replica frozen
// (SIGSTOP) while 10,000 site changes land elsewhere. The oracle is the writes each writer
// made and what the server said of them: an acknowledged write must be in the final state; a
// write that failed may or may not be (the kill or the outage cut its answer), but nothing
// else may. Every replica must end up with the same sites at the same version.
//
// A partition: the database and two replicas each in a network namespace of the test's, on
// addresses of their own; one replica is cut off the database and joined again.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <array>
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

#include <cmath>
#include <cstdio>
#include <future>
#include <limits>

#include <grpcpp/grpcpp.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "gvd/client.h"
#include "tests/support/postgres.h"
#include "tests/support/server_process.h"
#include "tests/support/stored_sites.h"
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

// A write acknowledged by one replica, read at its version through another whose renders
// are held: the reader waits until it has read the version from the store, then answers
// through the index (at most 64 points, plain sites) without a frame of it. Each answer
// against the oracle over that version's sites; a read that waited for the render would
// outlast the client's deadline.
TEST(ReplicaReads, AWriteThroughOneIsReadThroughAnotherBeforeItsRender) {
  TempPostgres pg;
  ASSERT_EQ(pg.error(), "");
  auto a = StartReplica(pg);
  auto b = StartReplica(pg);
  auto writer = Client::Connect(a->address());
  auto reader = Client::Connect(b->address());
  v1::Scene scene;
  ASSERT_TRUE(writer->CreateScene(testing::UnitScene("moved", 64, 64), &scene).ok());
  ASSERT_TRUE(Eventually([&] { return reader->GetScene("moved", &scene).ok(); }));
  testing::HoldRenders hold(*b);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Site> sites;
  v1::UpsertSitesRequest put;
  put.set_scene_id("moved");
  for (int i = 0; i < 100; ++i) {
    sites.push_back({"s" + std::to_string(i), PointSite{{u(rng), u(rng)}}});
    *put.add_sites() = testing::ToProtoSite(sites.back());
  }
  uint64_t v = 0;
  ASSERT_TRUE(writer->UpsertSites(put, &v).ok());
  for (int round = 0; round < 20; ++round) {
    std::vector<Vec2> q;
    if (round > 0) {
      Site& moved = sites[rng() % sites.size()];
      const Vec2 to{u(rng), u(rng)};
      moved.geometry = PointSite{to};
      put.clear_sites();
      *put.add_sites() = testing::ToProtoSite(moved);
      ASSERT_TRUE(writer->UpsertSites(put, &v).ok());
      q.push_back(to);
    }
    v1::FindNearestRequest find;
    find.set_scene_id("moved");
    find.set_min_version(v);
    while (q.size() < 16) q.push_back({u(rng), u(rng)});
    for (Vec2 p : q) testing::SetPoint(p, find.add_points());
    v1::FindNearestResponse r;
    const grpc::Status st = reader->FindNearest(find, &r);
    ASSERT_TRUE(st.ok()) << "round " << round << ": " << st.error_message();
    EXPECT_EQ(r.version(), v);
    ASSERT_EQ(r.results_size(), int(q.size()));
    for (size_t i = 0; i < q.size(); ++i) {
      const oracle::Best best = oracle::BestSite(q[i], sites);
      EXPECT_EQ(r.results(int(i)).site_id(), sites[best.index].id) << "round " << round;
      EXPECT_NEAR(r.results(int(i)).distance(), best.value, oracle::Tolerance(q[i], best.value));
      EXPECT_TRUE(r.results(int(i)).exact());
    }
  }
}

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
    // Thawed whatever assertion ends the test: a stopped process does not take SIGTERM.
    struct Thaw {
      pid_t pid;
      ~Thaw() { kill(pid, SIGCONT); }
    } thaw{replicas[2]->pid()};
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
      // Writers 0 and 1 write the same scene all the while, writer 1 through another
      // server: a batch overtaken on each of the server's tries is refused whole (ABORTED),
      // and a client sends it again, after a pause.
      grpc::Status s;
      for (int attempt = 0; attempt < 20; ++attempt) {
        uint64_t version;
        s = client->UpsertSites(r, &version);
        if (s.error_code() != grpc::StatusCode::ABORTED) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10 * (attempt + 1)));
      }
      ASSERT_TRUE(s.ok()) << "batch " << batch << ": " << s.error_code() << " "
                          << s.error_message();
    }
  }
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

// Network namespaces of one test: "db" for the database and one per replica, each replica
// joined to the database's namespace by a veth pair of its own (10.77.R.2 on the replica's
// side, 10.77.R.1 on the database's), and nothing else: a link set down is a partition.
class Namespaces {
 public:
  explicit Namespaces(int replicas) : base_("gvd" + std::to_string(getpid())) {
    if (getuid() != 0) {
      error_ = "network namespaces need root";
      return;
    }
    if (!Ip("netns add " + db())) return;
    made_.push_back(db());
    if (!Ip("-n " + db() + " link set lo up")) return;
    for (int r = 0; r < replicas; ++r) {
      const std::string ns = replica(r), net = "10.77." + std::to_string(r) + ".";
      if (!Ip("netns add " + ns)) return;
      made_.push_back(ns);
      if (!Ip("-n " + ns + " link set lo up") ||
          !Ip("-n " + db() + " link add " + link(r) + " type veth peer name eth0 netns " + ns) ||
          !Ip("-n " + db() + " addr add " + net + "1/24 dev " + link(r)) ||
          !Ip("-n " + ns + " addr add " + net + "2/24 dev eth0") ||
          !Ip("-n " + db() + " link set " + link(r) + " up") ||
          !Ip("-n " + ns + " link set eth0 up")) {
        return;
      }
    }
  }
  ~Namespaces() {
    for (const std::string& ns : made_) Ip("netns del " + ns);
  }
  // Empty when every namespace and link is made; else why not.
  const std::string& error() const { return error_; }
  std::string db() const { return base_ + "-db"; }
  std::string replica(int r) const { return base_ + "-r" + std::to_string(r); }
  // The database's address as replica r reaches it.
  static std::string db_address(int r) { return "10.77." + std::to_string(r) + ".1"; }
  // How a replica is cut off the database: its link loses its carrier, or the database's
  // address on that link goes (the replica's link stays up; its packets vanish unanswered).
  enum Partition { kLinkDown, kBlackHole };
  // Cuts replica r off the database, or joins it again.
  bool Cut(int r, Partition how) {
    const std::string on = "-n " + db() + " ";
    return how == kLinkDown ? Ip(on + "link set " + link(r) + " down")
                            : Ip(on + "addr del " + db_address(r) + "/24 dev " + link(r));
  }
  bool Join(int r, Partition how) {
    const std::string on = "-n " + db() + " ";
    return how == kLinkDown ? Ip(on + "link set " + link(r) + " up")
                            : Ip(on + "addr add " + db_address(r) + "/24 dev " + link(r));
  }

 private:
  static std::string link(int r) { return "r" + std::to_string(r); }
  // Runs `ip ARGS`; on failure keeps its output as the error.
  bool Ip(const std::string& args) {
    FILE* p = popen(("ip " + args + " 2>&1").c_str(), "r");
    if (p == nullptr) {
      error_ = "cannot run ip";
      return false;
    }
    std::string out;
    std::array<char, 256> buf;
    while (fgets(buf.data(), buf.size(), p) != nullptr) out += buf.data();
    if (pclose(p) != 0) {
      if (error_.empty()) error_ = "ip " + args + ": " + (out.empty() ? "failed" : out);
      return false;
    }
    return true;
  }

  const std::string base_;
  std::vector<std::string> made_;
  std::string error_;
};

TEST(ReplicaFaults, ReplicaCutOffTheDatabaseReportsItThenCatchesUp) {
  Namespaces ns(2);
  if (!ns.error().empty()) GTEST_SKIP() << "no network namespaces here: " << ns.error();
  TempPostgres pg(TempPostgres::Options{
      ns.db(), Namespaces::db_address(0) + "," + Namespaces::db_address(1)});
  ASSERT_EQ(pg.error(), "");
  // Each replica in its own namespace reaches the database over its veth pair only; the test
  // reaches the replica over a Unix socket.
  testing::TempDir sockets;
  std::vector<std::unique_ptr<ServerProcess>> replicas;
  for (int r = 0; r < 2; ++r) {
    const std::string socket = "unix:" + sockets.path() + "/" + std::to_string(r) + ".sock";
    replicas.push_back(std::make_unique<ServerProcess>(
        GVD_SERVER_PATH,
        std::vector<std::string>{"--store",
                                 "postgresql://gvd@" + Namespaces::db_address(r) + ":" +
                                     std::to_string(pg.port()) + "/gvd",
                                 "--render-threads", "1", "--listen", socket},
        std::vector<std::string>{"ip", "netns", "exec", ns.replica(r)}));
    ASSERT_EQ(replicas[r]->error(), "");
  }
  ServerProcess& writer = *replicas[0];
  ServerProcess& cut = *replicas[1];
  ClientOptions options;
  options.timeout = std::chrono::seconds(60);
  auto to_writer = Client::Connect(writer.address(), options);
  auto to_cut = Client::Connect(cut.address(), options);
  v1::Scene made;
  ASSERT_TRUE(to_writer->CreateScene(testing::UnitScene("scene", 64, 64), &made).ok());

  // The oracle: the sites as written, each write acknowledged before the next.
  std::map<std::string, Point> sites;
  std::mt19937_64 rng(27);
  std::uniform_real_distribution<double> u(0, 1);
  uint64_t version = 0;
  auto write = [&](Client& client, const std::string& id) {
    const Point p{u(rng), u(rng)};
    v1::UpsertSitesRequest r;
    r.set_scene_id("scene");
    auto* site = r.add_sites();
    site->set_id(id);
    site->mutable_point()->set_x(p.first);
    site->mutable_point()->set_y(p.second);
    grpc::Status s = client.UpsertSites(r, &version);
    if (s.ok()) sites[id] = p;
    return s;
  };
  // Whether `server` answers an exact FindNearest at `at` (or later) with the oracle's
  // nearest site for each of a few points.
  auto answers = [&](ServerProcess& server, uint64_t at) {
    v1::FindNearestRequest r;
    r.set_scene_id("scene");
    r.set_min_version(at);
    r.set_exact(true);
    std::vector<Point> queries;
    for (int k = 0; k < 16; ++k) queries.push_back({u(rng), u(rng)});
    for (const Point& q : queries) {
      auto* p = r.add_points();
      p->set_x(q.first);
      p->set_y(q.second);
    }
    v1::FindNearestResponse response;
    if (!Client::Connect(server.address(), options)->FindNearest(r, &response).ok()) return false;
    if (response.version() < at || response.results_size() != static_cast<int>(queries.size())) {
      return false;
    }
    for (size_t k = 0; k < queries.size(); ++k) {
      double best = std::numeric_limits<double>::infinity();
      for (const auto& [id, p] : sites) {
        best = std::min(best, std::hypot(p.first - queries[k].first, p.second - queries[k].second));
      }
      const auto& got = response.results(k);
      const Point& p = sites.at(got.site_id());
      if (std::hypot(p.first - queries[k].first, p.second - queries[k].second) != best) {
        return false;
      }
    }
    return true;
  };
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(write(*to_writer, "before-" + std::to_string(k)).ok());
  const uint64_t joined_at = version;
  ASSERT_TRUE(Eventually([&] { return answers(cut, joined_at); }));
  using Serving = grpc::health::v1::HealthCheckResponse;
  EXPECT_EQ(Health(cut), Serving::SERVING);

  auto since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  for (Namespaces::Partition how : {Namespaces::kLinkDown, Namespaces::kBlackHole}) {
    const char* name = how == Namespaces::kLinkDown ? "link down" : "black hole";
    SCOPED_TRACE(name);
    // Cut off: the other replica goes on writing; the cut one says NOT_SERVING, goes on
    // answering from the state it holds, reports how stale that is, and refuses writes with
    // UNAVAILABLE (within the store's deadline, not the client's).
    const std::map<std::string, Point> before_cut = sites;
    ASSERT_TRUE(ns.Cut(1, how)) << ns.error();
    const auto cut_at = std::chrono::steady_clock::now();
    for (int k = 0; k < 50; ++k) {
      const std::string id = "during-" + std::to_string(how) + "-" + std::to_string(k);
      ASSERT_TRUE(write(*to_writer, id).ok());
    }
    const uint64_t written = version;
    EXPECT_TRUE(Eventually([&] { return Health(cut) == Serving::NOT_SERVING; }, 40));
    std::printf("%s: NOT_SERVING %.1f s after the cut\n", name, since(cut_at));
    EXPECT_EQ(Health(writer), Serving::SERVING);
    v1::Scene stale;
    ASSERT_TRUE(to_cut->GetScene("scene", &stale).ok());
    EXPECT_LT(stale.version(), written);
    EXPECT_LT(stale.store_version(), written);
    EXPECT_GT(stale.store_read_age_seconds(), 1.0);
    auto held = Read(cut, "scene");
    ASSERT_TRUE(held.has_value());
    EXPECT_EQ(held->version, stale.version());
    EXPECT_EQ(held->sites, before_cut);
    const auto start = std::chrono::steady_clock::now();
    grpc::Status refused = write(*to_cut, "refused");
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.error_message();
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
    std::printf("%s: a write on the cut replica refused after %.1f s\n", name, since(start));
    // A read at the version written elsewhere waits for it, and is answered once joined.
    auto waiting = std::async(std::launch::async, [&] { return answers(cut, written); });
    EXPECT_EQ(waiting.wait_for(std::chrono::seconds(1)), std::future_status::timeout);

    // Joined again: it catches up from the log by itself, says SERVING, holds every
    // acknowledged write and nothing of the refused one, answers at the version written
    // elsewhere, and takes writes again.
    ASSERT_TRUE(ns.Join(1, how)) << ns.error();
    const auto joined = std::chrono::steady_clock::now();
    EXPECT_TRUE(Eventually([&] { return Health(cut) == Serving::SERVING; }, 60));
    std::printf("%s: SERVING %.1f s after the join\n", name, since(joined));
    EXPECT_TRUE(waiting.get());
    ASSERT_TRUE(Eventually([&] {
      auto now = Read(cut, "scene");
      return now && now->version >= written && now->sites == sites;
    }, 60));
    EXPECT_TRUE(answers(cut, written));
    ASSERT_TRUE(write(*to_cut, "after-" + std::to_string(how)).ok());
    const uint64_t after = version;
    ASSERT_TRUE(Eventually([&] {
      auto a = Read(writer, "scene"), b = Read(cut, "scene");
      return a && b && a->version == after && *a == *b && a->sites == sites;
    }));
    EXPECT_TRUE(answers(writer, after));
  }
}

}  // namespace
}  // namespace gvd
