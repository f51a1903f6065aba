#include "server/store.h"

#include <sqlite3.h>
#include <sys/stat.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace gvd {
namespace {

absl::Status SqliteError(sqlite3* db, const std::string& what) {
  return absl::InternalError(absl::StrCat("store: ", what, ": ", sqlite3_errmsg(db)));
}

// A prepared statement, finalized on scope exit.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) stmt_ = nullptr;
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  bool ok() const { return stmt_ != nullptr; }
  sqlite3_stmt* get() { return stmt_; }
  void Text(int i, const std::string& s) {
    sqlite3_bind_text(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
  }
  void Blob(int i, const std::string& s) {
    sqlite3_bind_blob(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
  }
  void Int(int i, uint64_t v) { sqlite3_bind_int64(stmt_, i, static_cast<sqlite3_int64>(v)); }
  // Steps a statement that returns no rows, and resets it for reuse.
  bool Run() {
    int rc = sqlite3_step(stmt_);
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    return rc == SQLITE_DONE;
  }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

std::string ColumnBlob(sqlite3_stmt* s, int i) {
  const void* p = sqlite3_column_blob(s, i);
  return std::string(static_cast<const char*>(p), sqlite3_column_bytes(s, i));
}

}  // namespace

absl::StatusOr<std::unique_ptr<Store>> Store::Open(const std::string& dir) {
  bool persistent = dir != ":memory:";
  std::string path = ":memory:";
  if (persistent) {
    if (mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) {
      return absl::FailedPreconditionError(
          absl::StrCat("store: cannot create directory ", dir, ": ", std::strerror(errno)));
    }
    path = dir + "/gvd.sqlite3";
  }
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    absl::Status s = absl::FailedPreconditionError(
        absl::StrCat("store: cannot open ", path, ": ", db ? sqlite3_errmsg(db) : "out of memory"));
    sqlite3_close(db);
    return s;
  }
  std::unique_ptr<Store> store(new Store(db, path));
  sqlite3_busy_timeout(db, 5000);
  for (const char* sql : {
           "PRAGMA journal_mode=WAL",
           "PRAGMA synchronous=FULL",
           "PRAGMA foreign_keys=ON",
           "CREATE TABLE IF NOT EXISTS scenes ("
           "  id TEXT PRIMARY KEY,"
           "  request BLOB NOT NULL,"  // the CreateSceneRequest
           "  version INTEGER NOT NULL)",
           "CREATE TABLE IF NOT EXISTS sites ("
           "  scene TEXT NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,"
           "  id TEXT NOT NULL,"
           "  site BLOB NOT NULL,"  // the Site
           "  PRIMARY KEY (scene, id)) WITHOUT ROWID",
       }) {
    if (auto s = store->Exec(sql); !s.ok()) return s;
  }
  return store;
}

Store::~Store() { sqlite3_close(db_); }

absl::Status Store::Exec(const char* sql) {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &error) != SQLITE_OK) {
    absl::Status s = absl::InternalError(absl::StrCat("store: ", sql, ": ", error ? error : "?"));
    sqlite3_free(error);
    return s;
  }
  return absl::OkStatus();
}

template <class Body>
absl::Status Store::Transaction(Body body) {
  std::lock_guard<std::mutex> lock(mu_);
  auto start = std::chrono::steady_clock::now();
  if (auto s = Exec("BEGIN IMMEDIATE"); !s.ok()) return s;
  absl::Status s = body();
  if (s.ok()) s = Exec("COMMIT");
  if (!s.ok()) {
    Exec("ROLLBACK").IgnoreError();
    return s;
  }
  last_commit_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return absl::OkStatus();
}

double Store::last_commit_seconds() const {
  std::lock_guard<std::mutex> lock(mu_);
  return last_commit_seconds_;
}

absl::StatusOr<std::vector<Store::StoredScene>> Store::Load() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<StoredScene> scenes;
  Statement s(db_, "SELECT id, request, version FROM scenes ORDER BY id");
  if (!s.ok()) return SqliteError(db_, "reading scenes");
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    StoredScene scene;
    if (!scene.request.ParseFromString(ColumnBlob(s.get(), 1))) {
      return absl::DataLossError(absl::StrCat(
          "store: scene ", reinterpret_cast<const char*>(sqlite3_column_text(s.get(), 0)),
          " has an unreadable request"));
    }
    scene.version = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 2));
    scenes.push_back(std::move(scene));
  }
  if (rc != SQLITE_DONE) return SqliteError(db_, "reading scenes");
  Statement sites(db_, "SELECT site FROM sites WHERE scene = ?");
  if (!sites.ok()) return SqliteError(db_, "reading sites");
  for (StoredScene& scene : scenes) {
    sites.Text(1, scene.request.scene_id());
    while ((rc = sqlite3_step(sites.get())) == SQLITE_ROW) {
      v1::Site site;
      if (!site.ParseFromString(ColumnBlob(sites.get(), 0))) {
        return absl::DataLossError(absl::StrCat("store: a site of scene ",
                                                scene.request.scene_id(), " is unreadable"));
      }
      scene.sites.push_back(std::move(site));
    }
    sqlite3_reset(sites.get());
    if (rc != SQLITE_DONE) return SqliteError(db_, "reading sites");
  }
  return scenes;
}

absl::Status Store::CreateScene(const v1::CreateSceneRequest& request, uint64_t version) {
  return Transaction([&]() -> absl::Status {
    Statement s(db_, "INSERT INTO scenes (id, request, version) VALUES (?, ?, ?)");
    s.Text(1, request.scene_id());
    s.Blob(2, request.SerializeAsString());
    s.Int(3, version);
    if (!s.ok() || !s.Run()) return SqliteError(db_, "storing the scene");
    return absl::OkStatus();
  });
}

absl::Status Store::DeleteScene(const std::string& scene_id) {
  return Transaction([&]() -> absl::Status {
    Statement s(db_, "DELETE FROM scenes WHERE id = ?");  // sites cascade
    s.Text(1, scene_id);
    if (!s.ok() || !s.Run()) return SqliteError(db_, "deleting the scene");
    return absl::OkStatus();
  });
}

absl::Status Store::SetVersion(const std::string& scene_id, uint64_t version) {
  Statement v(db_, "UPDATE scenes SET version = ? WHERE id = ?");
  v.Int(1, version);
  v.Text(2, scene_id);
  if (!v.ok() || !v.Run()) return SqliteError(db_, "storing the version");
  return absl::OkStatus();
}

absl::Status Store::UpsertSites(const std::string& scene_id,
                                const google::protobuf::RepeatedPtrField<v1::Site>& sites,
                                uint64_t version) {
  return Transaction([&]() -> absl::Status {
    Statement put(db_, "INSERT OR REPLACE INTO sites (scene, id, site) VALUES (?, ?, ?)");
    if (!put.ok()) return SqliteError(db_, "storing sites");
    for (const v1::Site& site : sites) {
      put.Text(1, scene_id);
      put.Text(2, site.id());
      put.Blob(3, site.SerializeAsString());
      if (!put.Run()) return SqliteError(db_, "storing a site");
    }
    return SetVersion(scene_id, version);
  });
}

absl::Status Store::DeleteSites(const std::string& scene_id, const std::vector<std::string>& ids,
                                uint64_t version) {
  return Transaction([&]() -> absl::Status {
    Statement del(db_, "DELETE FROM sites WHERE scene = ? AND id = ?");
    if (!del.ok()) return SqliteError(db_, "deleting sites");
    for (const std::string& id : ids) {
      del.Text(1, scene_id);
      del.Text(2, id);
      if (!del.Run()) return SqliteError(db_, "deleting a site");
    }
    return SetVersion(scene_id, version);
  });
}

}  // namespace gvd
