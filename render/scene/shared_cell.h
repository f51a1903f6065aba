// A shared_ptr that one thread replaces while others read it.
#pragma once

#include <memory>
#include <mutex>

namespace gvd {

// Thread-safe. load() and store() hold an internal lock only while the pointer is copied or
// swapped, never across other work, so readers wait for no writer's work. (Used instead of
// std::atomic<std::shared_ptr>, whose libstdc++ 12 implementation unlocks a load with relaxed
// ordering, which ThreadSanitizer reports as a race with the next store.)
template <class T>
class SharedCell {
 public:
  SharedCell() = default;
  explicit SharedCell(std::shared_ptr<T> p) : p_(std::move(p)) {}

  std::shared_ptr<T> load() const {
    std::lock_guard<std::mutex> lock(mu_);
    return p_;
  }
  void store(std::shared_ptr<T> p) {
    std::lock_guard<std::mutex> lock(mu_);
    p_.swap(p);
    // The old value (in p) is released after the lock.
  }

 private:
  mutable std::mutex mu_;
  std::shared_ptr<T> p_;
};

}  // namespace gvd
