// SceneStore on SQLite: one database file in WAL mode with synchronous=FULL, durable before
// each call returns (a relaxed commit: written before it returns, synced by a thread of the
// store's within set_relaxed_sync's period). Commits of change sets that arrive while another is being made durable
// share the next transaction (group commit: one fsync for all of them), each in a savepoint
// of its own, so that one that fails rolls back alone. Sites and settings are kept in the core's byte
// form (render/scene/codec.h), so every site kind the core gains is stored without a schema change.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/codec.h"
#include "server/store/store.h"
#include "server/store/rows.h"

struct sqlite3;
struct sqlite3_stmt;

namespace gvd {

// Thread-safe: one connection writes, behind a mutex (SQLite has one writer at a time
// anyway); a persistent store's folder reads packs, and its checkpointer copies the WAL into
// the database, each on a connection of its own.
class SqliteStore final : public SceneStore {
 public:
  // Reads the records of an earlier schema, which kept each scene's CreateSceneRequest and
  // each site's Site message: given to Open by the one who knows those messages (the server)
  // so that a database written by an earlier release is converted once, in one transaction.
  struct Legacy {
    std::function<absl::StatusOr<SceneSettings>(std::string_view request)> scene;
    std::function<absl::StatusOr<Site>(std::string_view site)> site;
  };

  // Opens (creating if needed) DIR/gvd.sqlite3. ":memory:" keeps nothing across restarts.
  // A database of the earlier schema is converted with `legacy`, or refused without it.
  static absl::StatusOr<std::unique_ptr<SqliteStore>> Open(const std::string& dir,
                                                           const Legacy& legacy = {});
  ~SqliteStore() override;  // closes the database cleanly (checkpointing the WAL)
  SqliteStore(const SqliteStore&) = delete;
  SqliteStore& operator=(const SqliteStore&) = delete;

  absl::StatusOr<std::vector<StoredScene>> Load() override;
  absl::StatusOr<uint64_t> CreateScene(const SceneSettings& settings, uint64_t version) override;
  absl::Status Commit(const ChangeSet& changes) override;
  absl::Status DeleteScene(std::string_view scene_id) override;
  absl::StatusOr<std::vector<SceneHead>> Heads() override;
  absl::StatusOr<SceneChanges> ReadChanges(std::string_view scene_id, uint64_t after) override;
  std::string Describe() const override { return path_; }
  // How much history is kept (rows.h); set before the store is shared.
  void set_retention(Retention retention) { retention_ = retention; }

  // Large change sets: one of at least `min_sites` puts is written as one row (a pack, one
  // sequential append) rather than a row per site, and a thread of the store's folds the
  // packs into site rows, `fold_chunk` sites a transaction, once no pack has been written for
  // `fold_after`; each chunk waits until no commit has begun for `fold_idle`, or
  // `fold_max_wait` after the previous chunk while commits keep coming. Set before the store
  // is shared.
  struct Packing {
    size_t min_sites = 4096;
    std::chrono::milliseconds fold_after{500};
    size_t fold_chunk = 256;
    std::chrono::milliseconds fold_idle{5};
    std::chrono::milliseconds fold_max_wait{100};
  };
  void set_packing(Packing packing);
  // Folds packs now, in at most `chunks` transactions (of fold_chunk sites each), and returns
  // how many sites it folded.
  absl::StatusOr<uint64_t> FoldPacks(uint64_t chunks = UINT64_MAX);

  // How long a relaxed commit may stay unsynced (it survives a crash of the server at once,
  // a crash of the machine once synced). 100 ms unless set.
  void set_relaxed_sync(std::chrono::milliseconds period);
  // Relaxed transactions committed and not known synced (after a failed sync of the WAL,
  // those it held stay counted).
  uint64_t relaxed_unsynced() const;
  // The WAL syncs the flusher made.
  uint64_t flusher_syncs() const;
  // The checkpoints of the WAL into the database that the checkpointer made.
  uint64_t checkpoints() const;

  // Seconds the last transaction took (BEGIN to durable COMMIT).
  double last_commit_seconds() const;
  // Transactions that committed change sets, and the change sets they committed.
  struct GroupStats {
    uint64_t transactions = 0;
    uint64_t change_sets = 0;
  };
  GroupStats group_stats() const;

 private:
  SqliteStore(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}
  absl::Status Exec(const char* sql);
  // The statement prepared once for the connection's life (null if it cannot be prepared).
  // CONTRACT: mu_ held, or the store not yet shared.
  sqlite3_stmt* Prepared(const char* sql);
  // Runs a cached statement that takes no parameters and returns no rows.
  absl::Status Step(const char* sql);
  absl::Status Migrate(const Legacy& legacy);
  // Runs `body` inside BEGIN IMMEDIATE ... COMMIT, rolling back if it fails; a relaxed one
  // commits without syncing, and the flusher syncs it.
  template <class Body>
  absl::Status Transaction(Body body, Durability durability = Durability::kSync);
  // Syncs the relaxed commits at most relaxed_sync_ after the first of them unsynced.
  void Flusher();
  // fdatasync of the WAL file.
  absl::Status SyncWal();
  // One change set's writes, inside the open transaction. CONTRACT: mu_ held.
  absl::Status Write(const ChangeSet& changes);
  // Why a change set's conditional update matched no scene: NOT_FOUND or ABORTED.
  // CONTRACT: mu_ held.
  absl::Status Refused(const ChangeSet& changes);
  // Deletes a scene's rows. CONTRACT: mu_ held, in a transaction.
  absl::Status DeleteRows(std::string_view scene_id);
  // Calls visit(id, version, bytes) for each site of the scene that has a row or a pack
  // entry, once, with the newest of them (bytes empty: a tombstone). CONTRACT: mu_ held.
  template <class Visit>
  absl::Status Latest(std::string_view scene_id, Visit visit);
  // Folds the next fold_chunk sites of a pack into site rows, in one transaction; false when
  // no pack was left. Returns through `folded` how many it folded.
  absl::StatusOr<bool> FoldSome(uint64_t* folded);
  // The oldest pack's fold_cursor_, read and ordered; OK with nothing done when there is no
  // pack or the cursor is that pack's already. A persistent store reads the pack on the
  // folder's connection, outside mu_; one in memory, under mu_.
  absl::Status PrepareFold();
  // PrepareFold on a thread at kFoldNice, unless the oldest pack's cursor is ready (the
  // folder's, before each chunk).
  absl::Status PrepareFoldBelowCalls();
  struct PackHead {
    uint64_t id = 0;
    std::string scene;
    uint64_t version = 0;  // the version that wrote it
  };
  // The oldest pack's, or none. CONTRACT: mu_ held.
  absl::StatusOr<std::optional<PackHead>> OldestPack();
  // The oldest pack, unless there is none or fold_cursor_ is its already. CONTRACT: mu_ held.
  absl::StatusOr<std::optional<PackHead>> PackToPrepare();
  // Tells the folder a pack was written (or found at the start).
  void WantFold();
  // Folds packs once they have rested fold_after; at the priority of the thread that made it
  // (the first call that wrote a pack, or the start that found one), since its chunks hold
  // mu_.
  void Folder();
  // Tells the checkpointer the WAL holds kCheckpointPages or more (the WAL hook's, after a
  // commit). CONTRACT: mu_ held.
  void WantCheckpoint();
  // Copies the WAL into the database whenever told, on a connection of its own.
  void Checkpointer();

  // Group commit: the change sets waiting for the next transaction, and whether one is under
  // way (its leader commits every waiter it took).
  struct Waiter {
    const ChangeSet* changes;
    absl::Status status;
    bool done = false;
  };
  mutable std::mutex group_mu_;
  std::condition_variable group_cv_;
  std::vector<Waiter*> waiting_;
  bool committing_ = false;
  GroupStats group_stats_;

  mutable std::mutex mu_;
  sqlite3* db_;
  std::string path_;
  std::unordered_map<std::string, sqlite3_stmt*> statements_;  // by SQL text
  double last_commit_seconds_ = 0;
  Retention retention_;
  bool relaxed_connection_ = false;  // the connection's synchronous=NORMAL. Guarded by mu_.

  // Relaxed commits: counts of those committed and of those known synced, when the first
  // unsynced one committed, and the thread that syncs them (started by the first).
  mutable std::mutex flush_mu_;
  std::condition_variable flush_cv_;
  uint64_t relaxed_written_ = 0;
  uint64_t relaxed_synced_ = 0;
  std::chrono::steady_clock::time_point oldest_unsynced_;
  std::chrono::milliseconds relaxed_sync_{100};
  uint64_t flusher_syncs_ = 0;
  bool stopping_ = false;
  std::thread flusher_;
  std::string wal_path_;  // the WAL's file; empty in memory
  int wal_fd_ = -1;       // the flusher's descriptor of it, once opened
  std::atomic<bool> sync_failed_{false};  // a sync of the WAL failed: no more relaxed commits

  // The pack being folded (by its row's id, never reused), parsed and put in id order once
  // for all its chunks. Guarded by mu_; dropped when a chunk's transaction fails.
  struct FoldCursor {
    uint64_t id = 0;
    std::string pack;
    std::vector<PackEntry> entries;  // into pack
    std::vector<uint32_t> order;  // of entries, by id
    uint64_t done = 0;            // entries of `order` folded, in transactions committed
  };
  std::unique_ptr<FoldCursor> fold_cursor_;
  // The folder's read-only connection to a persistent store, opened by its first fold: a
  // large load's pack is megabytes, whose reading would hold every commit up under mu_, and
  // in WAL mode a reader does not hold up the writer. Guarded by fold_read_mu_.
  std::mutex fold_read_mu_;
  sqlite3* fold_reader_ = nullptr;

  // The folder: whether a pack may wait, since when, and its thread (started by the first).
  Packing packing_;  // guarded by mu_ and fold_mu_ (either, to read)
  std::mutex fold_mu_;
  std::condition_variable fold_cv_;
  bool fold_wanted_ = false;
  bool fold_stopping_ = false;
  std::chrono::steady_clock::time_point last_pack_;     // the last pack written
  std::chrono::steady_clock::time_point wanted_since_;  // the first not yet folded
  std::chrono::steady_clock::time_point fold_retry_at_;  // after a failed fold
  // When the last commit of change sets began or ended (steady_clock ticks): the folder goes
  // between. Its end too: a commit that waited for a chunk would otherwise let the next
  // chunk start as soon as it ends.
  std::atomic<std::chrono::steady_clock::rep> last_commit_{0};
  std::chrono::milliseconds fold_backoff_{1000};
  std::thread folder_;

  // The checkpointer (a persistent store's): SQLite's own checkpoint runs in the commit that
  // leaves the WAL at 1,000 pages, under mu_, and copying them into the database took that
  // commit 26-66 ms. Its thread copies them beside the writer instead (a PASSIVE checkpoint,
  // on its own connection), started by the first commit that wants it; the writer's
  // connection checkpoints itself only if the checkpointer could not open one.
  mutable std::mutex ckpt_mu_;
  std::condition_variable ckpt_cv_;
  bool ckpt_wanted_ = false;
  bool ckpt_stopping_ = false;
  uint64_t checkpoints_ = 0;
  std::atomic<bool> ckpt_failed_{false};  // its connection could not be opened
  std::thread checkpointer_;
};

}  // namespace gvd
