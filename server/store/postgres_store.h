// SceneStore on PostgreSQL, the store that replicas share (store.h has the log's design).
// Every call is one statement or one short transaction on a pooled connection, bounded by a
// deadline: while the database cannot be reached a call fails with UNAVAILABLE within
// seconds, never hangs. A commit is acknowledged once PostgreSQL has committed it
// (synchronous_commit on); versions are checked and set inside the committing statement, so
// two servers writing one scene get distinct, ordered versions. Each commit notifies the
// channel "gvd_changes" (LISTEN/NOTIFY), which WaitForChanges listens to.
//
// Tables (made at Open if missing, under an advisory lock so that replicas starting at once
// do not race): gvd_scene (id, settings, version, incarnation, horizon) and gvd_site (scene,
// id, version, site; a tombstone has no bytes), with an index on (scene, version) for
// followers' reads, and gvd_schema (the schema's version).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/store/store.h"
#include "server/store/rows.h"

struct pg_conn;

namespace gvd {

class PostgresStore final : public SceneStore {
 public:
  struct Options {
    // At most this many connections for calls (the listener has one more).
    size_t connections = 8;
    // A call's deadline: past it the connection is dropped and the call is UNAVAILABLE.
    std::chrono::milliseconds deadline{10000};
    Retention retention;
  };
  // Connects to `url` (a libpq URL or key=value string; several hosts and
  // target_session_attrs work as libpq has them), and makes the tables if missing.
  // Defaults the URL may override: connect_timeout=3, TCP keepalives, tcp_user_timeout=5s.
  static absl::StatusOr<std::unique_ptr<PostgresStore>> Open(const std::string& url,
                                                             Options options);
  static absl::StatusOr<std::unique_ptr<PostgresStore>> Open(const std::string& url) {
    return Open(url, Options());
  }
  ~PostgresStore() override;
  PostgresStore(const PostgresStore&) = delete;
  PostgresStore& operator=(const PostgresStore&) = delete;

  absl::StatusOr<std::vector<StoredScene>> Load() override;
  absl::StatusOr<uint64_t> CreateScene(const SceneSettings& settings, uint64_t version) override;
  absl::Status Commit(const ChangeSet& changes) override;
  absl::Status DeleteScene(std::string_view scene_id) override;
  bool shared() const override { return true; }
  absl::StatusOr<std::vector<SceneHead>> Heads() override;
  absl::StatusOr<SceneChanges> ReadChanges(std::string_view scene_id, uint64_t after) override;
  bool WaitForChanges(int timeout_ms) override;
  std::string Describe() const override { return name_; }

 private:
  class Connection;
  class Lease;
  PostgresStore(std::string url, Options options);
  // A connection of the pool (made when none is idle and fewer than Options::connections
  // are open); UNAVAILABLE when the database cannot be reached.
  absl::StatusOr<Lease> Take();
  void Return(std::unique_ptr<Connection> connection);
  // Runs `body` between BEGIN `mode` and COMMIT, rolling back when it fails.
  template <class Body>
  absl::Status InTransaction(Lease& c, const char* mode, Body body);

  const std::string url_;
  const Options options_;
  std::string name_;  // for logs: user@host:port/database, no password

  std::mutex mu_;
  std::condition_variable idle_cv_;
  std::vector<std::unique_ptr<Connection>> idle_;
  size_t open_ = 0;

  std::unique_ptr<Connection> listener_;  // WaitForChanges's (one caller at a time)
};

}  // namespace gvd
