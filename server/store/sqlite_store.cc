#include "server/store/sqlite_store.h"

#include <sqlite3.h>
#include <fcntl.h>
#include <pthread.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <unordered_map>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/scene/codec.h"
#include "render/scene/id_order.h"
#include "server/log.h"
#include "server/store/rows.h"

namespace gvd {
namespace {

// The nice value (Linux sets it per thread) of the thread that reads and orders a pack for
// the folder: upkeep nobody waits for. Not the folder's own: its chunks hold mu_, which
// commits wait for.
constexpr int kFoldNice = 10;

// The WAL's size, in pages, at which a commit asks for a checkpoint: SQLite's own default.
constexpr int kCheckpointPages = 1000;

// The connection's last error as a status naming the store's file, by what it means for a
// caller: a full disk is RESOURCE_EXHAUSTED and failing or busy storage UNAVAILABLE (both
// pass: a later write succeeds once space is freed or the device recovers), a damaged file
// DATA_LOSS.
absl::Status SqliteError(sqlite3* db, const std::string& what) {
  const char* file = sqlite3_db_filename(db, "main");
  const std::string text = absl::StrCat("store ", file && *file ? file : ":memory:", ": ", what,
                                        ": ", sqlite3_errmsg(db));
  switch (sqlite3_extended_errcode(db) & 0xff) {
    case SQLITE_FULL:
      return absl::ResourceExhaustedError(
          absl::StrCat(text, " (its disk is full: nothing was stored, and writes succeed again "
                             "once space is freed)"));
    case SQLITE_IOERR:
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
    case SQLITE_READONLY:
    case SQLITE_CANTOPEN:
    case SQLITE_NOMEM:
      return absl::UnavailableError(text);
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return absl::DataLossError(absl::StrCat(text, " (the file is damaged, or is not a gvd store)"));
    default:
      return absl::InternalError(text);
  }
}

// A statement of the connection's cache (SqliteStore::Prepared), reset with its bindings
// cleared when the scope ends so that the next user finds it fresh.
class Statement {
 public:
  explicit Statement(sqlite3_stmt* stmt) : stmt_(stmt) {}
  ~Statement() {
    if (stmt_ == nullptr) return;
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  bool ok() const { return stmt_ != nullptr; }
  sqlite3_stmt* get() { return stmt_; }
  void Text(int i, std::string_view s) {
    sqlite3_bind_text(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
  }
  void Blob(int i, std::string_view s) {
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

std::string_view ColumnBlob(sqlite3_stmt* s, int i) {
  const void* p = sqlite3_column_blob(s, i);
  return std::string_view(static_cast<const char*>(p), sqlite3_column_bytes(s, i));
}

// The bytes of pack `id` read on connection `db`; nullopt when there is no such pack.
absl::StatusOr<std::optional<std::string>> ReadPack(sqlite3* db, uint64_t id) {
  sqlite3_stmt* raw = nullptr;
  if (sqlite3_prepare_v2(db, "SELECT sites FROM site_pack WHERE id = ?", -1, &raw, nullptr) !=
      SQLITE_OK) {
    return SqliteError(db, "reading packs");
  }
  std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> statement(raw, sqlite3_finalize);
  sqlite3_bind_int64(raw, 1, static_cast<sqlite3_int64>(id));
  const int rc = sqlite3_step(raw);
  if (rc == SQLITE_DONE) return std::nullopt;
  if (rc != SQLITE_ROW) return SqliteError(db, "reading packs");
  return std::string(ColumnBlob(raw, 0));
}

// How long a connection waits for another's lock before its call fails.
constexpr int kBusyTimeoutMs = 5000;

// Another connection to the store's file at `path`, for one thread of the store's alone
// (the folder's reads, the checkpointer's copies); `what` names its purpose in an error.
absl::StatusOr<sqlite3*> OpenConnection(const std::string& path, int flags,
                                        const std::string& what) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, flags | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    absl::Status s =
        db ? SqliteError(db, what) : absl::ResourceExhaustedError("store: out of memory");
    sqlite3_close(db);
    return s;
  }
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  return db;
}

std::string ColumnText(sqlite3_stmt* s, int i) {
  const unsigned char* p = sqlite3_column_text(s, i);
  return p ? std::string(reinterpret_cast<const char*>(p), sqlite3_column_bytes(s, i)) : "";
}

// The database's schema. The earlier one (tables "scenes" and "sites", holding request
// messages) is converted by Migrate.
// The version of kSchema, recorded in the file (PRAGMA user_version). Version 2 made the
// state a log (store.h): each site row carries the version that last wrote it, a removed
// site leaves a tombstone (no bytes), and a scene has an incarnation and a horizon. Version 3
// added packs: a large change set's sites in one row, folded into site rows later.
constexpr int kSchemaVersion = 3;
constexpr const char* kSchema[] = {
    "CREATE TABLE IF NOT EXISTS scene ("
    "  id TEXT PRIMARY KEY,"
    "  settings BLOB NOT NULL,"  // EncodeSettings
    "  version INTEGER NOT NULL,"
    "  incarnation INTEGER NOT NULL DEFAULT 0,"
    "  horizon INTEGER NOT NULL DEFAULT 0)",  // tombstones up to it are dropped
    "CREATE TABLE IF NOT EXISTS site ("
    "  scene TEXT NOT NULL REFERENCES scene(id) ON DELETE CASCADE,"  // kept by the store
    "  id TEXT NOT NULL,"
    "  site BLOB NOT NULL,"  // EncodeSite; empty: a tombstone
    "  version INTEGER NOT NULL DEFAULT 0,"
    "  PRIMARY KEY (scene, id)) WITHOUT ROWID",
    // A change set's puts written as one row (EncodePack), all of its version. A site's state
    // is the newest of its row and its entries in packs (Latest); the folder moves a pack's
    // entries into site rows a chunk a transaction, and drops the pack with its last chunk.
    // A fold cut short starts again from the pack's first entry (a fold is idempotent), so
    // the row is never rewritten: only appended, and deleted. Its id is never reused (a fold
    // part way through a pack knows it by its id: another connection may have deleted the
    // scene and written a pack of the same version for the scene made again).
    "CREATE TABLE IF NOT EXISTS site_pack ("
    "  id INTEGER PRIMARY KEY AUTOINCREMENT,"
    "  scene TEXT NOT NULL,"
    "  version INTEGER NOT NULL,"
    "  sites BLOB NOT NULL,"
    "  UNIQUE (scene, version))",
};
// Added to a store of schema version 1 (or 0, the same schema unrecorded), each column when
// missing: a conversion cut short is finished at the next start.
struct AddedColumn {
  const char* table;
  const char* column;
  const char* sql;
};
constexpr AddedColumn kToVersion2[] = {
    {"scene", "incarnation", "ALTER TABLE scene ADD COLUMN incarnation INTEGER NOT NULL DEFAULT 0"},
    {"scene", "horizon", "ALTER TABLE scene ADD COLUMN horizon INTEGER NOT NULL DEFAULT 0"},
    {"site", "version", "ALTER TABLE site ADD COLUMN version INTEGER NOT NULL DEFAULT 0"},
};
// Only tombstones are indexed by version: compaction finds them without a scan, and live
// sites' writes pay for no second index (a follower's read scans its scene's rows, and
// SQLite has no followers but tests).
constexpr const char* kTombstoneIndex =
    "CREATE INDEX IF NOT EXISTS site_tombstone ON site (scene, version) WHERE site = x''";
// A new incarnation: random, positive.
constexpr const char* kNewIncarnation = "((random() & 0x7fffffffffffffff) | 1)";

// A change set's puts as a pack (codec.h), in its order (of two puts of one id the later wins).
std::string EncodePack(const ChangeSet& changes) {
  std::string out;
  std::visit([&](const auto& sites) {
    for (const auto& site : sites) AppendToPack(*site, &out);
  }, changes.put);
  return out;
}
absl::Status DamagedPack(std::string_view scene_id, uint64_t version) {
  return absl::DataLossError(absl::StrCat("store: scene \"", std::string(scene_id),
                                          "\": the pack of version ", version, " is damaged"));
}

}  // namespace

absl::StatusOr<std::unique_ptr<SqliteStore>> SqliteStore::Open(const std::string& dir,
                                                               const Legacy& legacy) {
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
  if (sqlite3_open_v2(path.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    absl::Status s = absl::FailedPreconditionError(
        absl::StrCat("store: cannot open ", path, ": ", db ? sqlite3_errmsg(db) : "out of memory"));
    sqlite3_close(db);
    return s;
  }
  std::unique_ptr<SqliteStore> store(new SqliteStore(db, path));
  if (persistent) {
    store->wal_path_ = sqlite3_filename_wal(sqlite3_db_filename(db, "main"));
    // In place of SQLite's checkpoint after a commit (the hook replaces it): the store's
    // checkpointer copies the WAL into the database beside the writer.
    sqlite3_wal_hook(
        db,
        [](void* self, sqlite3* connection, const char*, int pages) {
          auto* store = static_cast<SqliteStore*>(self);
          if (pages < kCheckpointPages) return SQLITE_OK;
          if (store->ckpt_failed_.load()) {
            sqlite3_wal_checkpoint_v2(connection, nullptr, SQLITE_CHECKPOINT_PASSIVE, nullptr,
                                      nullptr);
          } else {
            store->WantCheckpoint();
          }
          return SQLITE_OK;
        },
        store.get());
  }
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  // Foreign keys stay off: checking each site row's scene made a bulk insert four to six
  // times slower once the table held other scenes' rows. The store keeps the reference
  // itself: Write stores nothing for a scene that is not stored, DeleteScene deletes its
  // sites.
  for (const char* sql : {"PRAGMA journal_mode=WAL", "PRAGMA synchronous=FULL",
                          "PRAGMA foreign_keys=OFF"}) {
    if (auto s = store->Exec(sql); !s.ok()) return s;
  }
  // The schema's version (PRAGMA user_version; 0 in stores made before it was recorded,
  // which hold this same schema): a store from a newer release is left as it is.
  int version = 0;
  {
    Statement v(store->Prepared("PRAGMA user_version"));
    if (!v.ok() || sqlite3_step(v.get()) != SQLITE_ROW) return SqliteError(db, "reading the schema version");
    version = sqlite3_column_int(v.get(), 0);
  }
  if (version > kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        "store ", path, " was written by a newer release of gvd (schema version ", version,
        "; this release reads up to ", kSchemaVersion, "): run that release, or start on a new "
        "--data directory"));
  }
  for (const char* sql : kSchema) {
    if (auto s = store->Exec(sql); !s.ok()) return s;
  }
  for (const AddedColumn& added : kToVersion2) {
    bool missing;
    {
      Statement has(store->Prepared(
          "SELECT count(*) FROM pragma_table_info(?) WHERE name = ?"));
      if (!has.ok()) return SqliteError(db, "reading the schema");
      has.Text(1, added.table);
      has.Text(2, added.column);
      if (sqlite3_step(has.get()) != SQLITE_ROW) return SqliteError(db, "reading the schema");
      missing = sqlite3_column_int(has.get(), 0) == 0;
    }
    if (missing) {
      if (auto s = store->Exec(added.sql); !s.ok()) return s;
    }
  }
  if (auto s = store->Exec(kTombstoneIndex); !s.ok()) return s;
  if (auto s = store->Migrate(legacy); !s.ok()) return s;
  if (auto s = store->Exec(absl::StrCat("UPDATE scene SET incarnation = ", kNewIncarnation,
                                        " WHERE incarnation = 0").c_str());
      !s.ok()) {
    return s;
  }
  if (version < kSchemaVersion) {
    if (auto s = store->Exec(absl::StrCat("PRAGMA user_version = ", kSchemaVersion).c_str()); !s.ok()) {
      return s;
    }
  }
  bool packs_left = false;
  {
    Statement packs(store->Prepared("SELECT 1 FROM site_pack LIMIT 1"));
    if (!packs.ok()) return SqliteError(db, "reading packs");
    const int rc = sqlite3_step(packs.get());
    if (rc != SQLITE_ROW && rc != SQLITE_DONE) return SqliteError(db, "reading packs");
    packs_left = rc == SQLITE_ROW;
  }
  // Packs left by the last run are folded by this one. Last: from here the store is shared
  // with its folder.
  if (packs_left) store->WantFold();
  return store;
}

void SqliteStore::set_packing(Packing packing) {
  std::lock_guard<std::mutex> lock(mu_);
  std::lock_guard<std::mutex> fold(fold_mu_);
  packing_ = packing;
  fold_cv_.notify_all();
}

void SqliteStore::WantFold() {
  std::lock_guard<std::mutex> lock(fold_mu_);
  last_pack_ = std::chrono::steady_clock::now();
  if (!fold_wanted_) wanted_since_ = last_pack_;
  fold_wanted_ = true;
  if (!folder_.joinable()) folder_ = std::thread([this] { Folder(); });
  fold_cv_.notify_all();
}

absl::Status SqliteStore::PrepareFoldBelowCalls() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto to_prepare = PackToPrepare();
    if (!to_prepare.ok()) return to_prepare.status();
    if (!*to_prepare) return absl::OkStatus();
  }
  // Below calls, as renders are: ordering a pack's entries takes tens of milliseconds of a
  // core, which a call's thread woken meanwhile would otherwise wait a time slice for. On a
  // thread of its own, since a thread's nice value cannot come back down: the folder's
  // chunks hold mu_, and one at nice 10 beside busy threads at 0 held commits for up to
  // 0.76 s (loads of 549 sites during a fold with two busy loops beside: at most 37-58 ms
  // with the chunks at nice 0).
  absl::Status s;
  std::thread([this, &s] {
    pthread_setname_np(pthread_self(), "gvd-store-order");
    setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kFoldNice);
    s = PrepareFold();
  }).join();
  return s;
}

void SqliteStore::Folder() {
  pthread_setname_np(pthread_self(), "gvd-store-fold");
  std::unique_lock<std::mutex> lock(fold_mu_);
  std::chrono::steady_clock::time_point last_chunk;  // when the last chunk ended
  while (!fold_stopping_) {
    if (!fold_wanted_) {
      fold_cv_.wait(lock);
      continue;
    }
    // A bulk load's render and the next change sets go first: the pack waits until none
    // has been written for fold_after, or ten times that since the first (packs that keep
    // coming are folded too), and a fold that failed waits for its retry.
    // Then each chunk goes between commits: once none has come for fold_idle, or
    // fold_max_wait after the last chunk while they keep coming.
    const std::chrono::steady_clock::time_point last_commit{
        std::chrono::steady_clock::duration(last_commit_.load())};
    const auto due = std::max({std::min(last_pack_ + packing_.fold_after,
                                        wanted_since_ + 10 * packing_.fold_after),
                               fold_retry_at_,
                               std::min(last_commit + packing_.fold_idle,
                                        last_chunk + packing_.fold_max_wait)});
    if (std::chrono::steady_clock::now() < due) {
      fold_cv_.wait_until(lock, due);
      continue;
    }
    fold_wanted_ = false;  // a pack written from here on sets it again
    lock.unlock();
    uint64_t folded = 0;
    absl::Status prepared = PrepareFoldBelowCalls();
    absl::StatusOr<bool> more = prepared.ok() ? FoldSome(&folded) : prepared;
    last_chunk = std::chrono::steady_clock::now();
    lock.lock();
    if (!more.ok()) {
      // The packs stay, read as they are; the fold is tried again after 1 s, then after twice
      // as long each time it fails, up to a minute (a damaged pack keeps failing, and is
      // DATA_LOSS to every read of its scene).
      Log(LogLevel::kError, "store_fold_failed", {{"store", path_}, {"error", more.status().ToString()},
                                                  {"retry_ms", std::to_string(fold_backoff_.count())}});
      fold_wanted_ = true;
      fold_retry_at_ = std::chrono::steady_clock::now() + fold_backoff_;
      fold_backoff_ = std::min(2 * fold_backoff_, std::chrono::milliseconds(60000));
    } else {
      fold_backoff_ = std::chrono::milliseconds(1000);
      if (*more) fold_wanted_ = true;
    }
  }
}

void SqliteStore::WantCheckpoint() {
  std::lock_guard<std::mutex> lock(ckpt_mu_);
  ckpt_wanted_ = true;
  if (!checkpointer_.joinable()) checkpointer_ = std::thread([this] { Checkpointer(); });
  ckpt_cv_.notify_all();
}

void SqliteStore::Checkpointer() {
  pthread_setname_np(pthread_self(), "gvd-store-ckpt");
  auto opened = OpenConnection(path_, SQLITE_OPEN_READWRITE, "opening it to checkpoint");
  sqlite3* db = opened.ok() ? *opened : nullptr;
  absl::Status s = opened.status();
  if (s.ok() &&
      sqlite3_exec(db, "PRAGMA synchronous=FULL", nullptr, nullptr, nullptr) != SQLITE_OK) {
    s = SqliteError(db, "opening it to checkpoint");
  }
  if (!s.ok()) {
    Log(LogLevel::kError, "store_checkpointer_failed",
        {{"store", path_}, {"error", s.ToString()}});
    sqlite3_close(db);
    ckpt_failed_ = true;  // the writer's connection checkpoints after its commits again
    return;
  }
  std::unique_lock<std::mutex> lock(ckpt_mu_);
  while (!ckpt_stopping_) {
    if (!ckpt_wanted_) {
      ckpt_cv_.wait(lock);
      continue;
    }
    ckpt_wanted_ = false;
    lock.unlock();
    // PASSIVE: what no reader still needs is copied, and the writer goes on meanwhile; the
    // WAL starts again from its beginning at the first commit after a complete one.
    const int rc = sqlite3_wal_checkpoint_v2(db, nullptr, SQLITE_CHECKPOINT_PASSIVE, nullptr,
                                             nullptr);
    lock.lock();
    if (rc == SQLITE_OK) {
      ++checkpoints_;
    } else {
      Log(LogLevel::kWarn, "store_checkpoint_failed",
          {{"store", path_}, {"error", sqlite3_errmsg(db)}});
    }
  }
  lock.unlock();
  sqlite3_close(db);  // not the last connection: the writer's, closed after, checkpoints
}

uint64_t SqliteStore::checkpoints() const {
  std::lock_guard<std::mutex> lock(ckpt_mu_);
  return checkpoints_;
}

absl::StatusOr<uint64_t> SqliteStore::FoldPacks(uint64_t chunks) {
  uint64_t folded = 0;
  for (uint64_t chunk = 0; chunk < chunks; ++chunk) {
    absl::StatusOr<bool> more = FoldSome(&folded);
    if (!more.ok()) return more.status();
    if (!*more) break;
  }
  return folded;
}

absl::StatusOr<std::optional<SqliteStore::PackHead>> SqliteStore::OldestPack() {
  Statement p(Prepared("SELECT id, scene, version FROM site_pack ORDER BY id LIMIT 1"));
  if (!p.ok()) return SqliteError(db_, "reading packs");
  const int rc = sqlite3_step(p.get());
  if (rc == SQLITE_DONE) return std::nullopt;
  if (rc != SQLITE_ROW) return SqliteError(db_, "reading packs");
  return PackHead{static_cast<uint64_t>(sqlite3_column_int64(p.get(), 0)), ColumnText(p.get(), 1),
                  static_cast<uint64_t>(sqlite3_column_int64(p.get(), 2))};
}

absl::StatusOr<std::optional<SqliteStore::PackHead>> SqliteStore::PackToPrepare() {
  auto oldest = OldestPack();
  if (!oldest.ok()) return oldest.status();
  if (*oldest && fold_cursor_ && fold_cursor_->id == (*oldest)->id) return std::nullopt;
  return oldest;
}

absl::Status SqliteStore::PrepareFold() {
  std::optional<PackHead> head;
  std::optional<std::string> pack;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto to_prepare = PackToPrepare();
    if (!to_prepare.ok()) return to_prepare.status();
    head = *to_prepare;
    if (!head) return absl::OkStatus();
    if (wal_path_.empty()) {  // in memory: no other connection sees the database
      auto read = ReadPack(db_, head->id);
      if (!read.ok()) return read.status();
      pack = std::move(*read);
    }
  }
  if (!wal_path_.empty()) {
    std::lock_guard<std::mutex> lock(fold_read_mu_);
    if (fold_reader_ == nullptr) {
      auto opened = OpenConnection(path_, SQLITE_OPEN_READONLY, "opening it to fold packs");
      if (!opened.ok()) return opened.status();
      fold_reader_ = *opened;
    }
    auto read = ReadPack(fold_reader_, head->id);
    if (!read.ok()) return read.status();
    pack = std::move(*read);
  }
  // Gone since: the scene was deleted, and the next chunk finds the next pack.
  if (!pack) return absl::OkStatus();
  auto cursor = std::make_unique<FoldCursor>();
  cursor->id = head->id;
  cursor->pack = std::move(*pack);
  auto entries = PackEntries(cursor->pack);
  if (!entries.ok()) return DamagedPack(head->scene, head->version);
  cursor->entries = std::move(*entries);
  // In id order, as Write stores rows; of two entries of one id the later stays later.
  cursor->order = IdOrder(cursor->entries.size(), [&](size_t k) -> std::string_view {
    return cursor->entries[k].id;
  });
  std::lock_guard<std::mutex> lock(mu_);
  fold_cursor_ = std::move(cursor);
  return absl::OkStatus();
}

absl::StatusOr<bool> SqliteStore::FoldSome(uint64_t* folded) {
  // The pack's entries are read and put in id order outside the store's lock (for 100,000
  // sites, tens of milliseconds that commits would otherwise wait for); each chunk checks
  // that the pack is still the oldest, and is left to the next call when it is not.
  if (auto s = PrepareFold(); !s.ok()) return s;
  bool found = false;
  absl::Status s = Transaction([&]() -> absl::Status {
    auto oldest = OldestPack();
    if (!oldest.ok()) return oldest.status();
    if (!*oldest) return absl::OkStatus();
    const auto& [id, scene, version] = **oldest;
    found = true;
    if (!fold_cursor_ || fold_cursor_->id != id) {
      fold_cursor_.reset();  // another pack came first: the next call prepares it
      return absl::OkStatus();
    }
    const auto& entries = fold_cursor_->entries;
    const std::vector<uint32_t>& order = fold_cursor_->order;
    const uint64_t done = fold_cursor_->done;
    // Latest's rule: the pack's put replaces an older row and a put of its own version, not a
    // newer row nor a removal of its own version.
    Statement put(Prepared(
        "INSERT INTO site (scene, id, site, version) VALUES (?, ?, ?, ?) "
        "ON CONFLICT (scene, id) DO UPDATE SET site = excluded.site, version = excluded.version "
        "WHERE excluded.version > site.version OR (excluded.version = site.version AND site.site <> x'')"));
    if (!put.ok()) return SqliteError(db_, "folding a pack");
    const uint64_t end = std::min<uint64_t>(order.size(), done + packing_.fold_chunk);
    for (uint64_t k = done; k < end; ++k) {
      const PackEntry& entry = entries[order[k]];
      put.Text(1, scene);
      put.Text(2, entry.id);
      put.Blob(3, entry.site);
      put.Int(4, version);
      if (!put.Run()) return SqliteError(db_, "folding a pack");
    }
    *folded += end - done;
    if (end == order.size()) {
      Statement drop(Prepared("DELETE FROM site_pack WHERE id = ?"));
      if (!drop.ok()) return SqliteError(db_, "folding a pack");
      drop.Int(1, id);
      if (!drop.Run()) return SqliteError(db_, "folding a pack");
      fold_cursor_.reset();
    } else {
      fold_cursor_->done = end;
    }
    return absl::OkStatus();
  }, Durability::kRelaxed);  // a chunk lost with the machine is folded again from its pack
  if (!s.ok()) {
    // What this chunk wrote was rolled back: the pack is folded again from its start.
    std::lock_guard<std::mutex> lock(mu_);
    fold_cursor_.reset();
    return s;
  }
  return found;
}

SqliteStore::~SqliteStore() {
  {
    std::lock_guard<std::mutex> lock(fold_mu_);
    fold_stopping_ = true;
    fold_cv_.notify_all();
  }
  if (folder_.joinable()) folder_.join();  // a pack left unfolded is folded after the next start
  {
    std::lock_guard<std::mutex> lock(flush_mu_);
    stopping_ = true;
    flush_cv_.notify_all();
  }
  if (flusher_.joinable()) flusher_.join();
  if (relaxed_written_ != relaxed_synced_ && !sync_failed_.load()) {
    if (auto s = SyncWal(); !s.ok()) {
      Log(LogLevel::kError, "store_sync_failed", {{"store", path_}, {"error", s.ToString()}});
    }
  }
  {
    std::lock_guard<std::mutex> lock(ckpt_mu_);
    ckpt_stopping_ = true;
    ckpt_cv_.notify_all();
  }
  if (checkpointer_.joinable()) checkpointer_.join();
  if (wal_fd_ >= 0) close(wal_fd_);
  sqlite3_close(fold_reader_);  // first: the last connection to close checkpoints the WAL
  for (const auto& [sql, stmt] : statements_) sqlite3_finalize(stmt);
  sqlite3_close(db_);
}

sqlite3_stmt* SqliteStore::Prepared(const char* sql) {
  auto [it, added] = statements_.try_emplace(sql, nullptr);
  if (added &&
      sqlite3_prepare_v3(db_, sql, -1, SQLITE_PREPARE_PERSISTENT, &it->second, nullptr) != SQLITE_OK) {
    statements_.erase(it);
    return nullptr;
  }
  return it->second;
}

absl::Status SqliteStore::Step(const char* sql) {
  Statement s(Prepared(sql));
  if (!s.ok() || !s.Run()) return SqliteError(db_, sql);
  return absl::OkStatus();
}

absl::Status SqliteStore::Exec(const char* sql) {
  if (sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) != SQLITE_OK) return SqliteError(db_, sql);
  return absl::OkStatus();
}

template <class Body>
absl::Status SqliteStore::Transaction(Body body, Durability durability) {
  std::lock_guard<std::mutex> lock(mu_);
  auto start = std::chrono::steady_clock::now();
  // In WAL mode, synchronous=NORMAL commits without syncing the WAL; FULL syncs it, and with
  // it every relaxed commit written before. After a failed sync of the WAL every commit is a
  // sync one: the store no longer vouches for what it has not synced itself.
  const bool relaxed =
      durability == Durability::kRelaxed && !wal_path_.empty() && !sync_failed_.load();
  if (relaxed != relaxed_connection_) {
    if (auto s = Exec(relaxed ? "PRAGMA synchronous=NORMAL" : "PRAGMA synchronous=FULL");
        !s.ok()) {
      return s;
    }
    relaxed_connection_ = relaxed;
  }
  const int64_t changes_before = sqlite3_total_changes64(db_);
  if (auto s = Step("BEGIN IMMEDIATE"); !s.ok()) return s;
  absl::Status s = body();
  if (s.ok()) s = Step("COMMIT");
  if (!s.ok()) {
    Step("ROLLBACK").IgnoreError();
    return s;
  }
  last_commit_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // A transaction that changed nothing wrote nothing to the WAL, and so synced nothing.
  const bool wrote = sqlite3_total_changes64(db_) != changes_before;
  {
    std::lock_guard<std::mutex> flush(flush_mu_);
    if (!relaxed) {
      if (wrote && !sync_failed_.load()) relaxed_synced_ = relaxed_written_;
    } else if (relaxed_written_++ == relaxed_synced_) {
      oldest_unsynced_ = std::chrono::steady_clock::now();
      if (!flusher_.joinable()) flusher_ = std::thread([this] { Flusher(); });
      flush_cv_.notify_all();
    }
  }
  return absl::OkStatus();
}

void SqliteStore::Flusher() {
  pthread_setname_np(pthread_self(), "gvd-store-sync");  // not its creator's name
  std::unique_lock<std::mutex> lock(flush_mu_);
  while (!stopping_ && !sync_failed_.load()) {
    if (relaxed_synced_ == relaxed_written_) {
      flush_cv_.wait(lock);
      continue;
    }
    // Synced within relaxed_sync_ of the first unsynced commit (the deadline read anew at
    // each wake-up: the period may change), unless a sync commit does it first.
    if (std::chrono::steady_clock::now() < oldest_unsynced_ + relaxed_sync_) {
      flush_cv_.wait_until(lock, oldest_unsynced_ + relaxed_sync_);
      continue;
    }
    const uint64_t written = relaxed_written_;
    const auto started = std::chrono::steady_clock::now();
    lock.unlock();
    absl::Status s = SyncWal();
    lock.lock();
    if (!s.ok()) {
      // Sticky: what the failed sync held may be lost, so none of it is counted synced, and
      // every later commit is a sync one, which fails while the disk does.
      sync_failed_ = true;
      Log(LogLevel::kError, "store_sync_failed", {{"store", path_}, {"error", s.ToString()}});
      break;
    }
    ++flusher_syncs_;
    relaxed_synced_ = std::max(relaxed_synced_, written);
    // Those written during the sync are no older than its start.
    if (relaxed_synced_ != relaxed_written_) oldest_unsynced_ = started;
  }
}

absl::Status SqliteStore::SyncWal() {
  // The WAL keeps its file for the connection's life (a checkpoint rewrites it from the
  // start), so syncing the file through a descriptor of our own syncs what SQLite wrote. The
  // descriptor stays open from the first sync on, so that a write-back error after it is
  // reported to it.
  if (wal_fd_ < 0) {
    wal_fd_ = open(wal_path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (wal_fd_ < 0) {
      return absl::UnavailableError(absl::StrCat("store ", path_, ": cannot open its WAL ",
                                                 wal_path_, ": ", std::strerror(errno)));
    }
  }
  if (fdatasync(wal_fd_) != 0) {
    return absl::UnavailableError(absl::StrCat("store ", path_, ": syncing its WAL ", wal_path_,
                                               ": ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

uint64_t SqliteStore::flusher_syncs() const {
  std::lock_guard<std::mutex> lock(flush_mu_);
  return flusher_syncs_;
}

uint64_t SqliteStore::relaxed_unsynced() const {
  std::lock_guard<std::mutex> lock(flush_mu_);
  return relaxed_written_ - relaxed_synced_;
}

void SqliteStore::set_relaxed_sync(std::chrono::milliseconds period) {
  std::lock_guard<std::mutex> lock(flush_mu_);
  relaxed_sync_ = period;
  flush_cv_.notify_all();
}

double SqliteStore::last_commit_seconds() const {
  std::lock_guard<std::mutex> lock(mu_);
  return last_commit_seconds_;
}

absl::Status SqliteStore::Migrate(const Legacy& legacy) {
  {
    Statement old(Prepared("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'scenes'"));
    if (!old.ok()) return SqliteError(db_, "reading the schema");
    if (sqlite3_step(old.get()) != SQLITE_ROW) return absl::OkStatus();
  }
  if (!legacy.scene || !legacy.site) {
    return absl::FailedPreconditionError(
        absl::StrCat("store: ", path_, " was written by an earlier release; this program "
                     "cannot convert it"));
  }
  return Transaction([&]() -> absl::Status {
    Statement scenes(Prepared("SELECT id, request, version FROM scenes ORDER BY id"));
    Statement sites(Prepared("SELECT site FROM sites WHERE scene = ?"));
    Statement put_scene(Prepared("INSERT INTO scene (id, settings, version) VALUES (?, ?, ?)"));
    Statement put_site(Prepared("INSERT INTO site (scene, id, site) VALUES (?, ?, ?)"));
    if (!scenes.ok() || !sites.ok() || !put_scene.ok() || !put_site.ok()) {
      return SqliteError(db_, "converting the earlier schema");
    }
    int rc;
    while ((rc = sqlite3_step(scenes.get())) == SQLITE_ROW) {
      const std::string id = ColumnText(scenes.get(), 0);
      auto settings = legacy.scene(ColumnBlob(scenes.get(), 1));
      if (!settings.ok()) {
        return absl::DataLossError(absl::StrCat("store: scene \"", id,
                                                "\" cannot be converted: ",
                                                settings.status().message()));
      }
      put_scene.Text(1, id);
      put_scene.Blob(2, EncodeSettings(*settings));
      put_scene.Int(3, static_cast<uint64_t>(sqlite3_column_int64(scenes.get(), 2)));
      if (!put_scene.Run()) return SqliteError(db_, "converting a scene");
      sites.Text(1, id);
      while ((rc = sqlite3_step(sites.get())) == SQLITE_ROW) {
        auto site = legacy.site(ColumnBlob(sites.get(), 0));
        if (!site.ok()) {
          return absl::DataLossError(absl::StrCat("store: a site of scene \"", id,
                                                  "\" cannot be converted: ",
                                                  site.status().message()));
        }
        put_site.Text(1, id);
        put_site.Text(2, site->id);
        put_site.Blob(3, EncodeSite(*site));
        if (!put_site.Run()) return SqliteError(db_, "converting a site");
      }
      sqlite3_reset(sites.get());
      if (rc != SQLITE_DONE) return SqliteError(db_, "reading sites");
    }
    if (rc != SQLITE_DONE) return SqliteError(db_, "reading scenes");
    sqlite3_reset(scenes.get());
    if (auto s = Exec("DROP TABLE sites"); !s.ok()) return s;
    return Exec("DROP TABLE scenes");
  });
}

absl::StatusOr<std::vector<StoredScene>> SqliteStore::Load() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<StoredScene> scenes;
  Statement s(Prepared("SELECT id, settings, version, incarnation FROM scene ORDER BY id"));
  if (!s.ok()) return SqliteError(db_, "reading scenes");
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    auto settings = DecodeSettings(ColumnBlob(s.get(), 1));
    if (!settings.ok()) {
      return absl::DataLossError(absl::StrCat("store: scene \"", ColumnText(s.get(), 0),
                                              "\": ", settings.status().message()));
    }
    StoredScene scene;
    scene.settings = std::move(*settings);
    scene.version = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 2));
    scene.incarnation = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 3));
    scenes.push_back(std::move(scene));
  }
  if (rc != SQLITE_DONE) return SqliteError(db_, "reading scenes");
  for (StoredScene& scene : scenes) {
    absl::Status read = Latest(scene.settings.id, [&](std::string_view, uint64_t, std::string_view bytes) {
      if (IsTombstone(bytes)) return absl::OkStatus();
      return DecodeInto(scene.settings, bytes, &scene.sites);
    });
    if (!read.ok()) return read;
  }
  return scenes;
}

template <class Visit>
absl::Status SqliteStore::Latest(std::string_view scene_id, Visit visit) {
  // The scene's packs, oldest first, and the newest entry of each id in them.
  struct Pack {
    uint64_t version;
    std::string bytes;
    std::vector<PackEntry> entries;  // into bytes
  };
  std::vector<Pack> packs;
  {
    Statement p(Prepared("SELECT version, sites FROM site_pack WHERE scene = ? ORDER BY version"));
    if (!p.ok()) return SqliteError(db_, "reading packs");
    p.Text(1, scene_id);
    int rc;
    while ((rc = sqlite3_step(p.get())) == SQLITE_ROW) {
      packs.push_back({static_cast<uint64_t>(sqlite3_column_int64(p.get(), 0)),
                       std::string(ColumnBlob(p.get(), 1)), {}});
    }
    if (rc != SQLITE_DONE) return SqliteError(db_, "reading packs");
  }
  struct Entry {
    uint64_t version;
    std::string_view bytes;
  };
  std::unordered_map<std::string_view, Entry> newest;
  for (Pack& pack : packs) {  // the vector is whole: its strings no longer move
    auto entries = PackEntries(pack.bytes);
    if (!entries.ok()) return DamagedPack(scene_id, pack.version);
    pack.entries = std::move(*entries);
    for (const PackEntry& e : pack.entries) newest.insert_or_assign(e.id, Entry{pack.version, e.site});
  }
  Statement rows(Prepared("SELECT id, site, version FROM site WHERE scene = ?"));
  if (!rows.ok()) return SqliteError(db_, "reading sites");
  rows.Text(1, scene_id);
  int rc;
  while ((rc = sqlite3_step(rows.get())) == SQLITE_ROW) {
    const std::string_view id = ColumnBlob(rows.get(), 0);
    const std::string_view bytes = ColumnBlob(rows.get(), 1);
    const uint64_t version = static_cast<uint64_t>(sqlite3_column_int64(rows.get(), 2));
    if (auto it = newest.find(id); it != newest.end()) {
      // A pack's put is newer than a row of an older version, and than a put of its own
      // version (the pack's fold wrote it); a removal of its own version came after it.
      if (it->second.version > version || (it->second.version == version && !IsTombstone(bytes))) {
        continue;
      }
      newest.erase(it);
    }
    if (auto s = visit(id, version, bytes); !s.ok()) return s;
  }
  if (rc != SQLITE_DONE) return SqliteError(db_, "reading sites");
  // Then the packs' entries that no row overtook, in the packs' order.
  for (const Pack& pack : packs) {
    for (const PackEntry& e : pack.entries) {
      auto it = newest.find(e.id);
      if (it == newest.end() || it->second.bytes.data() != e.site.data()) continue;
      if (auto s = visit(e.id, pack.version, e.site); !s.ok()) return s;
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<uint64_t> SqliteStore::CreateScene(const SceneSettings& settings,
                                                   uint64_t version) {
  uint64_t incarnation = 0;
  absl::Status stored = Transaction([&]() -> absl::Status {
    static const std::string insert = absl::StrCat(
        "INSERT INTO scene (id, settings, version, incarnation, horizon) VALUES (?, ?, ?, ",
        kNewIncarnation, ", 0) RETURNING incarnation");
    Statement s(Prepared(insert.c_str()));
    if (!s.ok()) return SqliteError(db_, "storing the scene");
    s.Text(1, settings.id);
    s.Blob(2, EncodeSettings(settings));
    s.Int(3, version);
    if (sqlite3_step(s.get()) != SQLITE_ROW) {
      if (sqlite3_extended_errcode(db_) == SQLITE_CONSTRAINT_PRIMARYKEY) {
        return absl::AlreadyExistsError(
            absl::StrCat("scene \"", settings.id, "\" already exists"));
      }
      return SqliteError(db_, "storing the scene");
    }
    incarnation = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 0));
    if (sqlite3_step(s.get()) != SQLITE_DONE) return SqliteError(db_, "storing the scene");
    return absl::OkStatus();
  });
  if (!stored.ok()) return stored;
  return incarnation;
}

absl::Status SqliteStore::DeleteScene(std::string_view scene_id) {
  return Transaction([&] { return DeleteRows(scene_id); });
}

absl::Status SqliteStore::DeleteRows(std::string_view scene_id) {
  Statement sites(Prepared("DELETE FROM site WHERE scene = ?"));
  sites.Text(1, scene_id);
  if (!sites.ok() || !sites.Run()) return SqliteError(db_, "deleting the scene's sites");
  fold_cursor_.reset();
  Statement packs(Prepared("DELETE FROM site_pack WHERE scene = ?"));
  packs.Text(1, scene_id);
  if (!packs.ok() || !packs.Run()) return SqliteError(db_, "deleting the scene's packs");
  Statement s(Prepared("DELETE FROM scene WHERE id = ?"));
  s.Text(1, scene_id);
  if (!s.ok() || !s.Run()) return SqliteError(db_, "deleting the scene");
  return absl::OkStatus();
}

absl::Status SqliteStore::Commit(const ChangeSet& changes) {
  Waiter me{&changes};
  std::vector<Waiter*> group;
  {
    std::unique_lock<std::mutex> lock(group_mu_);
    waiting_.push_back(&me);
    group_cv_.wait(lock, [&] { return me.done || !committing_; });
    if (me.done) return me.status;  // a leader committed it
    committing_ = true;             // lead: take every waiter so far, this one included
    group.swap(waiting_);
  }
  // One sync change set makes the whole transaction sync.
  Durability durability = Durability::kRelaxed;
  for (const Waiter* w : group) {
    if (w->changes->durability == Durability::kSync) durability = Durability::kSync;
  }
  last_commit_ = std::chrono::steady_clock::now().time_since_epoch().count();
  absl::Status s = Transaction([&]() -> absl::Status {
    if (group.size() == 1) {  // its failure is the transaction's: no savepoint to roll back to
      group[0]->status = Write(*group[0]->changes);
      return group[0]->status;
    }
    for (Waiter* w : group) {
      if (auto st = Step("SAVEPOINT change_set"); !st.ok()) return st;
      w->status = Write(*w->changes);
      // A failed change set leaves nothing behind; the others go on.
      if (!w->status.ok()) {
        if (auto st = Step("ROLLBACK TO change_set"); !st.ok()) return st;
      }
      if (auto st = Step("RELEASE change_set"); !st.ok()) return st;
    }
    return absl::OkStatus();
  }, durability);
  last_commit_ = std::chrono::steady_clock::now().time_since_epoch().count();
  {
    std::lock_guard<std::mutex> lock(group_mu_);
    for (Waiter* w : group) {
      if (!s.ok()) w->status = s;  // nothing of the transaction is stored
      w->done = true;
    }
    committing_ = false;
    if (s.ok()) {
      ++group_stats_.transactions;
      for (Waiter* w : group) group_stats_.change_sets += w->status.ok();
    }
  }
  group_cv_.notify_all();
  return me.status;
}

SqliteStore::GroupStats SqliteStore::group_stats() const {
  std::lock_guard<std::mutex> lock(group_mu_);
  return group_stats_;
}

absl::Status SqliteStore::Write(const ChangeSet& changes) {
  Statement put(Prepared(
      "INSERT OR REPLACE INTO site (scene, id, site, version) VALUES (?, ?, ?, ?)"));
  // A tombstone is a row of its own: the site removed may live in a pack only.
  Statement del(Prepared(
      "INSERT INTO site (scene, id, site, version) VALUES (?, ?, x'', ?) "
      "ON CONFLICT (scene, id) DO UPDATE SET site = x'', version = excluded.version"));
  Statement version(Prepared(
      "UPDATE scene SET version = ? WHERE id = ? AND version = ? AND (? = 0 OR incarnation = ?)"));
  if (!put.ok() || !del.ok() || !version.ok()) return SqliteError(db_, "storing sites");
  // The conditional append: the scene moves from the version the change follows, or not.
  version.Int(1, changes.version);
  version.Text(2, changes.scene_id);
  version.Int(3, changes.base());
  version.Int(4, changes.incarnation);
  version.Int(5, changes.incarnation);
  if (!version.Run()) return SqliteError(db_, "storing the version");
  if (sqlite3_changes(db_) != 1) return Refused(changes);
  auto store = [&](const auto& site) {
    put.Text(1, changes.scene_id);
    put.Text(2, site.id);
    put.Blob(3, EncodeSite(site));
    put.Int(4, changes.version);
    return put.Run();
  };
  // The rows go in in id order: the B-tree then fills its pages one after another instead of
  // splitting pages all over the table (a bulk load of random ids commits in less than half
  // the time).
  auto store_all = [&](const auto& sites) {
    const std::vector<uint32_t> order =
        IdOrder(sites.size(), [&](size_t k) -> std::string_view { return sites[k]->id; });
    for (uint32_t k : order) {
      if (!store(*sites[k])) return false;
    }
    return true;
  };
  if (changes.put_count() >= packing_.min_sites) {
    // One row for all of them, appended: the folder makes them site rows later.
    Statement pack(Prepared("INSERT INTO site_pack (scene, version, sites) VALUES (?, ?, ?)"));
    if (!pack.ok()) return SqliteError(db_, "storing a pack");
    pack.Text(1, changes.scene_id);
    pack.Int(2, changes.version);
    pack.Blob(3, EncodePack(changes));
    if (!pack.Run()) return SqliteError(db_, "storing a pack");
    WantFold();
  } else if (!std::visit(store_all, changes.put)) {
    return SqliteError(db_, "storing a site");
  }
  for (const std::string& id : changes.removed) {
    del.Text(1, changes.scene_id);
    del.Text(2, id);
    del.Int(3, changes.version);
    if (!del.Run()) return SqliteError(db_, "deleting a site");
  }
  if (retention_.CompactsAt(changes.version)) {
    // A tombstone newer than a pack not yet folded stays: it hides the pack's put of its site.
    Statement drop(Prepared(
        "DELETE FROM site WHERE scene = ?1 AND site = x'' AND version <= ?2 AND version < "
        "coalesce((SELECT min(version) FROM site_pack WHERE scene = ?1), ?2 + 1)"));
    Statement horizon(Prepared("UPDATE scene SET horizon = ? WHERE id = ?"));
    drop.Text(1, changes.scene_id);
    drop.Int(2, retention_.HorizonAt(changes.version));
    horizon.Int(1, retention_.HorizonAt(changes.version));
    horizon.Text(2, changes.scene_id);
    if (!drop.ok() || !horizon.ok() || !drop.Run() || !horizon.Run()) {
      return SqliteError(db_, "dropping old tombstones");
    }
  }
  return absl::OkStatus();
}

absl::Status SqliteStore::Refused(const ChangeSet& changes) {
  Statement s(Prepared("SELECT version, incarnation FROM scene WHERE id = ?"));
  if (!s.ok()) return SqliteError(db_, "reading the version");
  s.Text(1, changes.scene_id);
  const int rc = sqlite3_step(s.get());
  if (rc == SQLITE_DONE) {
    return absl::NotFoundError(
        absl::StrCat("store: scene \"", std::string(changes.scene_id), "\" is not stored"));
  }
  if (rc != SQLITE_ROW) return SqliteError(db_, "reading the version");
  return StaleChange(changes, static_cast<uint64_t>(sqlite3_column_int64(s.get(), 0)),
                     static_cast<uint64_t>(sqlite3_column_int64(s.get(), 1)));
}

absl::StatusOr<std::vector<SceneHead>> SqliteStore::Heads() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<SceneHead> heads;
  Statement s(Prepared("SELECT id, incarnation, version FROM scene ORDER BY id"));
  if (!s.ok()) return SqliteError(db_, "reading scenes");
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    heads.push_back({ColumnText(s.get(), 0), static_cast<uint64_t>(sqlite3_column_int64(s.get(), 1)),
                     static_cast<uint64_t>(sqlite3_column_int64(s.get(), 2))});
  }
  if (rc != SQLITE_DONE) return SqliteError(db_, "reading scenes");
  return heads;
}

absl::StatusOr<SceneChanges> SqliteStore::ReadChanges(std::string_view scene_id, uint64_t after) {
  // One connection behind mu_: nothing commits between the two reads.
  std::lock_guard<std::mutex> lock(mu_);
  SceneChanges out;
  uint64_t horizon = 0;
  {
    Statement s(Prepared("SELECT settings, incarnation, version, horizon FROM scene WHERE id = ?"));
    if (!s.ok()) return SqliteError(db_, "reading the scene");
    s.Text(1, scene_id);
    const int rc = sqlite3_step(s.get());
    if (rc == SQLITE_DONE) {
      return absl::NotFoundError(
          absl::StrCat("store: scene \"", std::string(scene_id), "\" is not stored"));
    }
    if (rc != SQLITE_ROW) return SqliteError(db_, "reading the scene");
    auto settings = DecodeSettings(ColumnBlob(s.get(), 0));
    if (!settings.ok()) {
      return absl::DataLossError(absl::StrCat("store: scene \"", std::string(scene_id),
                                              "\": ", settings.status().message()));
    }
    out.settings = std::move(*settings);
    out.incarnation = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 1));
    out.version = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 2));
    horizon = static_cast<uint64_t>(sqlite3_column_int64(s.get(), 3));
  }
  out.complete = after == 0 || after < horizon;
  absl::Status read = Latest(scene_id, [&](std::string_view id, uint64_t version,
                                           std::string_view bytes) {
    if (!out.complete && version <= after) return absl::OkStatus();
    if (IsTombstone(bytes)) {
      if (!out.complete) out.removed.emplace_back(id);
      return absl::OkStatus();
    }
    return DecodeInto(out.settings, bytes, &out.put);
  });
  if (!read.ok()) return read;
  return out;
}

}  // namespace gvd
