// A bounded load test: writers and readers on several scenes of the real server, over
// loopback, for GVD_LOAD_SECONDS (default 5). Every answer is checked against the oracle of the
// version it was served from; any unexpected status or wrong answer fails the test. Prints
// throughput and latency percentiles per kind of call.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "gvd/client.h"
#include "render/kernel/exact2.h"
#include "tests/support/server_process.h"
#include "tests/support/test_scenes.h"

namespace gvd {
namespace {

using Clock = std::chrono::steady_clock;

struct Latencies {
  std::mutex mu;
  std::map<std::string, std::vector<double>> micros;
  void Add(const std::string& kind, Clock::time_point start) {
    double us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    std::lock_guard<std::mutex> lock(mu);
    micros[kind].push_back(us);
  }
};

// A scene's sites at each acknowledged version. A reader can be served from a version a
// moment before its writer has recorded it, so Get waits a little for it.
struct SceneOracle {
  std::mutex mu;
  std::condition_variable cv;
  std::map<uint64_t, std::shared_ptr<const SiteTable>> at;
  void Put(uint64_t v, std::shared_ptr<const SiteTable> sites) {
    {
      std::lock_guard<std::mutex> lock(mu);
      at[v] = std::move(sites);
    }
    cv.notify_all();
  }
  std::shared_ptr<const SiteTable> Get(uint64_t v) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, std::chrono::seconds(2), [&] { return at.count(v) > 0; });
    auto it = at.find(v);
    return it == at.end() ? nullptr : it->second;
  }
};

TEST(LoadTest, MixedWorkloadHoldsItsContract) {
  const char* env = std::getenv("GVD_LOAD_SECONDS");
  const double seconds = env ? std::atof(env) : 5;
  testing::ServerProcess server(GVD_SERVER_PATH, {"--data", ":memory:"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  const std::vector<std::string> names = {"load-a", "load-b", "load-c"};
  std::map<std::string, SceneOracle> oracles;  // complete before the threads start
  for (const auto& name : names) oracles[name];
  {
    auto client = Client::Connect(server.address());
    for (const auto& name : names) {
      v1::CreateSceneRequest c = testing::UnitScene(name, 256, 256);
      if (name == "load-c") c.set_render_mode(v1::RENDER_MODE_EXACT);
      v1::Scene scene;
      ASSERT_TRUE(client->CreateScene(c, &scene).ok());
    }
  }
  Latencies lat;
  std::atomic<bool> stop{false};
  std::atomic<int> failures{0};
  auto fail = [&](const std::string& what) {
    if (failures++ < 10) ADD_FAILURE() << what;
  };

  std::vector<std::thread> threads;
  for (size_t s = 0; s < names.size(); ++s) {
    threads.emplace_back([&, s] {  // the scene's writer
      const std::string& name = names[s];
      SceneOracle& oracle = oracles.at(name);
      auto client = Client::Connect(server.address());
      std::mt19937_64 rng(100 + s);
      std::uniform_real_distribution<double> u(0, 1);
      std::map<std::string, Vec2> sites;
      int next = 0;
      while (!stop) {
        std::map<std::string, std::optional<Vec2>> change;
        const uint64_t what = sites.size() < 50 ? 0 : rng() % 3;
        for (int k = 0, n = 1 + static_cast<int>(rng() % 5); k < n; ++k) {
          if (what == 0) {
            change["p" + std::to_string(next++)] = Vec2{u(rng), u(rng)};
          } else {
            auto it = sites.begin();
            std::advance(it, rng() % sites.size());
            change[it->first] = what == 1 ? std::optional<Vec2>(Vec2{u(rng), u(rng)}) : std::nullopt;
          }
        }
        bool deleting = what == 2;
        if (deleting && sites.size() - change.size() < 20) continue;
        auto start = Clock::now();
        grpc::Status st;
        uint64_t v = 0;
        if (deleting) {
          std::vector<std::string> ids;
          for (auto& [id, p] : change) ids.push_back(id);
          st = client->DeleteSites(name, ids, &v);
        } else {
          v1::UpsertSitesRequest r;
          r.set_scene_id(name);
          for (auto& [id, p] : change) {
            auto* site = r.add_sites();
            site->set_id(id);
            site->mutable_point()->set_x(p->x);
            site->mutable_point()->set_y(p->y);
          }
          st = client->UpsertSites(r, &v);
        }
        lat.Add(deleting ? "DeleteSites" : "UpsertSites", start);
        if (!st.ok()) {
          fail(name + ": write failed: " + st.error_message());
          continue;
        }
        for (auto& [id, p] : change) {
          if (p) {
            sites[id] = *p;
          } else {
            sites.erase(id);
          }
        }
        auto table = std::make_shared<SiteTable>();
        for (auto& [id, p] : sites) table->push_back({id, PointSite{p}});
        oracle.Put(v, std::move(table));
      }
    });
  }
  for (int r = 0; r < 3; ++r) {
    threads.emplace_back([&, r] {  // readers: raster and exact queries on every scene
      auto client = Client::Connect(server.address());
      std::mt19937_64 rng(200 + r);
      std::uniform_real_distribution<double> u(0, 1);
      while (!stop) {
        const std::string& name = names[rng() % names.size()];
        v1::FindNearestRequest q;
        q.set_scene_id(name);
        q.set_exact(rng() % 2);
        std::vector<Vec2> points;
        for (int k = 0; k < 8; ++k) {
          points.push_back({u(rng), u(rng)});
          auto* p = q.add_points();
          p->set_x(points.back().x);
          p->set_y(points.back().y);
        }
        auto start = Clock::now();
        v1::FindNearestResponse resp;
        grpc::Status st = client->FindNearest(q, &resp);
        lat.Add(q.exact() ? "FindNearest exact" : "FindNearest raster", start);
        if (st.error_code() == grpc::StatusCode::FAILED_PRECONDITION) continue;  // no sites yet
        if (!st.ok()) {
          fail(name + ": query failed: " + st.error_message());
          continue;
        }
        auto sites = oracles.at(name).Get(resp.version());
        if (!sites) {
          fail(name + ": served from unknown version " + std::to_string(resp.version()));
          continue;
        }
        for (size_t k = 0; k < points.size(); ++k) {
          const auto& n = resp.results(k);
          auto it = std::find_if(sites->begin(), sites->end(), [&](auto& s) { return s.id == n.site_id(); });
          const double truth = oracle::BestSite(points[k], *sites).value;
          const double tolerance = oracle::Tolerance(points[k], n.distance());
          if (it == sites->end() ||
              std::abs(n.distance() - oracle::Distance(points[k], it->geometry)) > tolerance ||
              truth + tolerance < n.distance() - n.error_bound() ||
              (q.exact() && std::abs(n.distance() - truth) > tolerance)) {
            fail(name + ": wrong answer at version " + std::to_string(resp.version()));
          }
        }
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (auto& t : threads) t.join();

  std::printf("load: %.1f s, 3 scenes (256x256, one in exact mode), 3 writers, 3 readers of 8 points\n",
              seconds);
  std::printf("%-20s %8s %10s %9s %9s\n", "call", "count", "per s", "p50 us", "p99 us");
  for (auto& [kind, v] : lat.micros) {
    std::sort(v.begin(), v.end());
    std::printf("%-20s %8zu %10.0f %9.0f %9.0f\n", kind.c_str(), v.size(), v.size() / seconds,
                v[v.size() / 2], v[v.size() * 99 / 100]);
  }
  EXPECT_EQ(failures, 0);
  for (const char* kind : {"UpsertSites", "FindNearest raster", "FindNearest exact"}) {
    EXPECT_GT(lat.micros[kind].size(), 10u) << kind;
  }
}

}  // namespace
}  // namespace gvd
