// The memory budget (--max-memory): what scenes may hold together. A change that would take
// the scenes past it is refused before anything is stored.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>

#include "absl/status/status.h"

namespace gvd {

// Thread-safe. Bytes in use are the scenes' own figures (Scene::memory_bytes, summed by the
// caller's function), plus the reservations of changes under way: a change reserves what it
// adds before it is stored and releases the reservation once its scene holds it (or it
// failed), so a byte is counted at least once at every moment.
class MemoryBudget {
 public:
  // in_use: the bytes the scenes hold now; called under the budget's lock.
  MemoryBudget(uint64_t limit, std::function<uint64_t()> in_use)
      : limit_(limit), in_use_(std::move(in_use)) {}

  uint64_t limit() const { return limit_; }
  // What the scenes hold plus what is reserved.
  uint64_t used() const;

  // Reserves `bytes` for `what` (say, "scene \"a\" of 4096x4096 pixels"), or says why not:
  // RESOURCE_EXHAUSTED naming --max-memory, the need and what is free. Release the bytes once
  // the change is published or has failed (Reservation does).
  absl::Status Reserve(uint64_t bytes, const std::string& what);
  void Release(uint64_t bytes);

  // Reserves for the life of the object.
  class Reservation {
   public:
    Reservation(MemoryBudget* budget, uint64_t bytes) : budget_(budget), bytes_(bytes) {}
    Reservation(const Reservation&) = delete;
    Reservation& operator=(const Reservation&) = delete;
    ~Reservation() {
      if (budget_ != nullptr && bytes_ > 0) budget_->Release(bytes_);
    }

   private:
    MemoryBudget* budget_;
    uint64_t bytes_;
  };

 private:
  const uint64_t limit_;
  const std::function<uint64_t()> in_use_;
  mutable std::mutex mu_;
  uint64_t reserved_ = 0;  // guarded by mu_
};

// "4294967296", "512M", "4G", "4GiB", "1.5G": bytes (k, M, G, T are powers of 1024); nullopt
// for anything else, zero included.
std::optional<uint64_t> ParseBytes(const std::string& text);

// The default --max-memory: 3/4 of the memory limit of the server's cgroup (cgroup v2's
// memory.max, or v1's memory.limit_in_bytes, under `cgroup_root`), else of the physical
// memory. `source` says which ("cgroup" or "physical memory").
uint64_t DefaultMaxMemory(const std::string& cgroup_root, std::string* source);

// Bytes for people: "1.5 GiB", "512 MiB", "300 bytes".
std::string FormatBytes(uint64_t bytes);

}  // namespace gvd
