#include "server/store/postgres_store.h"

#include <endian.h>
#include <libpq-fe.h>
#include <poll.h>

#include <algorithm>
#include <cstring>
#include <utility>

#include "absl/strings/str_cat.h"
#include "render/scene/codec.h"
#include "server/store/digest.h"

namespace gvd {
namespace {

// Type OIDs of the parameters sent (pg_type.h).
constexpr Oid kInt8 = 20, kText = 25, kBytea = 17, kByteaArray = 1001;

// The schema's version, kept in gvd_schema: a database written by a newer release is left
// as it is. 2: scenes keep the digest of their sites (server/store/digest.h).
constexpr int kSchemaVersion = 2;
constexpr const char* kSchema[] = {
    "SELECT pg_advisory_xact_lock(7262541730)",
    "CREATE TABLE IF NOT EXISTS gvd_schema (version integer NOT NULL)",
    "INSERT INTO gvd_schema SELECT 1 WHERE NOT EXISTS (SELECT 1 FROM gvd_schema)",
    "CREATE SEQUENCE IF NOT EXISTS gvd_incarnation",
    "CREATE TABLE IF NOT EXISTS gvd_scene ("
    "  id text COLLATE \"C\" PRIMARY KEY,"
    "  settings bytea NOT NULL,"
    "  version bigint NOT NULL,"
    "  incarnation bigint NOT NULL DEFAULT nextval('gvd_incarnation'),"
    "  horizon bigint NOT NULL DEFAULT 0)",
    "CREATE TABLE IF NOT EXISTS gvd_site ("
    "  scene text COLLATE \"C\" NOT NULL,"
    "  id bytea NOT NULL,"
    "  version bigint NOT NULL,"
    "  site bytea NOT NULL,"  // empty: a tombstone
    "  PRIMARY KEY (scene, id))",
    "CREATE INDEX IF NOT EXISTS gvd_site_version ON gvd_site (scene, version)",
};
// What takes a database of version 1 (as kSchema makes it) to version 2: each scene's
// digest, computed from its rows.
const std::string kToVersion2[] = {
    "ALTER TABLE gvd_scene ADD COLUMN digest bigint",
    absl::StrCat("UPDATE gvd_scene s SET digest = (SELECT coalesce(bit_xor(", kSqlSiteDigest,
                 "), 0) FROM gvd_site t WHERE t.scene = s.id AND t.site <> ''::bytea)"),
    "UPDATE gvd_schema SET version = 2",
};

// One parameter, sent in binary (or SQL's NULL).
struct Param {
  Oid type;
  std::string bytes;
  bool null = false;
};
Param Int8(uint64_t v) {
  const uint64_t be = htobe64(v);
  return {kInt8, std::string(reinterpret_cast<const char*>(&be), 8)};
}
Param Int8(std::optional<uint64_t> v) { return v ? Int8(*v) : Param{kInt8, "", true}; }
Param Text(std::string_view s) { return {kText, std::string(s)}; }
Param Bytea(std::string_view s) { return {kBytea, std::string(s)}; }
// A one-dimensional bytea[] in PostgreSQL's binary array form.
Param ByteaArray(const std::vector<std::string_view>& items) {
  std::string out;
  auto i32 = [&](uint32_t v) {
    const uint32_t be = htobe32(v);
    out.append(reinterpret_cast<const char*>(&be), 4);
  };
  i32(items.empty() ? 0 : 1);  // dimensions
  i32(0);                      // no nulls
  i32(kBytea);
  if (!items.empty()) {
    i32(static_cast<uint32_t>(items.size()));
    i32(1);  // lower bound
  }
  for (std::string_view item : items) {
    i32(static_cast<uint32_t>(item.size()));
    out.append(item);
  }
  return {kByteaArray, std::move(out)};
}

// A result, cleared when it goes.
class Result {
 public:
  explicit Result(PGresult* r = nullptr) : r_(r) {}
  ~Result() { PQclear(r_); }
  Result(Result&& o) noexcept : r_(std::exchange(o.r_, nullptr)) {}
  Result& operator=(Result&& o) noexcept {
    std::swap(r_, o.r_);
    return *this;
  }
  int rows() const { return PQntuples(r_); }
  std::string_view bytes(int row, int col) const {
    return std::string_view(PQgetvalue(r_, row, col), PQgetlength(r_, row, col));
  }
  bool null(int row, int col) const { return PQgetisnull(r_, row, col); }
  std::optional<uint64_t> nullable_int8(int row, int col) const {
    if (null(row, col)) return std::nullopt;
    return int8(row, col);
  }
  uint64_t int8(int row, int col) const {
    uint64_t be;
    std::memcpy(&be, PQgetvalue(r_, row, col), 8);
    return be64toh(be);
  }

 private:
  PGresult* r_;
};

}  // namespace

// A connection with calls bound by a deadline (libpq's asynchronous calls and poll).
class PostgresStore::Connection {
 public:
  explicit Connection(PGconn* c) : c_(c) {}
  ~Connection() { PQfinish(c_); }
  PGconn* get() { return c_; }
  bool broken() const { return broken_ || PQstatus(c_) != CONNECTION_OK; }
  // Whether an idle connection is still open: reads what the server sent meanwhile (a
  // server that shut down or restarted has closed it, saying so), without waiting.
  bool Alive() {
    if (broken()) return false;
    if (!PQconsumeInput(c_)) broken_ = true;
    while (PGnotify* n = PQnotifies(c_)) PQfreemem(n);
    // A server that shut down sends its reason and closes: the reason may be read before the
    // close is seen.
    pollfd p{PQsocket(c_), POLLRDHUP, 0};
    if (poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR))) broken_ = true;
    return !broken();
  }

  // Runs one statement and returns its result; the
  // error as a status naming `what`. The connection is broken after a failure to talk.
  absl::StatusOr<Result> Run(const char* sql, const std::vector<Param>& params,
                             std::chrono::milliseconds deadline, std::string_view what) {
    const auto until = std::chrono::steady_clock::now() + deadline;
    std::vector<Oid> types;
    std::vector<const char*> values;
    std::vector<int> lengths, formats;
    for (const Param& p : params) {
      types.push_back(p.type);
      values.push_back(p.null ? nullptr : p.bytes.data());
      lengths.push_back(static_cast<int>(p.bytes.size()));
      formats.push_back(1);
    }
    // Results in binary: integers and bytes come as they are.
    const int sent = PQsendQueryParams(c_, sql, static_cast<int>(params.size()), types.data(),
                                       values.data(), lengths.data(), formats.data(), 1);
    if (!sent) return Lost(what);
    // Sends what is buffered, then reads until the results are in.
    for (;;) {
      const int f = PQflush(c_);
      if (f < 0) return Lost(what);
      if (f == 0) break;
      if (!Wait(POLLOUT | POLLIN, until)) return Late(what);
      if (!PQconsumeInput(c_)) return Lost(what);
    }
    Result last;
    absl::Status error;
    for (;;) {
      while (PQisBusy(c_)) {
        if (!Wait(POLLIN, until)) return Late(what);
        if (!PQconsumeInput(c_)) return Lost(what);
      }
      PGresult* r = PQgetResult(c_);
      if (r == nullptr) break;
      const ExecStatusType st = PQresultStatus(r);
      if ((st == PGRES_FATAL_ERROR || st == PGRES_NONFATAL_ERROR) && error.ok()) {
        error = Error(r, what);
      }
      last = Result(r);
    }
    if (!error.ok()) return error;
    return last;
  }

 private:
  // Waits until the socket is ready for `events`; false past `until`.
  bool Wait(short events, std::chrono::steady_clock::time_point until) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        until - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{PQsocket(c_), events, 0};
    return poll(&p, 1, static_cast<int>(left.count())) > 0;
  }
  absl::Status Lost(std::string_view what) {
    broken_ = true;
    return absl::UnavailableError(
        absl::StrCat("store: ", std::string(what), ": the connection to PostgreSQL failed: ",
                     PQerrorMessage(c_)));
  }
  absl::Status Late(std::string_view what) {
    broken_ = true;  // the statement may still run: the connection is not used again
    return absl::UnavailableError(absl::StrCat(
        "store: ", std::string(what), ": PostgreSQL did not answer in time (the call may or "
        "may not have taken effect; a read of the scene tells)"));
  }
  // A statement's error by what it means for a caller.
  absl::Status Error(PGresult* r, std::string_view what) {
    const char* state = PQresultErrorField(r, PG_DIAG_SQLSTATE);
    const std::string code = state ? state : "";
    const std::string text = absl::StrCat("store: ", std::string(what), ": ",
                                          PQresultErrorMessage(r));
    if (code == "23505") return absl::AlreadyExistsError(text);
    if (code == "40001" || code == "40P01") return absl::AbortedError(text);
    if (code.rfind("53", 0) == 0) return absl::ResourceExhaustedError(text);
    // Connection trouble, a server shutting down, or a standby that cannot take writes.
    if (code.rfind("08", 0) == 0 || code.rfind("57", 0) == 0 || code == "25006" || code.empty()) {
      broken_ = true;
      return absl::UnavailableError(text);
    }
    return absl::InternalError(text);
  }

  PGconn* c_;
  bool broken_ = false;
};

// A connection taken from the pool, given back (or dropped, when broken) when it goes.
class PostgresStore::Lease {
 public:
  Lease(PostgresStore* store, std::unique_ptr<Connection> c) : store_(store), c_(std::move(c)) {}
  Lease(Lease&&) = default;
  ~Lease() {
    if (c_) store_->Return(std::move(c_));
  }
  Connection* operator->() { return c_.get(); }

 private:
  PostgresStore* store_;
  std::unique_ptr<Connection> c_;
};

namespace {

// Connects with the store's defaults, which the URL's own settings override.
absl::StatusOr<PGconn*> Connect(const std::string& url) {
  const char* keys[] = {"connect_timeout", "keepalives", "keepalives_idle",
                        "keepalives_interval", "keepalives_count", "tcp_user_timeout",
                        "application_name", "options", "dbname", nullptr};
  const char* values[] = {"3", "1", "5", "2", "2", "5000", "gvd-server",
                          "-c synchronous_commit=on -c client_min_messages=warning",
                          url.c_str(), nullptr};
  PGconn* c = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
  if (c == nullptr) return absl::ResourceExhaustedError("store: out of memory connecting");
  if (PQstatus(c) != CONNECTION_OK) {
    absl::Status s = absl::UnavailableError(
        absl::StrCat("store: cannot connect to PostgreSQL: ", PQerrorMessage(c)));
    PQfinish(c);
    return s;
  }
  return c;
}

}  // namespace

PostgresStore::PostgresStore(std::string url, Options options)
    : url_(std::move(url)), options_(options) {}

PostgresStore::~PostgresStore() = default;

absl::StatusOr<std::unique_ptr<PostgresStore>> PostgresStore::Open(const std::string& url,
                                                                   Options options) {
  std::unique_ptr<PostgresStore> store(new PostgresStore(url, options));
  auto c = Connect(url);
  if (!c.ok()) return c.status();
  auto connection = std::make_unique<Connection>(*c);
  store->name_ = absl::StrCat("postgresql://", PQuser(*c), "@", PQhost(*c), ":", PQport(*c), "/",
                              PQdb(*c));
  absl::StatusOr<Result> version;
  ++store->open_;
  {
    Lease lease(store.get(), std::move(connection));
    absl::Status schema = store->InTransaction(lease, "", [&]() -> absl::Status {
      for (const char* sql : kSchema) {
        if (auto r = lease->Run(sql, {}, options.deadline, "making tables"); !r.ok()) {
          return r.status();
        }
      }
      version = lease->Run("SELECT max(version)::int8 FROM gvd_schema", {}, options.deadline,
                           "reading the schema version");
      if (!version.ok() || version->int8(0, 0) >= 2) return version.status();
      for (const std::string& sql : kToVersion2) {
        if (auto r = lease->Run(sql.c_str(), {}, options.deadline, "updating the tables");
            !r.ok()) {
          return r.status();
        }
      }
      return absl::OkStatus();
    });
    if (!schema.ok()) return schema;
  }
  if (version->int8(0, 0) > uint64_t{kSchemaVersion}) {
    return absl::FailedPreconditionError(absl::StrCat(
        "store ", store->name_, " was written by a newer release of gvd (schema version ",
        version->int8(0, 0), "; this release reads up to ", kSchemaVersion, ")"));
  }
  return store;
}

absl::StatusOr<PostgresStore::Lease> PostgresStore::Take() {
  {
    std::unique_lock<std::mutex> lock(mu_);
    if (!idle_cv_.wait_for(lock, options_.deadline,
                           [&] { return !idle_.empty() || open_ < options_.connections; })) {
      return absl::UnavailableError(absl::StrCat(
          "store: all ", options_.connections, " connections to PostgreSQL stayed busy for ",
          options_.deadline.count(), " ms"));
    }
    // Idle connections the database closed (it restarted, or failed over) are dropped here
    // rather than failing the call that takes them.
    while (!idle_.empty()) {
      std::unique_ptr<Connection> c = std::move(idle_.back());
      idle_.pop_back();
      if (c->Alive()) return Lease(this, std::move(c));
      --open_;
    }
    ++open_;
  }
  auto c = Connect(url_);
  if (!c.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    --open_;
    idle_cv_.notify_one();
    return c.status();
  }
  return Lease(this, std::make_unique<Connection>(*c));
}

void PostgresStore::Return(std::unique_ptr<Connection> connection) {
  std::lock_guard<std::mutex> lock(mu_);
  if (connection->broken()) {
    --open_;
  } else {
    idle_.push_back(std::move(connection));
  }
  idle_cv_.notify_one();
}

absl::StatusOr<std::vector<StoredScene>> PostgresStore::Load() {
  auto c = Take();
  if (!c.ok()) return c.status();
  // One snapshot for both reads.
  absl::StatusOr<Result> scenes, sites;
  absl::Status read = InTransaction(*c, "ISOLATION LEVEL REPEATABLE READ READ ONLY", [&] {
    scenes = (*c)->Run("SELECT id, settings, version, incarnation FROM gvd_scene ORDER BY id",
                       {}, options_.deadline, "loading scenes");
    if (!scenes.ok()) return scenes.status();
    sites = (*c)->Run(
        "SELECT scene, site FROM gvd_site WHERE site <> ''::bytea ORDER BY scene", {},
        options_.deadline, "loading sites");
    return sites.status();
  });
  if (!read.ok()) return read;
  std::vector<StoredScene> out;
  for (int i = 0; i < scenes->rows(); ++i) {
    auto settings = DecodeSettings(scenes->bytes(i, 1));
    if (!settings.ok()) {
      return absl::DataLossError(absl::StrCat("store: scene \"", std::string(scenes->bytes(i, 0)),
                                              "\": ", settings.status().message()));
    }
    out.push_back({std::move(*settings), scenes->int8(i, 2), scenes->int8(i, 3)});
  }
  // Sites come in scene order, as the scenes do.
  size_t k = 0;
  for (int i = 0; i < sites->rows(); ++i) {
    const std::string_view scene = sites->bytes(i, 0);
    while (k < out.size() && out[k].settings.id < scene) ++k;
    if (k == out.size() || out[k].settings.id != scene) continue;  // a scene being deleted
    if (auto s = DecodeInto(out[k].settings, sites->bytes(i, 1), &out[k].sites);
        !s.ok()) {
      return s;
    }
  }
  return out;
}

absl::StatusOr<uint64_t> PostgresStore::CreateScene(const SceneSettings& settings,
                                                    uint64_t version) {
  auto c = Take();
  if (!c.ok()) return c.status();
  auto r = (*c)->Run(
      "WITH made AS (INSERT INTO gvd_scene (id, settings, version, digest) VALUES ($1, $2, $3, 0) "
      "RETURNING incarnation) SELECT incarnation, pg_notify('gvd_changes', $1) FROM made",
      {Text(settings.id), Bytea(EncodeSettings(settings)), Int8(version)}, options_.deadline,
      absl::StrCat("storing scene \"", settings.id, "\""));
  if (r.status().code() == absl::StatusCode::kAlreadyExists) {
    return absl::AlreadyExistsError(absl::StrCat("scene \"", settings.id, "\" already exists"));
  }
  if (!r.ok()) return r.status();
  return r->int8(0, 0);
}

absl::Status PostgresStore::DeleteScene(std::string_view scene_id) {
  auto c = Take();
  if (!c.ok()) return c.status();
  // The scene's row goes first, under its lock: a commit under way finishes before, one
  // after finds no scene, so the second statement (a fresh snapshot) sees every site row.
  const std::vector<Param> id = {Text(scene_id)};
  return InTransaction(*c, "", [&]() -> absl::Status {
    for (const char* sql : {"DELETE FROM gvd_scene WHERE id = $1",
                            "DELETE FROM gvd_site WHERE scene = $1",
                            "SELECT pg_notify('gvd_changes', $1)"}) {
      if (auto r = (*c)->Run(sql, id, options_.deadline, "deleting a scene"); !r.ok()) {
        return r.status();
      }
    }
    return absl::OkStatus();
  });
}

template <class Body>
absl::Status PostgresStore::InTransaction(Lease& c, const char* mode, Body body) {
  if (auto r = c->Run(absl::StrCat("BEGIN ", mode).c_str(), {}, options_.deadline, "beginning");
      !r.ok()) {
    return r.status();
  }
  absl::Status s = body();
  if (s.ok()) {
    auto r = c->Run("COMMIT", {}, options_.deadline, "committing");
    s = r.status();
  }
  if (!s.ok() && !c->broken()) {
    // Leaves the connection fit for the next call (or broken, and dropped).
    (void)c->Run("ROLLBACK", {}, options_.deadline, "rolling back");
  }
  return s;
}

absl::Status PostgresStore::Commit(const ChangeSet& changes) {
  std::vector<std::string> encoded;
  std::vector<std::string_view> put_ids, put_sites, removed;
  encoded.reserve(changes.put_count());
  uint64_t put_digest = 0;  // of the sites put; the database takes out those they replace
  std::visit([&](const auto& sites) {
    for (const auto& site : sites) {
      encoded.push_back(EncodeSite(*site));
      put_digest ^= SiteDigest(encoded.back());
      put_ids.push_back(site->id);
    }
  }, changes.put);
  for (const std::string& bytes : encoded) put_sites.push_back(bytes);
  for (const std::string& id : changes.removed) removed.push_back(id);
  const std::string scene(changes.scene_id);
  auto c = Take();
  if (!c.ok()) return c.status();
  // The conditional append, in one statement: the scene moves from the version the change
  // follows, and only then are its rows written and the followers told. A relaxed change is
  // committed as a sync one (the database's synchronous_commit): replicas apply a commit as
  // soon as they are told of it, and one the database then lost (a relaxed commit, at a crash
  // of the database) would leave them ahead of it. The scene's digest moves by the sites put
  // and the live rows they replace or remove, as they were before the statement.
  static const std::string sql = absl::StrCat(
      "WITH head AS (UPDATE gvd_scene SET version = $2, digest = digest # $8 # "
      "  (SELECT coalesce(bit_xor(", kSqlSiteDigest, "), 0) FROM gvd_site "
      "   WHERE scene = $1 AND site <> ''::bytea AND (id = ANY($4::bytea[]) OR id = ANY($6::bytea[]))) "
      "  WHERE id = $1 AND version = $3 AND ($7 = 0 OR incarnation = $7) "
      "  AND ($9::int8 IS NULL OR digest = $9) RETURNING id), "
      "put AS (INSERT INTO gvd_site (scene, id, version, site) "
      "  SELECT head.id, p.id, $2, p.site FROM head, unnest($4::bytea[], $5::bytea[]) AS p(id, site) "
      "  ON CONFLICT (scene, id) DO UPDATE SET version = EXCLUDED.version, site = EXCLUDED.site), "
      "gone AS (UPDATE gvd_site SET version = $2, site = ''::bytea "
      "  WHERE scene = (SELECT id FROM head) AND id = ANY($6::bytea[])) "
      "SELECT pg_notify('gvd_changes', id) FROM head");
  auto r = (*c)->Run(
      sql.c_str(),
      {Text(scene), Int8(changes.version), Int8(changes.base()), ByteaArray(put_ids),
       ByteaArray(put_sites), ByteaArray(removed), Int8(changes.incarnation), Int8(put_digest),
       Int8(changes.base_digest)},
      options_.deadline, absl::StrCat("committing to scene \"", scene, "\""));
  if (!r.ok()) return r.status();
  if (r->rows() == 0) {
    auto head = (*c)->Run("SELECT version, incarnation, digest FROM gvd_scene WHERE id = $1",
                          {Text(scene)}, options_.deadline, "reading a scene's version");
    if (!head.ok()) return head.status();
    if (head->rows() == 0) {
      return absl::NotFoundError(absl::StrCat("store: scene \"", scene, "\" is not stored"));
    }
    return StaleChange(changes, head->int8(0, 0), head->int8(0, 1), head->nullable_int8(0, 2));
  }
  if (options_.retention.CompactsAt(changes.version)) {
    // Old tombstones and the horizon move together, in one statement.
    auto compacted = (*c)->Run(
        "WITH dropped AS (DELETE FROM gvd_site WHERE scene = $1 AND site = ''::bytea "
        "AND version <= $2) UPDATE gvd_scene SET horizon = greatest(horizon, $2) WHERE id = $1",
        {Text(scene), Int8(options_.retention.HorizonAt(changes.version))}, options_.deadline,
        "dropping old tombstones");
    // The change is committed: a compaction that failed is done by a later one.
    (void)compacted;
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<SceneHead>> PostgresStore::Heads() {
  auto c = Take();
  if (!c.ok()) return c.status();
  auto r = (*c)->Run("SELECT id, incarnation, version, digest FROM gvd_scene ORDER BY id", {},
                     options_.deadline, "reading scenes' heads");
  if (!r.ok()) return r.status();
  std::vector<SceneHead> heads;
  heads.reserve(r->rows());
  for (int i = 0; i < r->rows(); ++i) {
    heads.push_back(
        {std::string(r->bytes(i, 0)), r->int8(i, 1), r->int8(i, 2), r->nullable_int8(i, 3)});
  }
  return heads;
}

absl::StatusOr<SceneChanges> PostgresStore::ReadChanges(std::string_view scene_id,
                                                        uint64_t after) {
  auto c = Take();
  if (!c.ok()) return c.status();
  // One statement, one snapshot: the scene's head and the rows written after `after` (all
  // of them when its tombstones from after `after` may be gone).
  auto r = (*c)->Run(
      "SELECT s.settings, s.incarnation, s.version, s.horizon, t.id, t.site, s.digest "
      "FROM gvd_scene s LEFT JOIN gvd_site t ON t.scene = s.id "
      "  AND (t.version > $2 OR s.horizon > $2 OR $2 = 0) "
      "WHERE s.id = $1",
      {Text(scene_id), Int8(after)}, options_.deadline, "reading a scene's changes");
  if (!r.ok()) return r.status();
  if (r->rows() == 0) {
    return absl::NotFoundError(
        absl::StrCat("store: scene \"", std::string(scene_id), "\" is not stored"));
  }
  SceneChanges out;
  auto settings = DecodeSettings(r->bytes(0, 0));
  if (!settings.ok()) {
    return absl::DataLossError(absl::StrCat("store: scene \"", std::string(scene_id), "\": ",
                                            settings.status().message()));
  }
  out.settings = std::move(*settings);
  out.incarnation = r->int8(0, 1);
  out.version = r->int8(0, 2);
  out.digest = r->nullable_int8(0, 6);
  out.complete = after == 0 || after < r->int8(0, 3);
  for (int i = 0; i < r->rows(); ++i) {
    if (r->null(i, 4)) continue;  // no rows joined
    const std::string_view bytes = r->bytes(i, 5);
    if (IsTombstone(bytes)) {
      if (!out.complete) out.removed.emplace_back(r->bytes(i, 4));
      continue;
    }
    if (auto s = DecodeInto(out.settings, bytes, &out.put); !s.ok()) return s;
  }
  return out;
}

bool PostgresStore::WaitForChanges(int timeout_ms) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  auto sleep = [&] {
    std::this_thread::sleep_until(until);
    return false;
  };
  if (listener_ == nullptr || listener_->broken()) {
    listener_.reset();
    auto c = Connect(url_);
    if (!c.ok()) return sleep();
    auto connection = std::make_unique<Connection>(*c);
    if (!connection->Run("LISTEN gvd_changes", {}, options_.deadline, "listening").ok()) {
      return sleep();
    }
    listener_ = std::move(connection);
    // Commits before LISTEN took effect were not announced: the caller reads the heads.
    return true;
  }
  PGconn* c = listener_->get();
  bool told = false;
  auto drain = [&] {
    while (PGnotify* n = PQnotifies(c)) {
      told = true;
      PQfreemem(n);
    }
  };
  drain();
  if (told) return true;
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      until - std::chrono::steady_clock::now());
  pollfd p{PQsocket(c), POLLIN, 0};
  if (left.count() > 0 && poll(&p, 1, static_cast<int>(left.count())) > 0) {
    if (!PQconsumeInput(c)) {
      listener_.reset();
      return sleep();
    }
    drain();
  }
  return told;
}

}  // namespace gvd
