// The durable store of scenes and sites: SQLite in WAL mode with synchronous=FULL, one
// transaction per accepted request, committed before the request is acknowledged. Scenes are
// kept as their CreateSceneRequest and sites as their Site messages, so that every site kind
// the API gains is stored without a schema change. Thread-safe: one connection behind a mutex.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "gvd/v1/voronoi.pb.h"

struct sqlite3;

namespace gvd {

class Store {
 public:
  // Opens (creating if needed) DIR/gvd.sqlite3. ":memory:" keeps nothing across restarts.
  static absl::StatusOr<std::unique_ptr<Store>> Open(const std::string& dir);
  ~Store();  // closes the database cleanly (checkpointing the WAL)
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  struct StoredScene {
    v1::CreateSceneRequest request;
    uint64_t version = 0;
    std::vector<v1::Site> sites;
  };
  // Every stored scene with its sites and version.
  absl::StatusOr<std::vector<StoredScene>> Load();

  absl::Status CreateScene(const v1::CreateSceneRequest& request, uint64_t version);
  absl::Status DeleteScene(const std::string& scene_id);
  // Inserts or replaces the sites and sets the scene's version, in one transaction.
  absl::Status UpsertSites(const std::string& scene_id,
                           const google::protobuf::RepeatedPtrField<v1::Site>& sites,
                           uint64_t version);
  // Removes the sites and sets the scene's version, in one transaction.
  absl::Status DeleteSites(const std::string& scene_id, const std::vector<std::string>& ids,
                           uint64_t version);

  const std::string& path() const { return path_; }
  // Seconds the last commit took (BEGIN to durable COMMIT).
  double last_commit_seconds() const;

 private:
  Store(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}
  absl::Status Exec(const char* sql);
  // Sets a scene's version (inside a transaction).
  absl::Status SetVersion(const std::string& scene_id, uint64_t version);
  // Runs `body` inside BEGIN IMMEDIATE ... COMMIT, rolling back if it fails.
  template <class Body>
  absl::Status Transaction(Body body);

  mutable std::mutex mu_;
  sqlite3* db_;
  std::string path_;
  double last_commit_seconds_ = 0;
};

}  // namespace gvd
