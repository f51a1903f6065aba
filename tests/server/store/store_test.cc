// The store behind the scene core: the byte form of sites and settings, and SqliteStore's
// load, commit, delete, reopen and conversion of the earlier schema. The oracle is a plain
// model kept here (a std::map of encoded-by-hand fields), compared bit for bit.
#include <sqlite3.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <chrono>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "render/kernel/exact2.h"
#include "render/kernel/path2.h"
#include "render/scene/codec.h"
#include "render/scene/scene.h"
#include "server/store/sqlite_store.h"
#include "tests/support/meshes3.h"
#include "tests/support/stored_sites.h"

namespace gvd {
namespace {

using testing::RandomSite;
using testing::SameBits;
using testing::SameSite;
using testing::TempDir;
using testing::SitesOf;
using testing::PutOf;

std::string RandomId(std::mt19937_64& rng) {
  std::string id(1 + rng() % 12, '\0');
  for (char& c : id) c = static_cast<char>(rng() % 256);
  return id;
}

SceneSettings ValidSettings() {
  SceneSettings s;
  s.id = "scene";
  s.grid = Grid{{0, 0, 2, 1}, 64, 32};
  s.eps = 0.01;
  s.cone_triangles = 40;
  return s;
}

TEST(Codec, SitesRoundTripBitForBit) {
  std::mt19937_64 rng(11);
  for (int i = 0; i < 2000; ++i) {
    Site s = RandomSite(rng, i, RandomId(rng));
    auto back = DecodeSite<Site>(EncodeSite(s));
    ASSERT_TRUE(back.ok()) << back.status();
    EXPECT_TRUE(SameSite(s, *back)) << "site " << i;
  }
}

TEST(Codec, SettingsRoundTripBitForBit) {
  SceneSettings s;
  s.id = std::string("scene\0with nul", 14);
  s.grid = Grid{{-0.0, -1e300, 5e-324, 1e300}, 4096, 3};
  s.eps = 1.0 / 3;
  s.cone_triangles = 77;
  s.mode = RenderMode::kExact;
  s.diagram = Diagram::kFarthest;
  auto back = DecodeSettings(EncodeSettings(s));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->id, s.id);
  EXPECT_TRUE(SameBits(back->grid.window.min_x, -0.0));
  EXPECT_TRUE(SameBits(back->grid.window.min_y, -1e300));
  EXPECT_TRUE(SameBits(back->grid.window.max_x, 5e-324));
  EXPECT_TRUE(SameBits(back->grid.window.max_y, 1e300));
  EXPECT_EQ(back->grid.width, 4096u);
  EXPECT_EQ(back->grid.height, 3u);
  EXPECT_TRUE(SameBits(back->eps, 1.0 / 3));
  EXPECT_EQ(back->cone_triangles, 77u);
  EXPECT_EQ(back->mode, RenderMode::kExact);
  EXPECT_EQ(back->diagram, Diagram::kFarthest);
}

// Damage is DATA_LOSS, never a crash or a site read from garbage: every proper prefix, every
// extension and every changed format or tag byte of an encoding is refused.
TEST(Codec, DamagedBytesAreDataLoss) {
  std::mt19937_64 rng(12);
  for (int kind = 0; kind < 5; ++kind) {
    const std::string bytes = EncodeSite(RandomSite(rng, kind, "id"));
    for (size_t n = 0; n < bytes.size(); ++n) {
      auto s = DecodeSite<Site>(std::string_view(bytes).substr(0, n));
      ASSERT_EQ(s.status().code(), absl::StatusCode::kDataLoss) << "kind " << kind << " prefix " << n;
    }
    EXPECT_EQ(DecodeSite<Site>(bytes + "x").status().code(), absl::StatusCode::kDataLoss);
    std::string format = bytes;
    format[0] = 9;
    EXPECT_EQ(DecodeSite<Site>(format).status().code(), absl::StatusCode::kDataLoss);
    // The geometry tag follows the format byte, the id (4-byte length + 2 bytes) and the
    // three weights.
    std::string tag = bytes;
    tag[1 + 4 + 2 + 24] = 0;
    EXPECT_EQ(DecodeSite<Site>(tag).status().code(), absl::StatusCode::kDataLoss);
  }
  // A point count far beyond the bytes present.
  std::string line = EncodeSite(Site{"l", PolylineSite{{{0, 0}, {1, 1}}}});
  line[1 + 4 + 1 + 24 + 1 + 3] = '\x7f';
  EXPECT_EQ(DecodeSite<Site>(line).status().code(), absl::StatusCode::kDataLoss);
  const std::string settings = EncodeSettings(ValidSettings());
  ASSERT_TRUE(DecodeSettings(settings).ok());
  for (size_t n = 0; n < settings.size(); ++n) {
    EXPECT_EQ(DecodeSettings(settings.substr(0, n)).status().code(), absl::StatusCode::kDataLoss);
  }
  std::string mode = settings;
  mode[mode.size() - 2] = 7;
  EXPECT_EQ(DecodeSettings(mode).status().code(), absl::StatusCode::kDataLoss);
}

// Well-formed bytes whose values no accepted site or scene has (a NaN coordinate, a negative
// weight, a polygon of two vertices, an empty window...) were damaged after they were
// written: DATA_LOSS too, so that the server stops naming the file rather than render them.
TEST(Codec, ValuesNoAcceptedSiteHadAreDataLoss) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Site> bad = {
      Site{"", PointSite{{0, 0}}},
      Site{"p", PointSite{{nan, 0}}},
      Site{"p", PointSite{{0, inf}}},
      Site{"s", SegmentSite{{0, 0}, {-inf, 1}}},
      Site{"l", PolylineSite{{{0, 0}}}},
      Site{"l", PolylineSite{{{0, 0}, {1, nan}}}},
      Site{"g", PolygonSite{{{0, 0}, {1, 1}}}},
      Site{"b", BezierSite{{{0, 0}, {1, 1}}, 0.1, {{0, 0}, {1, 1}}}},
      Site{"b", BezierSite{{{0, 0}, {1, 1}, {2, 0}}, -1, {{0, 0}, {2, 0}}}},
  };
  for (double additive : {-1.0, nan, inf}) bad.push_back(Site{"w", PointSite{{0, 0}}, additive});
  for (double m : {0.0, -2.0, nan}) bad.push_back(Site{"w", PointSite{{0, 0}}, 0, m});
  for (double r : {0.0, -1.0, nan}) bad.push_back(Site{"w", PointSite{{0, 0}}, 0, 1, r});
  for (double approximation : {-1.0, nan, inf}) {
    PathSite path = MakePath({Subpath{{{0, 0}, {1, 0}, {1, 1}}, {1, 2}, true}}, FillRule::kNonZero,
                             Side::kBoth, 0.01);
    path.approximation = approximation;
    bad.push_back(Site{"a", path});
  }
  for (size_t i = 0; i < bad.size(); ++i) {
    EXPECT_EQ(DecodeSite<Site>(EncodeSite(bad[i])).status().code(), absl::StatusCode::kDataLoss) << i;
  }
  // The same sites with their values mended decode.
  EXPECT_TRUE(DecodeSite<Site>(EncodeSite(Site{"p", PointSite{{0, 1e300}}, 1e15, 1e-6, 1e-300})).ok());
  EXPECT_TRUE(DecodeSite<Site>(EncodeSite(Site{"g", PolygonSite{{{0, 0}, {1, 1}, {0, 0}}}})).ok());

  std::vector<SceneSettings> scenes(7, ValidSettings());
  scenes[0].id.clear();
  scenes[1].grid.window.max_x = scenes[1].grid.window.min_x;
  scenes[2].grid.window.min_y = nan;
  scenes[3].grid.window = {-1e308, 0, 1e308, 1};  // its width overflows
  scenes[4].grid.height = 0;
  scenes[5].eps = 0;
  scenes[6].cone_triangles = 2;
  for (size_t i = 0; i < scenes.size(); ++i) {
    EXPECT_EQ(DecodeSettings(EncodeSettings(scenes[i])).status().code(),
              absl::StatusCode::kDataLoss) << i;
  }
}

// A curve whose coordinates are finite but whose control polygon is longer than a double holds is
// accepted by the server (its coordinates and box are finite), so it must load again after a
// restart: its default tolerance is finite where each piece is, and infinite where the curve
// bends past what a double holds, which the bound then states honestly.
TEST(Codec, HugeCurvesTheServerAcceptsDecode) {
  // A straight curve: each piece 1.7e308 long, their sum past DBL_MAX, no bend.
  const Site straight{"s", MakeBezier({{-1.7e308, 0}, {0, 0}, {1.7e308, 0}}, 0)};
  const auto& b = std::get<BezierSite>(straight.geometry);
  EXPECT_TRUE(std::isfinite(b.tolerance)) << b.tolerance;
  EXPECT_GE(b.tolerance, 1.7e308 / 1000);
  // A bend past DBL_MAX: c2 - 2 c1 + c0 overflows.
  const Site bent{"b", MakeBezier({{-8e307, 0}, {8e307, 1}, {-8e307, 2}}, 0)};
  for (const Site& site : {straight, bent}) {
    auto back = DecodeSite<Site>(EncodeSite(site));
    ASSERT_TRUE(back.ok()) << site.id << ": " << back.status();
    EXPECT_TRUE(SameSite(site, *back)) << site.id;
  }
}


SceneSettings Settings(const std::string& id) {
  SceneSettings s;
  s.id = id;
  s.grid = Grid{{0, 0, 1, 1}, 32, 16};
  s.eps = 0.25;
  s.cone_triangles = 9;
  return s;
}

using SceneModel = std::map<std::string, Site>;
struct StoreModel {
  std::map<std::string, uint64_t> versions;
  std::map<std::string, SceneModel> sites;
};

void ExpectStoreHolds(SqliteStore& store, const StoreModel& model) {
  auto loaded = store.Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), model.versions.size());
  auto expected = model.versions.begin();
  for (const StoredScene& scene : *loaded) {
    SCOPED_TRACE(scene.settings.id);
    ASSERT_EQ(scene.settings.id, expected->first);  // in id order
    EXPECT_EQ(scene.version, expected->second);
    EXPECT_EQ(scene.settings.grid.width, 32u);
    EXPECT_TRUE(SameBits(scene.settings.eps, 0.25));
    const SceneModel& sites = model.sites.at(scene.settings.id);
    const std::vector<Site> stored = SitesOf(scene);
    ASSERT_EQ(stored.size(), sites.size());
    for (const Site& site : stored) {
      auto it = sites.find(site.id);
      ASSERT_NE(it, sites.end()) << site.id;
      EXPECT_TRUE(SameSite(site, it->second)) << site.id;
    }
    ++expected;
  }
}

// Random creates, change sets and deletes, checked against the model after each reopen: what
// a call acknowledged is there, a refused call left nothing behind. With `packing`, and with
// `fold` true folding at random moments besides what its folder does.
void CheckCommitsAcrossReopens(uint64_t seed, const SqliteStore::Packing* packing, bool fold) {
  TempDir dir;
  std::mt19937_64 rng(seed);
  StoreModel model;
  for (int round = 0; round < 4; ++round) {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok()) << store.status();
    if (packing) (*store)->set_packing(*packing);
    ExpectStoreHolds(**store, model);
    for (int op = 0; op < 60; ++op) {
      if (fold && rng() % 8 == 0) {
        auto folded = (*store)->FoldPacks();
        ASSERT_TRUE(folded.ok()) << folded.status();
        ExpectStoreHolds(**store, model);
      }
      const std::string scene = "s" + std::to_string(rng() % 4);
      const bool exists = model.versions.count(scene) > 0;
      if (!exists) {
        ASSERT_TRUE((*store)->CreateScene(Settings(scene), 5).ok());
        model.versions[scene] = 5;
        model.sites[scene] = {};
        continue;
      }
      if (rng() % 15 == 0) {
        ASSERT_TRUE((*store)->DeleteScene(scene).ok());
        model.versions.erase(scene);
        model.sites.erase(scene);
        continue;
      }
      SceneModel& sites = model.sites[scene];
      std::vector<std::shared_ptr<const Site>> put;
      std::vector<std::string> removed;
      std::map<std::string, bool> touched;
      for (int k = 0, n = 1 + rng() % 30; k < n; ++k) {
        std::string id = "id" + std::to_string(rng() % 50);
        if (touched.count(id)) continue;
        touched[id] = true;
        if (sites.count(id) && rng() % 3 == 0) {
          removed.push_back(id);
        } else {
          put.push_back(std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id)));
        }
      }
      const uint64_t version = model.versions[scene] + 1;
      ASSERT_TRUE((*store)->Commit({scene, version, put, removed}).ok());
      for (const auto& s : put) sites[s->id] = *s;
      for (const auto& id : removed) sites.erase(id);
      model.versions[scene] = version;
    }
    // A change set for a scene that is not stored is refused whole.
    auto site = std::make_shared<const Site>(Site{"x", PointSite{{0, 0}}});
    std::vector<std::shared_ptr<const Site>> put = {site};
    EXPECT_EQ((*store)->Commit({"absent", 9, put, {}}).code(), absl::StatusCode::kNotFound);
    // A second create of a stored scene is refused and changes nothing.
    if (!model.versions.empty()) {
      EXPECT_FALSE((*store)->CreateScene(Settings(model.versions.begin()->first), 1).ok());
    }
    ExpectStoreHolds(**store, model);
  }
}

TEST(Store, KeepsWhatWasCommittedAcrossReopens) { CheckCommitsAcrossReopens(13, nullptr, false); }

// The same with change sets of four puts or more written as packs: read before their fold,
// folded at random moments, folded by the store's own folder a chunk of three sites at a
// time while the writes go on, and left unfolded across a reopen.
TEST(Store, PackedChangeSetsReadTheSameBeforeAndAfterTheirFold) {
  SqliteStore::Packing never;
  never.min_sites = 4;
  never.fold_after = std::chrono::hours(1);
  {
    SCOPED_TRACE("folded by FoldPacks only");
    CheckCommitsAcrossReopens(17, &never, true);
  }
  {
    SCOPED_TRACE("never folded");
    CheckCommitsAcrossReopens(19, &never, false);
  }
  SqliteStore::Packing busy;
  busy.min_sites = 4;
  busy.fold_after = std::chrono::milliseconds(0);
  busy.fold_chunk = 3;
  busy.fold_idle = std::chrono::milliseconds(0);
  {
    SCOPED_TRACE("folded by the folder as they come");
    CheckCommitsAcrossReopens(23, &busy, true);
  }
}

// The nice value of each of this process's threads named `name` (/proc/self/task).
std::vector<int> NiceOfThreads(const std::string& name) {
  std::vector<int> nice;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string thread_name;
    std::getline(comm, thread_name);
    if (thread_name != name) continue;
    std::ifstream stat(task.path() / "stat");
    std::string line;
    std::getline(stat, line);
    // After the name's closing parenthesis: state (field 3) ... nice (field 19).
    std::istringstream fields(line.substr(line.rfind(')') + 2));
    std::string field;
    for (int k = 3; k <= 19 && fields >> field; ++k) {
      if (k == 19) nice.push_back(std::stoi(field));
    }
  }
  return nice;
}

// The folder's chunks hold the lock that every commit waits for, so they run at the
// priority of the thread that wrote the pack, not below it as the pack's ordering does: a
// chunk at nice 10 beside busy threads at 0 held commits for most of a second.
TEST(Store, TheFoldersChunksRunAtItsWritersPriority) {
  TempDir dir;
  auto opened = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(opened.ok()) << opened.status();
  SqliteStore& store = **opened;
  SqliteStore::Packing packing;
  packing.min_sites = 4;
  packing.fold_after = std::chrono::milliseconds(0);
  packing.fold_idle = std::chrono::milliseconds(0);
  packing.fold_chunk = 3;
  store.set_packing(packing);
  const int writer_nice = getpriority(PRIO_PROCESS, 0);  // this thread's (Linux)
  ASSERT_TRUE(store.CreateScene(Settings("s"), 1).ok());
  std::mt19937_64 rng(41);
  std::vector<std::shared_ptr<const Site>> put;
  for (int k = 0; k < 40; ++k) {
    put.push_back(std::make_shared<const Site>(RandomSite(rng, k, "id" + std::to_string(k))));
  }
  ASSERT_TRUE(store.Commit(ChangeSet{"s", 2, put, {}}).ok());
  // Folded once the pack's row is gone (read through a connection of the test's own).
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2((dir.path() + "/data/gvd.sqlite3").c_str(), &db,
                            SQLITE_OPEN_READONLY, nullptr),
            SQLITE_OK);
  int packs = -1;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(1);
  while (packs != 0 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    sqlite3_stmt* count = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "SELECT count(*) FROM site_pack", -1, &count, nullptr),
              SQLITE_OK);
    if (sqlite3_step(count) == SQLITE_ROW) packs = sqlite3_column_int(count, 0);
    sqlite3_finalize(count);
  }
  sqlite3_close(db);
  ASSERT_EQ(packs, 0) << "the pack was not folded in a minute";
  // The folder, and any thread it made that has not named itself yet (the flusher, the
  // checkpointer), which has its nice value.
  const std::vector<int> folders = NiceOfThreads("gvd-store-fold");
  ASSERT_FALSE(folders.empty());
  for (int nice : folders) EXPECT_EQ(nice, writer_nice);
}

// Executes SQL on a database file directly, as an earlier release would have.
void RawSql(const std::string& path, const std::vector<std::string>& statements) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  for (const std::string& sql : statements) {
    char* error = nullptr;
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error), SQLITE_OK)
        << sql << ": " << (error ? error : "");
    sqlite3_free(error);
  }
  sqlite3_close(db);
}

// The earlier schema, holding records that the test's own legacy reader understands:
// a scene's record is its id, a site's is "id x y".
void WriteEarlierSchema(const std::string& dir) {
  ASSERT_EQ(system(("mkdir -p '" + dir + "'").c_str()), 0);
  RawSql(dir + "/gvd.sqlite3",
         {"CREATE TABLE scenes (id TEXT PRIMARY KEY, request BLOB NOT NULL, version INTEGER NOT NULL)",
          "CREATE TABLE sites (scene TEXT NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,"
          " id TEXT NOT NULL, site BLOB NOT NULL, PRIMARY KEY (scene, id)) WITHOUT ROWID",
          "INSERT INTO scenes VALUES ('a', 'a', 7), ('b', 'b', 3)",
          "INSERT INTO sites VALUES ('a', 'p', 'p 0.25 0.5'), ('a', 'q', 'q 0.75 0.125'),"
          " ('b', 'r', 'r 0.5 0.5')"});
}

SqliteStore::Legacy TestLegacy(bool refuse_r = false) {
  return {
      [](std::string_view id) -> absl::StatusOr<SceneSettings> {
        return Settings(std::string(id));
      },
      [refuse_r](std::string_view record) -> absl::StatusOr<Site> {
        std::string s(record);
        char id[8];
        double x, y;
        if (std::sscanf(s.c_str(), "%7s %lf %lf", id, &x, &y) != 3) {
          return absl::DataLossError("bad record");
        }
        if (refuse_r && std::string(id) == "r") return absl::DataLossError("refused r");
        return Site{id, PointSite{{x, y}}};
      },
  };
}

// Writers of several scenes commit at once: whatever transactions their change sets share,
// each acknowledged one is stored after a reopen, and the ones refused (a scene that is not
// stored, committed in the middle of the others) leave nothing behind.
TEST(Store, ConcurrentWritersShareTransactionsAndFailAlone) {
  TempDir dir;
  constexpr int kWriters = 6, kCommits = 40;
  StoreModel model;
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok()) << store.status();
    for (int w = 0; w < kWriters; ++w) {
      const std::string scene = "w" + std::to_string(w);
      ASSERT_TRUE((*store)->CreateScene(Settings(scene), 1).ok());
      model.versions[scene] = 1 + kCommits;
      model.sites[scene] = {};
    }
    std::vector<SceneModel> written(kWriters);
    std::vector<std::thread> writers;
    std::atomic<uint64_t> failures{0};
    for (int w = 0; w <= kWriters; ++w) {  // the last one writes to a scene never stored
      writers.emplace_back([&, w] {
        std::mt19937_64 rng(100 + w);
        const std::string scene = w < kWriters ? "w" + std::to_string(w) : "missing";
        for (int c = 0; c < kCommits; ++c) {
          std::vector<std::shared_ptr<const Site>> put;
          for (int k = 0; k < 3; ++k) {
            put.push_back(std::make_shared<const Site>(
                RandomSite(rng, static_cast<int>(rng()), "id" + std::to_string(rng() % 20))));
          }
          std::sort(put.begin(), put.end(), [](const auto& a, const auto& b) { return a->id < b->id; });
          put.erase(std::unique(put.begin(), put.end(),
                                [](const auto& a, const auto& b) { return a->id == b->id; }),
                    put.end());
          absl::Status s = (*store)->Commit({scene, uint64_t(2 + c), put, {}});
          if (w == kWriters) {
            if (s.code() != absl::StatusCode::kNotFound) ++failures;
            continue;
          }
          if (!s.ok()) {
            ++failures;
            continue;
          }
          for (const auto& site : put) written[w][site->id] = *site;
        }
      });
    }
    for (auto& t : writers) t.join();
    ASSERT_EQ(failures.load(), 0u);
    for (int w = 0; w < kWriters; ++w) model.sites["w" + std::to_string(w)] = written[w];
    SqliteStore::GroupStats stats = (*store)->group_stats();
    EXPECT_EQ(stats.change_sets, uint64_t(kWriters) * kCommits);
    EXPECT_LE(stats.transactions, stats.change_sets);
    std::printf("%llu change sets in %llu transactions\n",
                static_cast<unsigned long long>(stats.change_sets),
                static_cast<unsigned long long>(stats.transactions));
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  ExpectStoreHolds(**store, model);
}

// A VFS over the process's default one that counts the syncs of WAL files, the oracle of
// which commits waited for the disk, and records the threads that synced a database file
// (the end of a checkpoint).
class WalSyncCounter {
 public:
  WalSyncCounter() {
    real_ = sqlite3_vfs_find(nullptr);
    vfs_ = *real_;
    vfs_.zName = "gvd-test-wal-sync-counter";
    vfs_.szOsFile = static_cast<int>(sizeof(File)) + real_->szOsFile;
    vfs_.pAppData = this;
    vfs_.xOpen = [](sqlite3_vfs* v, const char* name, sqlite3_file* f, int flags,
                    int* out) {
      auto* self = static_cast<WalSyncCounter*>(v->pAppData);
      auto* file = reinterpret_cast<File*>(f);
      file->real = reinterpret_cast<sqlite3_file*>(file + 1);
      file->wal = (flags & SQLITE_OPEN_WAL) != 0;
      file->main = (flags & SQLITE_OPEN_MAIN_DB) != 0;
      file->owner = self;
      const int rc = self->real_->xOpen(self->real_, name, file->real, flags, out);
      // A file whose open failed is not closed: no methods, as in the real VFS.
      f->pMethods = rc == SQLITE_OK && file->real->pMethods ? &self->methods_ : nullptr;
      if (f->pMethods) self->methods_ = Forwarding(file->real->pMethods);
      return rc;
    };
    sqlite3_vfs_register(&vfs_, /*makeDflt=*/1);
  }
  ~WalSyncCounter() {
    sqlite3_vfs_register(real_, 1);
    sqlite3_vfs_unregister(&vfs_);
  }
  int wal_syncs() const { return wal_syncs_; }
  // The threads that synced a database file, one entry a sync.
  std::vector<std::thread::id> db_syncs() const {
    std::lock_guard<std::mutex> lock(mu_);
    return db_syncs_;
  }

 private:
  struct File {
    sqlite3_file base;
    sqlite3_file* real;
    bool wal;
    bool main;
    WalSyncCounter* owner;
  };
  static sqlite3_file* R(sqlite3_file* f) { return reinterpret_cast<File*>(f)->real; }
  // Every method passes to the real file's; xSync also counts.
  static sqlite3_io_methods Forwarding(const sqlite3_io_methods* m) {
    sqlite3_io_methods io = *m;
    io.xClose = [](sqlite3_file* f) { return R(f)->pMethods->xClose(R(f)); };
    io.xRead = [](sqlite3_file* f, void* b, int n, sqlite3_int64 o) {
      return R(f)->pMethods->xRead(R(f), b, n, o);
    };
    io.xWrite = [](sqlite3_file* f, const void* b, int n, sqlite3_int64 o) {
      return R(f)->pMethods->xWrite(R(f), b, n, o);
    };
    io.xTruncate = [](sqlite3_file* f, sqlite3_int64 n) {
      return R(f)->pMethods->xTruncate(R(f), n);
    };
    io.xSync = [](sqlite3_file* f, int flags) {
      auto* file = reinterpret_cast<File*>(f);
      if (file->wal) ++file->owner->wal_syncs_;
      if (file->main) {
        std::lock_guard<std::mutex> lock(file->owner->mu_);
        file->owner->db_syncs_.push_back(std::this_thread::get_id());
      }
      return R(f)->pMethods->xSync(R(f), flags);
    };
    io.xFileSize = [](sqlite3_file* f, sqlite3_int64* n) {
      return R(f)->pMethods->xFileSize(R(f), n);
    };
    io.xLock = [](sqlite3_file* f, int l) { return R(f)->pMethods->xLock(R(f), l); };
    io.xUnlock = [](sqlite3_file* f, int l) { return R(f)->pMethods->xUnlock(R(f), l); };
    io.xCheckReservedLock = [](sqlite3_file* f, int* r) {
      return R(f)->pMethods->xCheckReservedLock(R(f), r);
    };
    io.xFileControl = [](sqlite3_file* f, int op, void* a) {
      return R(f)->pMethods->xFileControl(R(f), op, a);
    };
    io.xSectorSize = [](sqlite3_file* f) { return R(f)->pMethods->xSectorSize(R(f)); };
    io.xDeviceCharacteristics = [](sqlite3_file* f) {
      return R(f)->pMethods->xDeviceCharacteristics(R(f));
    };
    io.xShmMap = [](sqlite3_file* f, int i, int n, int w, void volatile** p) {
      return R(f)->pMethods->xShmMap(R(f), i, n, w, p);
    };
    io.xShmLock = [](sqlite3_file* f, int o, int n, int fl) {
      return R(f)->pMethods->xShmLock(R(f), o, n, fl);
    };
    io.xShmBarrier = [](sqlite3_file* f) { R(f)->pMethods->xShmBarrier(R(f)); };
    io.xShmUnmap = [](sqlite3_file* f, int d) { return R(f)->pMethods->xShmUnmap(R(f), d); };
    io.xFetch = [](sqlite3_file* f, sqlite3_int64 o, int n, void** p) {
      return R(f)->pMethods->xFetch(R(f), o, n, p);
    };
    io.xUnfetch = [](sqlite3_file* f, sqlite3_int64 o, void* p) {
      return R(f)->pMethods->xUnfetch(R(f), o, p);
    };
    return io;
  }

  sqlite3_vfs* real_;
  sqlite3_vfs vfs_;
  sqlite3_io_methods methods_{};
  std::atomic<int> wal_syncs_{0};
  mutable std::mutex mu_;
  std::vector<std::thread::id> db_syncs_;
};

// The WAL is copied into the database by the store's checkpointer, beside the writer: no
// commit syncs the database file, yet checkpoints happen, and every commit is there after
// a reopen. SQLite syncs the database file only at the end of a checkpoint that copied the
// whole WAL, which one running while commits go on need not do; once they stop, the
// checkpoint the last commit asked for does.
TEST(Store, CheckpointsRunBesideTheCommits) {
  TempDir dir;
  WalSyncCounter syncs;
  StoreModel model;
  std::mt19937_64 rng(31);
  const auto me = std::this_thread::get_id();
  auto mine = [&] {
    const auto all = syncs.db_syncs();
    return std::count(all.begin(), all.end(), me);
  };
  auto others = [&] { return syncs.db_syncs().size() - static_cast<size_t>(mine()); };
  {
    auto opened = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(opened.ok()) << opened.status();
    SqliteStore& store = **opened;
    store.set_relaxed_sync(std::chrono::hours(1));
    ASSERT_TRUE(store.CreateScene(Settings("s"), 1).ok());
    const auto before = mine();  // opening a new database may sync it
    // Some 3,000 pages of WAL, committed here: enough for three checkpoints' worth.
    for (uint64_t version = 2; version < 400; ++version) {
      std::vector<std::shared_ptr<const Site>> put;
      for (int k = 0; k < 40; ++k) {
        put.push_back(std::make_shared<const Site>(
            RandomSite(rng, static_cast<int>(rng()), "id" + std::to_string(rng() % 5000))));
        model.sites["s"][put.back()->id] = *put.back();
      }
      ChangeSet change{"s", version, put, {}};
      change.durability = Durability::kRelaxed;
      ASSERT_TRUE(store.Commit(change).ok());
      model.versions["s"] = version;
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(1);
    while ((store.checkpoints() == 0 || others() == 0) &&
           std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    EXPECT_GE(store.checkpoints(), 1u) << "no checkpoint in a minute";
    EXPECT_GT(others(), 0u) << "no checkpoint copied the whole WAL in a minute";
    EXPECT_EQ(mine(), before) << "a commit synced the database file: it ran a checkpoint";
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  ExpectStoreHolds(**store, model);
}

// A relaxed commit is written without a sync of the WAL and synced by the store's flusher
// (with a period short enough, this test waits for it) or by the next sync commit that
// writes; a sync commit syncs before it returns. All of them are there after a reopen.
TEST(Store, RelaxedCommitsSkipTheSyncAndAreSyncedWithinTheirPeriod) {
  TempDir dir;
  WalSyncCounter syncs;
  StoreModel model;
  std::mt19937_64 rng(29);
  {
    auto opened = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(opened.ok()) << opened.status();
    SqliteStore& store = **opened;
    store.set_relaxed_sync(std::chrono::hours(1));  // no flush in the first part
    ASSERT_TRUE(store.CreateScene(Settings("s"), 1).ok());
    uint64_t version = 1;
    auto commit = [&](Durability durability) {
      std::vector<std::shared_ptr<const Site>> put = {std::make_shared<const Site>(
          RandomSite(rng, static_cast<int>(rng()), "id" + std::to_string(rng() % 50)))};
      ChangeSet change{"s", ++version, put, {}};
      change.durability = durability;
      ASSERT_TRUE(store.Commit(change).ok());
      model.sites["s"][put[0]->id] = *put[0];
      model.versions["s"] = version;
    };
    const int before = syncs.wal_syncs();
    for (int i = 0; i < 5; ++i) commit(Durability::kRelaxed);
    EXPECT_EQ(syncs.wal_syncs(), before) << "a relaxed commit synced the WAL";
    EXPECT_EQ(store.relaxed_unsynced(), 5u);
    // A sync commit that is refused writes nothing, so syncs nothing: the relaxed ones stay
    // unsynced.
    {
      std::vector<std::shared_ptr<const Site>> put = {
          std::make_shared<const Site>(RandomSite(rng, 1, "stale"))};
      ChangeSet stale{"s", version, put, {}};  // follows version - 1: the scene moved on
      EXPECT_EQ(store.Commit(stale).code(), absl::StatusCode::kAborted);
    }
    EXPECT_EQ(store.relaxed_unsynced(), 5u) << "a refused sync commit counted as a sync";
    commit(Durability::kSync);
    EXPECT_GT(syncs.wal_syncs(), before) << "a sync commit returned before syncing the WAL";
    EXPECT_EQ(store.relaxed_unsynced(), 0u) << "the sync commit synced the relaxed ones before it";
    const int after_sync = syncs.wal_syncs();
    commit(Durability::kSync);
    EXPECT_GT(syncs.wal_syncs(), after_sync);

    // The flusher: with a short period, the relaxed commits are synced without a sync commit.
    store.set_relaxed_sync(std::chrono::milliseconds(5));
    const int before_flush = syncs.wal_syncs();
    for (int i = 0; i < 3; ++i) commit(Durability::kRelaxed);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (store.relaxed_unsynced() != 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_EQ(store.relaxed_unsynced(), 0u) << "the flusher never synced the relaxed commits";
    EXPECT_GE(store.flusher_syncs(), 1u) << "they were counted synced without the flusher's sync";
    // The flusher syncs through a descriptor of its own, past this VFS: SQLite synced nothing.
    EXPECT_EQ(syncs.wal_syncs(), before_flush) << "a relaxed commit synced the WAL";
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  ExpectStoreHolds(**store, model);
}

TEST(Store, ConvertsTheEarlierSchemaOnce) {
  TempDir dir;
  const std::string data = dir.path() + "/data";
  WriteEarlierSchema(data);
  {
    // Without a reader for the old records the database is refused, and left as it was.
    auto refused = SqliteStore::Open(data);
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
    // A record the reader refuses stops the conversion, which changes nothing.
    auto failed = SqliteStore::Open(data, TestLegacy(/*refuse_r=*/true));
    EXPECT_EQ(failed.status().code(), absl::StatusCode::kDataLoss);
    EXPECT_NE(failed.status().message().find("refused r"), std::string::npos);
  }
  StoreModel model;
  model.versions = {{"a", 7}, {"b", 3}};
  model.sites["a"]["p"] = Site{"p", PointSite{{0.25, 0.5}}};
  model.sites["a"]["q"] = Site{"q", PointSite{{0.75, 0.125}}};
  model.sites["b"]["r"] = Site{"r", PointSite{{0.5, 0.5}}};
  {
    auto store = SqliteStore::Open(data, TestLegacy());
    ASSERT_TRUE(store.ok()) << store.status();
    ExpectStoreHolds(**store, model);
    auto site = std::make_shared<const Site>(Site{"s", PointSite{{0.1, 0.2}}});
    std::vector<std::shared_ptr<const Site>> put = {site};
    ASSERT_TRUE((*store)->Commit({"b", 4, put, {}}).ok());
    model.versions["b"] = 4;
    model.sites["b"]["s"] = *site;
  }
  // Converted once: a reopen needs no reader and finds the converted data and what followed.
  auto again = SqliteStore::Open(data);
  ASSERT_TRUE(again.ok()) << again.status();
  ExpectStoreHolds(**again, model);
}

// Deleting a scene waits for its writer, and every later write finds it gone.
// The schema version in the file, read with SQLite itself.
int UserVersion(const std::string& file) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &stmt, nullptr);
  int v = sqlite3_step(stmt) == SQLITE_ROW ? sqlite3_column_int(stmt, 0) : -1;
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return v;
}

// A store of schema version 1 (before the log) keeps its scenes and sites, and takes the
// log's columns: its rows count as written at version 0, so any follower reads them.
TEST(Store, ASchemaVersion1StoreBecomesALog) {
  TempDir dir;
  ASSERT_EQ(system(("mkdir -p '" + dir.path() + "/data'").c_str()), 0);
  const std::string file = dir.path() + "/data/gvd.sqlite3";
  const Site p{"p", PointSite{{0.25, 0.5}}};
  RawSql(file, {"CREATE TABLE scene (id TEXT PRIMARY KEY, settings BLOB NOT NULL,"
                " version INTEGER NOT NULL)",
                "CREATE TABLE site (scene TEXT NOT NULL REFERENCES scene(id) ON DELETE CASCADE,"
                " id TEXT NOT NULL, site BLOB NOT NULL, PRIMARY KEY (scene, id)) WITHOUT ROWID",
                "PRAGMA user_version = 1"});
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    const std::string settings = EncodeSettings(Settings("a")), site = EncodeSite(p);
    sqlite3_prepare_v2(db, "INSERT INTO scene VALUES ('a', ?, 7)", -1, &st, nullptr);
    sqlite3_bind_blob(st, 1, settings.data(), static_cast<int>(settings.size()), SQLITE_STATIC);
    EXPECT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_finalize(st);
    sqlite3_prepare_v2(db, "INSERT INTO site VALUES ('a', 'p', ?)", -1, &st, nullptr);
    sqlite3_bind_blob(st, 1, site.data(), static_cast<int>(site.size()), SQLITE_STATIC);
    EXPECT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_finalize(st);
    sqlite3_close(db);
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_EQ(UserVersion(file), 3);
  StoreModel model;
  model.versions["a"] = 7;
  model.sites["a"] = {{"p", p}};
  ExpectStoreHolds(**store, model);
  auto changes = (*store)->ReadChanges("a", 3);
  ASSERT_TRUE(changes.ok()) << changes.status();
  EXPECT_EQ(changes->version, 7u);
  EXPECT_NE(changes->incarnation, 0u);
  EXPECT_TRUE(PutOf(*changes).empty());  // written before version 3, as far as the log knows
  std::vector<std::string> removed = {"p"};
  ASSERT_TRUE((*store)->Commit({"a", 8, {}, removed}).ok());
  changes = (*store)->ReadChanges("a", 7);
  ASSERT_TRUE(changes.ok());
  EXPECT_EQ(changes->removed, removed);
}

// A damaged file, a file of something else and a store of a newer release are refused when
// the store opens, each naming the file, and none is changed.
TEST(Store, DamagedForeignAndNewerFilesAreRefusedByName) {
  TempDir dir;
  const std::string file = dir.path() + "/data/gvd.sqlite3";
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok()) << store.status();
    ASSERT_TRUE((*store)->CreateScene(Settings("a"), 1).ok());
  }
  EXPECT_EQ(UserVersion(file), 3);  // recorded in every store
  std::system(("cp " + file + " " + dir.path() + "/good").c_str());

  std::mt19937_64 rng(5);
  std::string noise(64 * 1024, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  for (const std::string& bytes : {noise, std::string("scene,a\nsite,b\n")}) {
    { std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes; }
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_FALSE(store.ok());
    EXPECT_EQ(store.status().code(), absl::StatusCode::kDataLoss) << store.status();
    EXPECT_NE(store.status().message().find(file), std::string::npos) << store.status();
    std::ifstream in(file, std::ios::binary);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), bytes);
  }

  std::system(("rm -f " + file + "*; cp " + dir.path() + "/good " + file).c_str());
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 7", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  auto newer = SqliteStore::Open(dir.path() + "/data");
  ASSERT_FALSE(newer.ok());
  EXPECT_EQ(newer.status().code(), absl::StatusCode::kFailedPrecondition) << newer.status();
  EXPECT_NE(newer.status().message().find(file), std::string::npos) << newer.status();
  EXPECT_NE(newer.status().message().find("newer release"), std::string::npos) << newer.status();
  EXPECT_EQ(UserVersion(file), 7);
}

TEST(Store, ARetiredSceneRefusesWrites) {
  Scene scene(Settings("gone"));
  ASSERT_TRUE(scene.Upsert({{"a", PointSite{{0.1, 0.1}}}}, 10).ok());
  EXPECT_EQ(scene.Retire([] { return absl::UnavailableError("disk"); }).code(),
            absl::StatusCode::kUnavailable);
  EXPECT_FALSE(scene.deleted());  // a failed delete keeps the scene
  ASSERT_TRUE(scene.Retire().ok());
  EXPECT_TRUE(scene.deleted());
  EXPECT_EQ(scene.Retire().code(), absl::StatusCode::kNotFound);
  bool persisted = false;
  auto write = scene.Upsert({{"b", PointSite{{0.2, 0.2}}}}, 10, [&](const ChangeSet&) {
    persisted = true;
    return absl::OkStatus();
  });
  EXPECT_EQ(write.status().code(), absl::StatusCode::kNotFound);
  EXPECT_FALSE(persisted);
  EXPECT_EQ(scene.Delete({"a"}).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(scene.version(), 2u);
}

// The change set a write hands to the store is exactly what it did.
TEST(Store, ChangeSetsNameWhatAWriteDid) {
  Scene scene(Settings("c"));
  ASSERT_TRUE(scene.Upsert({{"a", PointSite{{0.1, 0.1}}}, {"b", PointSite{{0.2, 0.2}}}}, 10).ok());
  std::vector<std::string> put_ids, removed;
  uint64_t version = 0;
  ASSERT_TRUE(scene
                  .Upsert({{"b", PointSite{{0.3, 0.3}}}, {"c", PointSite{{0.4, 0.4}}}}, 10,
                          [&](const ChangeSet& c) {
                            for (const auto& s : c.Put<Site>()) put_ids.push_back(s->id);
                            version = c.version;
                            EXPECT_EQ(c.scene_id, "c");
                            EXPECT_TRUE(c.removed.empty());
                            return absl::OkStatus();
                          })
                  .ok());
  EXPECT_EQ(put_ids, (std::vector<std::string>{"b", "c"}));
  EXPECT_EQ(version, 3u);
  ASSERT_TRUE(scene
                  .Delete({"a", "c"},
                          [&](const ChangeSet& c) {
                            removed.assign(c.removed.begin(), c.removed.end());
                            EXPECT_EQ(c.put_count(), 0u);
                            EXPECT_EQ(c.version, 4u);
                            return absl::OkStatus();
                          })
                  .ok());
  EXPECT_EQ(removed, (std::vector<std::string>{"a", "c"}));
}

// The rows of a change set are written in id order, not in the order they were put: where
// one id is put twice (a change set the scene core would not make), the later one is kept,
// as when the rows went in as put; and ids out of order, differing past their first 8 bytes,
// are all kept.
// `fold_chunks`: how many chunks of the pack to fold before reading.
void CheckALaterPutWins(const SqliteStore::Packing& packing, uint64_t fold_chunks) {
  TempDir dir;
  std::mt19937_64 rng(31);
  const std::vector<std::string> ids = {"same-prefix-b", "a", "same-prefix-a", "a", "z", "a"};
  std::vector<std::shared_ptr<const Site>> put;
  for (const std::string& id : ids) {
    put.push_back(std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id)));
  }
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok()) << store.status();
    (*store)->set_packing(packing);
    ASSERT_TRUE((*store)->CreateScene(Settings("d"), 1).ok());
    ASSERT_TRUE((*store)->Commit({"d", 2, put, {}}).ok());
    if (fold_chunks > 0) {
      auto folded = (*store)->FoldPacks(fold_chunks);
      ASSERT_TRUE(folded.ok()) << folded.status();
      EXPECT_EQ(*folded, std::min<uint64_t>(put.size(), fold_chunks * packing.fold_chunk));
    }
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  // Read after the restart, and again once what was left of the pack is folded (a fold cut
  // short by the restart starts again from the pack's first site).
  for (int pass = 0; pass < 2; ++pass) {
    SCOPED_TRACE(pass == 0 ? "after the restart" : "folded after the restart");
    if (pass == 1) {
      ASSERT_TRUE((*store)->FoldPacks().ok());
    }
    auto scenes = (*store)->Load();
    ASSERT_TRUE(scenes.ok()) << scenes.status();
    ASSERT_EQ(scenes->size(), 1u);
    std::map<std::string, const Site*> stored;
    const std::vector<Site> front = SitesOf(scenes->front());
    for (const Site& site : front) stored[site.id] = &site;
    ASSERT_EQ(stored.size(), 4u);
    EXPECT_TRUE(SameSite(*stored["a"], *put[5])) << "the last of a's three puts";
    EXPECT_TRUE(SameSite(*stored["same-prefix-a"], *put[2]));
    EXPECT_TRUE(SameSite(*stored["same-prefix-b"], *put[0]));
    EXPECT_TRUE(SameSite(*stored["z"], *put[4]));
  }
}

TEST(Store, ALaterPutOfAnIdInOneChangeSetWins) {
  SqliteStore::Packing rows, packed;
  packed.min_sites = 2;
  packed.fold_after = std::chrono::hours(1);
  {
    SCOPED_TRACE("rows");
    CheckALaterPutWins(rows, 0);
  }
  {
    SCOPED_TRACE("a pack");
    CheckALaterPutWins(packed, 0);
  }
  {
    SCOPED_TRACE("a pack folded");
    CheckALaterPutWins(packed, 1);
  }
  // Folded a site at a time, in id order: a's first put and then its second are rows while
  // its last is still in the pack (read after the restart, the rest folded by then or not).
  packed.fold_chunk = 1;
  for (uint64_t chunks : {1u, 2u}) {
    SCOPED_TRACE(::testing::Message() << "a pack, " << chunks << " of its sites folded");
    CheckALaterPutWins(packed, chunks);
  }
}

// A removal newer than a pack not yet folded hides the pack's put of its site: compaction
// keeps its tombstone until the pack is folded, and a follower reading from any version
// sees the site removed.
TEST(Store, ATombstoneOutlivesTheUnfoldedPackItHides) {
  TempDir dir;
  std::mt19937_64 rng(37);
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok()) << store.status();
  SqliteStore::Packing packing;
  packing.min_sites = 3;
  packing.fold_after = std::chrono::hours(1);
  (*store)->set_packing(packing);
  (*store)->set_retention(Retention{2, 1});  // every commit drops tombstones 2 versions old
  ASSERT_TRUE((*store)->CreateScene(Settings("t"), 1).ok());
  std::vector<std::shared_ptr<const Site>> put;
  for (const char* id : {"a", "b", "c"}) {
    put.push_back(std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id)));
  }
  ASSERT_TRUE((*store)->Commit({"t", 2, put, {}}).ok());  // a pack
  const std::vector<std::string> removed = {"a"};
  ASSERT_TRUE((*store)->Commit({"t", 3, {}, removed}).ok());
  // A follower at version 1 (before the pack) and one at version 2 (after it).
  auto sorted_ids = [](const SceneChanges& c) {
    std::set<std::string> out;
    for (const auto& site : PutOf(c)) out.insert(site->id);
    return out;
  };
  for (uint64_t after : {1u, 2u}) {
    auto changes = (*store)->ReadChanges("t", after);
    ASSERT_TRUE(changes.ok()) << changes.status();
    ASSERT_FALSE(changes->complete) << after;
    const std::set<std::string> put_after = after == 1 ? std::set<std::string>{"b", "c"}
                                                         : std::set<std::string>{};
    EXPECT_EQ(sorted_ids(*changes), put_after) << after;
    EXPECT_EQ(changes->removed, removed) << after;
  }
  for (uint64_t v = 4; v < 12; ++v) {
    std::vector<std::shared_ptr<const Site>> one = {
        std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), "d"))};
    ASSERT_TRUE((*store)->Commit({"t", v, one, {}}).ok());
  }
  auto ids = [&]() {
    std::set<std::string> out;
    auto scenes = (*store)->Load();
    EXPECT_TRUE(scenes.ok()) << scenes.status();
    if (scenes.ok()) {
      for (const Site& site : SitesOf(scenes->front())) out.insert(site.id);
    }
    return out;
  };
  const std::set<std::string> want = {"b", "c", "d"};
  EXPECT_EQ(ids(), want);
  // A follower from before the horizon (9) reads the whole state.
  for (uint64_t after : {0u, 2u, 3u}) {
    auto changes = (*store)->ReadChanges("t", after);
    ASSERT_TRUE(changes.ok()) << changes.status();
    EXPECT_TRUE(changes->complete) << after;
    EXPECT_EQ(sorted_ids(*changes), want) << after;
  }
  auto folded = (*store)->FoldPacks();
  ASSERT_TRUE(folded.ok()) << folded.status();
  EXPECT_EQ(*folded, 3u);
  EXPECT_EQ(ids(), want);
  // Once folded, the tombstone is dropped by the next compaction, and "a" stays removed.
  ASSERT_TRUE((*store)->Commit({"t", 12, {}, std::vector<std::string>{"b"}}).ok());
  EXPECT_EQ(ids(), (std::set<std::string>{"c", "d"}));
}

// A fold part way through a pack, in one connection, while another deletes the scene, makes
// it again and writes a pack of the same version: the first goes on with the new pack from
// its start, and the old pack's sites do not come back.
TEST(Store, AFoldPartWayThroughAPackKnowsItFromANewOneOfItsVersion) {
  TempDir dir;
  std::mt19937_64 rng(41);
  auto a = SqliteStore::Open(dir.path() + "/data");
  auto b = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(a.ok() && b.ok());
  SqliteStore::Packing packing;
  packing.min_sites = 2;
  packing.fold_after = std::chrono::hours(1);
  packing.fold_chunk = 2;
  (*a)->set_packing(packing);
  (*b)->set_packing(packing);
  auto sites = [&](const std::vector<std::string>& ids) {
    std::vector<std::shared_ptr<const Site>> out;
    for (const std::string& id : ids) {
      out.push_back(std::make_shared<const Site>(RandomSite(rng, static_cast<int>(rng()), id)));
    }
    return out;
  };
  ASSERT_TRUE((*a)->CreateScene(Settings("s"), 1).ok());
  ASSERT_TRUE((*a)->Commit({"s", 2, sites({"old1", "old2", "old3", "old4"}), {}}).ok());
  auto folded = (*a)->FoldPacks(1);
  ASSERT_TRUE(folded.ok()) << folded.status();
  EXPECT_EQ(*folded, 2u);
  ASSERT_TRUE((*b)->DeleteScene("s").ok());
  ASSERT_TRUE((*b)->CreateScene(Settings("s"), 1).ok());
  const auto fresh = sites({"new1", "new2", "new3", "new4", "new5"});
  ASSERT_TRUE((*b)->Commit({"s", 2, fresh, {}}).ok());
  folded = (*a)->FoldPacks();
  ASSERT_TRUE(folded.ok()) << folded.status();
  EXPECT_EQ(*folded, fresh.size());
  for (SqliteStore* store : {a->get(), b->get()}) {
    auto scenes = store->Load();
    ASSERT_TRUE(scenes.ok()) << scenes.status();
    ASSERT_EQ(scenes->size(), 1u);
    std::map<std::string, const Site*> stored;
    const std::vector<Site> front = SitesOf(scenes->front());
    for (const Site& site : front) stored[site.id] = &site;
    ASSERT_EQ(stored.size(), fresh.size());
    for (const auto& site : fresh) {
      ASSERT_TRUE(stored.count(site->id)) << site->id;
      EXPECT_TRUE(SameSite(*stored[site->id], *site)) << site->id;
    }
  }
}

// ---- 3D scenes ----

bool SameVec3(Vec3 a, Vec3 b) { return SameBits(a.x, b.x) && SameBits(a.y, b.y) && SameBits(a.z, b.z); }

std::vector<Site3> Sites3() {
  Site3 weighted{"w", SegmentSite3{{-0.0, 1e300, 5e-324}, {1, 2, 3}}};
  weighted.additive = 1.0 / 3;
  weighted.multiplicative = 7;
  weighted.max_distance = 2.5;
  return {{"p", PointSite3{{0.1, -0.2, 0.3}}},
          weighted,
          {"t", TriangleSite3{{0, 0, 0}, {1, 0, 0}, {0, 1, 1e-9}}},
          {"m", Placed(Torus(1, 0.25, 8, 6), {0.5, 0.5, 0.5}, 1.0 / 3)}};
}

TEST(Codec, Sites3RoundTripBitForBit) {
  for (const Site3& s : Sites3()) {
    auto back = DecodeSite<Site3>(EncodeSite(s));
    ASSERT_TRUE(back.ok()) << s.id << ": " << back.status();
    EXPECT_EQ(back->id, s.id);
    EXPECT_TRUE(SameBits(back->additive, s.additive) && SameBits(back->multiplicative, s.multiplicative) &&
                SameBits(back->max_distance, s.max_distance));
    EXPECT_EQ(back->geometry.index(), s.geometry.index());
    if (const auto* m = std::get_if<MeshSite3>(&s.geometry)) {
      const auto& b = std::get<MeshSite3>(back->geometry);
      ASSERT_EQ(b.vertices.size(), m->vertices.size());
      for (size_t i = 0; i < m->vertices.size(); ++i) EXPECT_TRUE(SameVec3(b.vertices[i], m->vertices[i]));
      EXPECT_EQ(b.triangles, m->triangles);
      // Its tables and tree are made again, and answer as the original's do.
      EXPECT_EQ(b.edges, m->edges);
      const Hit3 x = NearestFeature({0.5, 0.5, 2}, s.geometry), y = NearestFeature({0.5, 0.5, 2}, back->geometry);
      EXPECT_EQ(x.distance, y.distance);
      EXPECT_EQ(x.index, y.index);
    } else if (const auto* t = std::get_if<TriangleSite3>(&s.geometry)) {
      const auto& b = std::get<TriangleSite3>(back->geometry);
      EXPECT_TRUE(SameVec3(b.a, t->a) && SameVec3(b.b, t->b) && SameVec3(b.c, t->c));
    } else if (const auto* g = std::get_if<SegmentSite3>(&s.geometry)) {
      const auto& b = std::get<SegmentSite3>(back->geometry);
      EXPECT_TRUE(SameVec3(b.a, g->a) && SameVec3(b.b, g->b));
    } else {
      EXPECT_TRUE(SameVec3(std::get<PointSite3>(back->geometry).p, std::get<PointSite3>(s.geometry).p));
    }
  }
}

TEST(Codec, Damaged3DBytesAreDataLoss) {
  for (const Site3& s : Sites3()) {
    const std::string bytes = EncodeSite(s);
    for (size_t n = 0; n < bytes.size(); ++n) {
      ASSERT_EQ(DecodeSite<Site3>(std::string_view(bytes).substr(0, n)).status().code(),
                absl::StatusCode::kDataLoss)
          << s.id << " prefix " << n;
    }
    EXPECT_EQ(DecodeSite<Site3>(bytes + "x").status().code(), absl::StatusCode::kDataLoss);
    // A 2D site's bytes are no 3D site, and the other way round.
    EXPECT_EQ(DecodeSite<Site>(bytes).status().code(), absl::StatusCode::kDataLoss) << s.id;
  }
  EXPECT_EQ(DecodeSite<Site3>(EncodeSite(Site{"p", PointSite{{1, 2}}})).status().code(),
            absl::StatusCode::kDataLoss);
  // A mesh whose triangle names a vertex past the end, or a NaN coordinate.
  Site3 mesh = Sites3()[3];
  std::string bad = EncodeSite(mesh);
  bad[bad.size() - 1] = '\x7f';  // the last index's high byte
  EXPECT_EQ(DecodeSite<Site3>(bad).status().code(), absl::StatusCode::kDataLoss);
  Site3 nan{"n", PointSite3{{NAN, 0, 0}}};
  EXPECT_EQ(DecodeSite<Site3>(EncodeSite(nan)).status().code(), absl::StatusCode::kDataLoss);
}

TEST(Codec, Settings3RoundTripAnd2DKeepsItsFormat) {
  SceneSettings s = ValidSettings();
  EXPECT_EQ(EncodeSettings(s)[0], 1);  // a 2D scene's settings read by every release
  s.depth = 48;
  s.min_z = -1e-300;
  s.max_z = 1.0 / 3;
  const std::string bytes = EncodeSettings(s);
  EXPECT_EQ(bytes[0], 2);
  auto back = DecodeSettings(bytes);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->depth, 48u);
  EXPECT_TRUE(SameBits(back->min_z, -1e-300));
  EXPECT_TRUE(SameBits(back->max_z, 1.0 / 3));
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_EQ(DecodeSettings(bytes.substr(0, n)).status().code(), absl::StatusCode::kDataLoss);
  }
  s.max_z = s.min_z;  // an empty z range no accepted scene had
  EXPECT_EQ(DecodeSettings(EncodeSettings(s)).status().code(), absl::StatusCode::kDataLoss);
}

TEST(Store, Keeps3DScenesAcrossReopens) {
  TempDir dir;
  SceneSettings settings = ValidSettings();
  settings.id = "space";
  settings.depth = 16;
  settings.max_z = 1;
  {
    auto store = SqliteStore::Open(dir.path() + "/data");
    ASSERT_TRUE(store.ok()) << store.status();
    ASSERT_TRUE((*store)->CreateScene(settings, 1).ok());
    Scene3 scene(settings);
    auto commit = [&](const ChangeSet& c) {
      EXPECT_TRUE(c.Put<Site>().empty());  // a 3D scene's change puts Site3s
      return (*store)->Commit(c);
    };
    ASSERT_TRUE(scene.Upsert(Sites3(), 10, commit).ok());
    ASSERT_TRUE(scene.Delete({"p"}, commit).ok());
  }
  auto store = SqliteStore::Open(dir.path() + "/data");
  ASSERT_TRUE(store.ok());
  auto loaded = (*store)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  const StoredScene& back = (*loaded)[0];
  EXPECT_EQ(back.settings.depth, 16u);
  EXPECT_EQ(back.version, 3u);
  EXPECT_TRUE(SitesOf(back).empty());
  std::vector<std::string> ids;
  for (const Site3& s : SitesOf<Site3>(back)) ids.push_back(s.id);
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(ids, (std::vector<std::string>{"m", "t", "w"}));
}

}  // namespace
}  // namespace gvd
