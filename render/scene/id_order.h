// The order of a list of ids, by byte-wise comparison: how the id map keeps them, and how the
// store writes a change set's rows (its B-tree then fills pages in key order, not at random).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string_view>
#include <type_traits>
#include <vector>

namespace gvd {

// The positions 0..n-1 ordered by id_at(position), a std::string_view of an id that outlives
// the call, equal ids in their positions' order. Sorted as (the first 8 bytes of the id,
// big-endian; its position), full ids compared only where those bytes are equal: no string
// is moved, and few are compared, per step of the sort.
template <class IdAt>
std::vector<uint32_t> IdOrder(size_t n, IdAt&& id_at) {
  // A view, not a string returned by value: the keys read the ids after id_at returns.
  static_assert(std::is_same_v<std::invoke_result_t<IdAt&, size_t>, std::string_view>,
                "id_at must return a std::string_view");
  struct Key {
    uint64_t prefix;
    uint32_t at;
  };
  std::vector<Key> keys(n);
  for (size_t k = 0; k < n; ++k) {
    const std::string_view id = id_at(k);
    unsigned char bytes[8] = {};
    std::memcpy(bytes, id.data(), std::min<size_t>(8, id.size()));
    uint64_t prefix = 0;
    for (unsigned char b : bytes) prefix = prefix << 8 | b;
    keys[k] = {prefix, static_cast<uint32_t>(k)};
  }
  std::sort(keys.begin(), keys.end(), [&](const Key& a, const Key& b) {
    if (a.prefix != b.prefix) return a.prefix < b.prefix;
    const int order = id_at(a.at).compare(id_at(b.at));
    return order != 0 ? order < 0 : a.at < b.at;  // equal ids keep their order
  });
  std::vector<uint32_t> order(n);
  for (size_t k = 0; k < n; ++k) order[k] = keys[k].at;
  return order;
}

}  // namespace gvd
